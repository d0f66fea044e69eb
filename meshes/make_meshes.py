"""Generate the meshes shipped in meshes/ with gmsh (``python meshes/make_meshes.py``).

- chain.msh: the paper's chain of three springs (Mata & Lew 2011 §5.1): nodes 0..3, node 0 the anchor.
- triangle.msh: the paper's triangle net (Mata & Lew 2011 §5.2).
- lattice2d.msh: a 2D triangulated 8×4 lattice, clamped on its left edge, two materials.
- truss_block.msh: a 3D tetrahedral truss block 4×1×1 made of four unit slabs: materials
  "soft" (x < 2) and "stiff" (x > 2), a "hot" tip slab (x > 3), a clamped face "clamp" (x = 0)
  and the free end face "tip" (x = 4). It is also written to thermonet/data/, the built-in
  default scene's copy that a wheel ships.
- thermal_bar.msh: a 3D tetrahedral bar 8×1×1 (mesh size 0.5), spring group "bar", node groups
  "hot_end" (the face x = 0, held by a heat bath in scenes/thermal_shock.toml) and "far_end"
  (the face x = 8, insulated).
- bracket.msh: an aluminium L-bracket in metres (docs/continuum.md): a base plate 60 × 40 × 6 mm
  ("base") and an upright flange 6 × 40 × 46 mm on it ("flange"); the whole part "bracket", the
  bolted end face of the base "clamp" (x = 60 mm). Tetrahedra of about 5 mm.
- dogbone.msh: a flat tensile specimen (triangles, in the plane z = 0), 10 long: grips 2 × 2 at
  both ends ("grip_left" x ≤ 2, "grip_right" x ≥ 8) and a gauge 6 × 1 ("gauge") between them.

Physical groups become node groups (anchors, masses, velocities) and spring groups (materials,
temperatures) in scenes. Files are gmsh 4.1 ASCII, small enough to read in a diff.
"""

from __future__ import annotations

import math
import os

import gmsh

HERE = os.path.dirname(os.path.abspath(__file__))


def _start(name: str) -> None:
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.model.add(name)


def _finish(filename: str) -> None:
    gmsh.write(os.path.join(HERE, filename))
    gmsh.finalize()


def _springs(points, pairs, names) -> None:
    """Straight springs between gmsh points, each one mesh line element, each its own group."""
    geo = gmsh.model.geo
    lines = []
    for (a, b) in pairs:
        line = geo.addLine(points[a], points[b])
        geo.mesh.setTransfiniteCurve(line, 2)
        lines.append(line)
    geo.synchronize()
    for line, name in zip(lines, names):
        gmsh.model.addPhysicalGroup(1, [line], name=name)
    gmsh.model.addPhysicalGroup(1, lines, name="springs")
    for i, p in enumerate(points):
        gmsh.model.addPhysicalGroup(0, [p], name=f"m{i}")


def chain() -> None:
    _start("chain")
    xyz = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (1, 1, 1)]
    points = [gmsh.model.geo.addPoint(*p) for p in xyz]
    _springs(points, [(0, 1), (1, 2), (2, 3)], ["spring1", "spring2", "spring3"])
    gmsh.model.addPhysicalGroup(0, [points[0]], name="anchor")
    gmsh.model.mesh.generate(1)
    _finish("chain.msh")


def triangle() -> None:
    _start("triangle")
    xyz = [(-0.5, 0, 0), (0.5, 0, 0), (0, math.sqrt(3) / 2, 0)]
    points = [gmsh.model.geo.addPoint(*p) for p in xyz]
    # the paper's spring 1 joins masses 1–3, spring 2 joins 1–2, spring 3 joins 2–3
    _springs(points, [(0, 2), (0, 1), (1, 2)], ["spring1", "spring2", "spring3"])
    gmsh.model.mesh.generate(1)
    _finish("triangle.msh")


def lattice2d(nx: int = 8, ny: int = 4) -> None:
    _start("lattice2d")
    occ = gmsh.model.occ
    left = occ.addRectangle(0, 0, 0, nx / 2, ny)
    right = occ.addRectangle(nx / 2, 0, 0, nx / 2, ny)
    occ.fragment([(2, left)], [(2, right)])
    occ.synchronize()
    for dim, tag in gmsh.model.getEntities(1):
        x0, y0, _, x1, y1, _ = gmsh.model.getBoundingBox(dim, tag)
        n = round(max(x1 - x0, y1 - y0)) + 1
        gmsh.model.mesh.setTransfiniteCurve(tag, n)
    for _, tag in gmsh.model.getEntities(2):
        gmsh.model.mesh.setTransfiniteSurface(tag, "Alternate")
    gmsh.model.addPhysicalGroup(2, [left], name="soft")
    gmsh.model.addPhysicalGroup(2, [right], name="stiff")
    edge = [t for d, t in gmsh.model.getEntitiesInBoundingBox(-0.1, -0.1, -0.1, 0.1, ny + 0.1, 0.1, dim=1)]
    gmsh.model.addPhysicalGroup(1, edge, name="clamp")
    gmsh.model.mesh.generate(2)
    _finish("lattice2d.msh")


def truss_block(size: float = 0.25) -> None:
    _start("truss_block")
    occ = gmsh.model.occ
    slabs = [occ.addBox(i, 0, 0, 1, 1, 1) for i in range(4)]
    occ.fragment([(3, slabs[0])], [(3, s) for s in slabs[1:]])
    occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMin", size)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    volumes = sorted(gmsh.model.getEntities(3), key=lambda e: gmsh.model.occ.getCenterOfMass(*e)[0])
    tags = [t for _, t in volumes]
    gmsh.model.addPhysicalGroup(3, tags[:2], name="soft")
    gmsh.model.addPhysicalGroup(3, tags[2:], name="stiff")
    gmsh.model.addPhysicalGroup(3, tags[3:], name="hot")

    def face_at(x):
        return [t for d, t in gmsh.model.getEntitiesInBoundingBox(x - 1e-3, -1e-3, -1e-3, x + 1e-3, 1.001, 1.001, dim=2)]

    gmsh.model.addPhysicalGroup(2, face_at(0.0), name="clamp")
    gmsh.model.addPhysicalGroup(2, face_at(4.0), name="tip")
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)
    gmsh.option.setNumber("Mesh.RandomSeed", 1)
    gmsh.model.mesh.generate(3)
    gmsh.write(os.path.join(HERE, "..", "thermonet", "data", "truss_block.msh"))  # the default scene's copy
    _finish("truss_block.msh")


def thermal_bar(length: float = 8.0, size: float = 0.5) -> None:
    _start("thermal_bar")
    occ = gmsh.model.occ
    bar = occ.addBox(0, 0, 0, length, 1, 1)
    occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMin", size)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    gmsh.model.addPhysicalGroup(3, [bar], name="bar")

    def face_at(x):
        return [t for d, t in gmsh.model.getEntitiesInBoundingBox(x - 1e-3, -1e-3, -1e-3, x + 1e-3, 1.001, 1.001, dim=2)]

    gmsh.model.addPhysicalGroup(2, face_at(0.0), name="hot_end")
    gmsh.model.addPhysicalGroup(2, face_at(length), name="far_end")
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)
    gmsh.option.setNumber("Mesh.RandomSeed", 1)
    gmsh.model.mesh.generate(3)
    _finish("thermal_bar.msh")
def bracket(size: float = 0.005) -> None:
    _start("bracket")
    occ = gmsh.model.occ
    base = occ.addBox(0, 0, 0, 0.06, 0.04, 0.006)
    flange = occ.addBox(0, 0, 0.006, 0.006, 0.04, 0.046)
    occ.fragment([(3, base)], [(3, flange)])
    occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMin", size)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    volumes = sorted(gmsh.model.getEntities(3), key=lambda e: gmsh.model.occ.getCenterOfMass(*e)[2])
    gmsh.model.addPhysicalGroup(3, [t for _, t in volumes], name="bracket")
    gmsh.model.addPhysicalGroup(3, [volumes[0][1]], name="base")
    gmsh.model.addPhysicalGroup(3, [volumes[1][1]], name="flange")
    end = [t for d, t in gmsh.model.getEntitiesInBoundingBox(0.0599, -1e-4, -1e-4, 0.0601, 0.0401, 0.0061, dim=2)]
    gmsh.model.addPhysicalGroup(2, end, name="clamp")
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)
    gmsh.option.setNumber("Mesh.RandomSeed", 1)
    gmsh.model.mesh.generate(3)
    _finish("bracket.msh")


def dogbone(size: float = 0.25) -> None:
    _start("dogbone")
    occ = gmsh.model.occ
    left = occ.addRectangle(0, -1, 0, 2, 2)
    gauge = occ.addRectangle(2, -0.5, 0, 6, 1)
    right = occ.addRectangle(8, -1, 0, 2, 2)
    occ.fragment([(2, gauge)], [(2, left), (2, right)])
    occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMin", size)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    surfaces = sorted(gmsh.model.getEntities(2), key=lambda e: gmsh.model.occ.getCenterOfMass(*e)[0])
    gmsh.model.addPhysicalGroup(2, [surfaces[0][1]], name="grip_left")
    gmsh.model.addPhysicalGroup(2, [surfaces[1][1]], name="gauge")
    gmsh.model.addPhysicalGroup(2, [surfaces[2][1]], name="grip_right")
    gmsh.option.setNumber("Mesh.RandomSeed", 1)
    gmsh.model.mesh.generate(2)
    _finish("dogbone.msh")


if __name__ == "__main__":
    dogbone()
    chain()
    triangle()
    lattice2d()
    truss_block()
    thermal_bar()
    bracket()
    print("wrote", ", ".join(f for f in sorted(os.listdir(HERE)) if f.endswith(".msh")))
