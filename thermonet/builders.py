"""Net builders: the paper's chain and triangle, a 3D cubic lattice, and any mesh meshio reads."""

from __future__ import annotations

import contextlib
import io
import os
import numpy as np

from .errors import InputError, MeshError
from .net import Net

# Unique edges of each supported cell type, as local vertex pairs (meshio's vertex order).
CELL_EDGES: dict[str, tuple[tuple[int, int], ...]] = {
    "line": ((0, 1),),
    "triangle": ((0, 1), (1, 2), (2, 0)),
    "quad": ((0, 1), (1, 2), (2, 3), (3, 0)),
    "tetra": ((0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)),
    "hexahedron": (
        (0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7),
    ),
    "wedge": ((0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3), (0, 3), (1, 4), (2, 5)),
    "pyramid": ((0, 1), (1, 2), (2, 3), (3, 0), (0, 4), (1, 4), (2, 4), (3, 4)),
}
CELL_DIM = {"line": 1, "triangle": 2, "quad": 2, "tetra": 3, "hexahedron": 3, "wedge": 3, "pyramid": 3}
# Cell types meshio may report that carry no springs and are skipped silently.
IGNORED_CELLS = {"vertex"}
# Tetrahedral splits used to measure cells for lumped masses.
_TETS = {
    "tetra": ((0, 1, 2, 3),),
    "hexahedron": ((0, 1, 3, 4), (1, 2, 3, 6), (1, 4, 5, 6), (3, 4, 6, 7), (1, 3, 4, 6)),
    "wedge": ((0, 1, 2, 3), (1, 2, 3, 4), (2, 3, 4, 5)),
    "pyramid": ((0, 1, 2, 4), (0, 2, 3, 4)),
}


# ---------------------------------------------------------------------------------------------
# generators


def chain() -> Net:
    """The paper's chain of three springs (Mata & Lew 2011, §5.1): node 0 anchored at the origin,
    nodes (1,0,0), (1,1,0), (1,1,1); spring i joins nodes i−1 and i; masses 1, 2, 1.5; l0 = 1."""
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 1.0, 1.0]])
    edges = np.array([[0, 1], [1, 2], [2, 3]])
    masses = np.array([1.0, 1.0, 2.0, 1.5])
    anchored = np.array([True, False, False, False])
    return Net(x, edges, masses, anchored, rest_lengths=np.ones(3), source="chain")


def triangle() -> Net:
    """The paper's triangle net (Mata & Lew 2011, §5.2): equilateral, side 1; nodes 0, 1, 2 are the paper's
    masses 1, 2, 3; springs 0, 1, 2 are the paper's springs 1 (1–3), 2 (1–2), 3 (2–3)."""
    x = np.array([[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0], [0.0, np.sqrt(3.0) / 2.0, 0.0]])
    edges = np.array([[0, 2], [0, 1], [1, 2]])
    return Net(x, edges, np.array([1.0, 1.0, 2.0]), rest_lengths=np.ones(3), source="triangle")


_NEIGHBOUR_OFFSETS = {
    6: [(1, 0, 0), (0, 1, 0), (0, 0, 1)],
    18: [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, -1, 0), (1, 0, 1), (1, 0, -1), (0, 1, 1), (0, 1, -1)],
}
_NEIGHBOUR_OFFSETS[26] = _NEIGHBOUR_OFFSETS[18] + [(1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1)]


def lattice(
    shape=(10, 10, 10),
    spacing: float = 1.0,
    neighbours: int = 6,
    jitter: float = 0.0,
    seed: int = 0,
    mass: float = 1.0,
) -> Net:
    """A 3D cubic lattice of ``shape = (nx, ny, nz)`` cells (so (nx+1)(ny+1)(nz+1) nodes).

    neighbours: 6 (edges of the cubes), 18 (+ face diagonals) or 26 (+ body diagonals).
    jitter: each node is displaced by a uniform random vector of up to ``jitter * spacing`` per
        axis (seeded); rest lengths are the jittered lengths.
    Nodes are numbered x-fastest; springs are grouped by offset. Useful for scale tests:
    a 6-neighbour lattice of k³ cells has about 3k³ springs.
    """
    if neighbours not in _NEIGHBOUR_OFFSETS:
        raise InputError(f"lattice: neighbours must be 6, 18 or 26, got {neighbours}")
    shape = tuple(int(s) for s in np.broadcast_to(shape, (3,)))
    if min(shape) < 0 or max(shape) < 1:
        raise InputError(f"lattice: shape must be non-negative cell counts with at least one > 0, got {shape}")
    if not (spacing > 0 and np.isfinite(spacing)):
        raise InputError(f"lattice: spacing must be > 0, got {spacing}")
    if not (0 <= jitter < 0.5):
        raise InputError(f"lattice: jitter must be in [0, 0.5), got {jitter}")
    nx, ny, nz = (s + 1 for s in shape)
    idx = np.arange(nx * ny * nz).reshape(nz, ny, nx)
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    x = np.column_stack([i.ravel(), j.ravel(), k.ravel()]).astype(np.float64) * spacing
    if jitter:
        x += np.random.default_rng(seed).uniform(-jitter, jitter, x.shape) * spacing
    blocks = []
    for dx, dy, dz in _NEIGHBOUR_OFFSETS[neighbours]:
        src = idx[max(0, -dz): nz - max(0, dz), max(0, -dy): ny - max(0, dy), max(0, -dx): nx - max(0, dx)]
        dst = idx[max(0, dz): nz + min(0, dz), max(0, dy): ny + min(0, dy), max(0, dx): nx + min(0, dx)]
        if src.size:
            blocks.append(np.column_stack([src.ravel(), dst.ravel()]))
    edges = np.concatenate(blocks)
    return Net(x, edges, np.full(len(x), float(mass)), source=f"lattice{shape}x{neighbours}")


# ---------------------------------------------------------------------------------------------
# meshes


def read_meshio(path):
    """``meshio.read(path)``, its failures as a :class:`MeshError` naming the file: a missing
    file, a folder, a file no reader accepts (meshio calls ``sys.exit()`` on some of those: a
    notebook or the CLI must not be shut down) or a truncated or corrupt one."""
    import meshio

    path = os.fspath(path)
    if os.path.isdir(path):
        raise MeshError(f"{path}: is a folder, not a mesh file")
    if not os.path.exists(path):
        raise MeshError(f"{path}: no such mesh file")
    said = io.StringIO()  # meshio prints its reason before some of its sys.exit() calls
    try:
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
            return meshio.read(path)
    except (Exception, SystemExit) as exc:
        printed = " ".join(said.getvalue().split()).removeprefix("Error: ")
        reason = str(exc).strip() if not isinstance(exc, SystemExit) else (printed or "no meshio reader accepts it")
        raise MeshError(f"{path}: meshio cannot read it: {reason or type(exc).__name__}") from None


def read_mesh(
    path,
    *,
    cell_types=None,
    mass: float | str | None = None,
    density: float | None = None,
    anchors=None,
) -> Net:
    """Read any mesh meshio reads (gmsh ``.msh``, ``.vtu``, ...) into a :class:`Net`.

    See :func:`from_meshio` for the arguments. Errors name the file.
    """
    path = os.fspath(path)
    mesh = read_meshio(path)
    return from_meshio(mesh, cell_types=cell_types, mass=mass, density=density, anchors=anchors, source=path)


def from_meshio(
    mesh,
    *,
    cell_types=None,
    mass: float | str | None = None,
    density: float | None = None,
    anchors=None,
    source: str = "<mesh>",
) -> Net:
    """Turn a ``meshio.Mesh`` into a spring net.

    Line cells are springs; triangle, quad, tetra, hexahedron, wedge and pyramid cells contribute
    their unique edges. Points that belong to no spring are dropped; ``net.point_ids`` (n,) maps each
    node back to its mesh point index.

    cell_types: which cell types become springs (default: all supported ones present).
    mass: node mass: a number (uniform), the name of a point-data field, or None.
    density: lumped masses: density × measure (length, area or volume) of the cells of the highest
        dimension present, shared equally among their vertices. Default (neither given): mass 1.
    anchors: node group names (physical groups / cell sets) or node indices to anchor.

    Groups: gmsh physical groups (``field_data`` + ``gmsh:physical``) and meshio ``cell_sets``
    give node groups (all vertices of their cells) and spring groups (the springs their cells
    contribute; a spring shared by cells of several groups belongs to each).
    """
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim != 2 or len(points) == 0:
        raise MeshError(f"{source}: the mesh has no points")
    if points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(len(points))])
    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        a = int(np.flatnonzero(bad)[0])
        raise MeshError(f"{source}: point {a} has a non-finite coordinate {points[a].tolist()}")

    present = [block.type for block in mesh.cells]
    unsupported = sorted({t for t in present if t not in CELL_EDGES and t not in IGNORED_CELLS})
    if cell_types is None:
        wanted = {t for t in present if t in CELL_EDGES}
    else:
        wanted = set(cell_types)
        unknown = sorted(wanted - set(CELL_EDGES))
        if unknown:
            raise MeshError(
                f"{source}: cell type(s) {', '.join(unknown)} cannot become springs; supported: {', '.join(CELL_EDGES)}"
            )
    if not wanted:
        hint = f" (unsupported cell types present: {', '.join(unsupported)})" if unsupported else ""
        raise MeshError(f"{source}: the mesh has no cells that give springs{hint}")

    edge_blocks, edge_cellref = [], []  # per block: (k*ncell, 2) edges, and (block, cell) of each
    for bi, block in enumerate(mesh.cells):
        if block.type not in wanted:
            continue
        conn = np.asarray(block.data, dtype=np.int64)
        if conn.size == 0:
            continue
        if conn.min() < 0 or conn.max() >= len(points):
            c = int(np.flatnonzero(((conn < 0) | (conn >= len(points))).any(axis=1))[0])
            raise MeshError(f"{source}: {block.type} cell {c} refers to a point outside 0..{len(points) - 1}")
        local = np.asarray(CELL_EDGES[block.type])
        e = conn[:, local].reshape(-1, 2)
        edge_blocks.append(e)
        edge_cellref.append(np.column_stack([np.full(len(e), bi), np.repeat(np.arange(len(conn)), len(local))]))
    if not edge_blocks:
        raise MeshError(f"{source}: the mesh has no cells that give springs")
    all_edges = np.concatenate(edge_blocks)
    cellref = np.concatenate(edge_cellref)
    degenerate = all_edges[:, 0] == all_edges[:, 1]
    if degenerate.any():
        k = int(np.flatnonzero(degenerate)[0])
        bi, c = cellref[k]
        raise MeshError(f"{source}: {mesh.cells[bi].type} cell {c} is degenerate: it repeats point {all_edges[k, 0]}")
    key = np.sort(all_edges, axis=1)
    unique, inverse = np.unique(key, axis=0, return_inverse=True)
    inverse = inverse.ravel()

    used = np.unique(unique)
    point_to_node = np.full(len(points), -1, dtype=np.int64)
    point_to_node[used] = np.arange(len(used))
    positions = points[used]
    edges = point_to_node[unique]
    with np.errstate(over="ignore", invalid="ignore"):  # reported below, with the points
        lengths = np.linalg.norm(positions[edges[:, 1]] - positions[edges[:, 0]], axis=1)
    if not np.isfinite(lengths).all():
        e = int(np.flatnonzero(~np.isfinite(lengths))[0])
        raise MeshError(
            f"{source}: the spring between mesh points {unique[e].tolist()} has no finite length "
            f"(coordinates {points[unique[e][0]].tolist()} and {points[unique[e][1]].tolist()})"
        )
    if (lengths <= 0).any():
        e = int(np.flatnonzero(lengths <= 0)[0])
        raise MeshError(
            f"{source}: mesh points {unique[e].tolist()} coincide, so the spring between them has zero length"
        )

    node_groups, spring_groups = _mesh_groups(mesh, source, point_to_node, cellref, inverse)

    masses = _node_masses(mesh, source, points, used, mass, density, wanted)
    volumes, dimension = _spring_volumes(mesh, points, wanted, cellref, inverse, len(unique))
    anchored = np.zeros(len(used), dtype=bool)
    if anchors is not None:
        for item in np.atleast_1d(np.asarray(anchors, dtype=object)):
            if isinstance(item, str):
                if item not in node_groups:
                    raise MeshError(
                        f"{source}: anchor group {item!r} does not exist; groups: {', '.join(sorted(node_groups)) or 'none'}"
                    )
                anchored[node_groups[item]] = True
            else:
                anchored[int(item)] = True
    return Net(
        positions, edges, masses, anchored,
        node_groups=node_groups, spring_groups=spring_groups, source=source, point_ids=used,
        spring_volumes=volumes, cell_dimension=dimension,
    )


def _spring_volumes(mesh, points, wanted, cellref, inverse, n_springs):
    """(m,) each spring's share of the measure of the highest-dimensional cells (each cell split
    equally over its edges), and that dimension."""
    top = max(CELL_DIM[t] for t in wanted)
    volumes = np.zeros(n_springs)
    for bi, block in enumerate(mesh.cells):
        if block.type not in wanted or CELL_DIM[block.type] != top or len(block.data) == 0:
            continue
        conn = np.asarray(block.data, dtype=np.int64)
        share = cell_measure(block.type, points, conn) / len(CELL_EDGES[block.type])
        rows = np.flatnonzero(cellref[:, 0] == bi)
        np.add.at(volumes, inverse[rows], share[cellref[rows, 1]])
    return volumes, top


def _mesh_groups(mesh, source, point_to_node, cellref, inverse):
    """Node and spring groups from gmsh physical groups and meshio cell sets."""
    node_groups: dict[str, np.ndarray] = {}
    spring_groups: dict[str, list] = {}

    def add(name, block_index, cell_mask):
        conn = np.asarray(mesh.cells[block_index].data)[cell_mask]
        nodes = point_to_node[np.unique(conn)]
        nodes = nodes[nodes >= 0]
        node_groups[name] = np.union1d(node_groups.get(name, np.empty(0, np.int64)), nodes)
        sel = cellref[:, 0] == block_index
        if sel.any():
            cells = np.flatnonzero(cell_mask)
            hit = sel & np.isin(cellref[:, 1], cells)
            spring_groups.setdefault(name, []).append(np.unique(inverse[hit]))

    names = {}
    for name, data in (getattr(mesh, "field_data", None) or {}).items():
        data = np.asarray(data).ravel()
        if data.size >= 2:
            names[(int(data[1]), int(data[0]))] = name
    physical = (getattr(mesh, "cell_data", None) or {}).get("gmsh:physical")
    if physical is not None:
        for bi, (block, tags) in enumerate(zip(mesh.cells, physical)):
            tags = np.asarray(tags).ravel()
            dim = CELL_DIM.get(block.type, 0 if block.type == "vertex" else -1)
            for tag in np.unique(tags):
                name = names.get((dim, int(tag)), f"physical_{int(tag)}")
                add(name, bi, tags == tag)
    for name, per_block in (getattr(mesh, "cell_sets", None) or {}).items():
        if name.startswith("gmsh:"):
            continue
        for bi, ids in enumerate(per_block):
            if ids is None or len(ids) == 0 or bi >= len(mesh.cells):
                continue
            mask = np.zeros(len(mesh.cells[bi].data), dtype=bool)
            mask[np.asarray(ids, dtype=np.int64)] = True
            add(name, bi, mask)
    return node_groups, {k: np.unique(np.concatenate(v)) for k, v in spring_groups.items()}


def _node_masses(mesh, source, points, used, mass, density, wanted):
    if mass is not None and density is not None:
        raise MeshError(f"{source}: give either mass or density, not both")
    if isinstance(mass, str):
        if mass not in mesh.point_data:
            raise MeshError(
                f"{source}: no point-data field {mass!r} for masses; fields: {', '.join(mesh.point_data) or 'none'}"
            )
        return np.asarray(mesh.point_data[mass], dtype=np.float64).reshape(len(points), -1)[used, 0]
    if density is None:
        return np.full(len(used), 1.0 if mass is None else float(mass))
    if not (density > 0):
        raise MeshError(f"{source}: density must be > 0, got {density}")
    top = max(CELL_DIM[t] for t in wanted)
    lumped = np.zeros(len(points))
    for block in mesh.cells:
        if block.type not in wanted or CELL_DIM[block.type] != top:
            continue
        conn = np.asarray(block.data, dtype=np.int64)
        measure = cell_measure(block.type, points, conn)
        np.add.at(lumped, conn.ravel(), np.repeat(density * measure / conn.shape[1], conn.shape[1]))
    return lumped[used]


def cell_measure(cell_type: str, points: np.ndarray, conn: np.ndarray) -> np.ndarray:
    """Length, area or volume of each cell: (ncell,) for ``conn`` (ncell, k) of one type."""
    p = points[conn]
    if cell_type == "line":
        return np.linalg.norm(p[:, 1] - p[:, 0], axis=1)
    if cell_type in ("triangle", "quad"):
        area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        if cell_type == "quad":
            area += 0.5 * np.linalg.norm(np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]), axis=1)
        return area
    vol = np.zeros(len(conn))
    for a, b, c, d in _TETS[cell_type]:
        vol += np.abs(np.einsum("ij,ij->i", np.cross(p[:, b] - p[:, a], p[:, c] - p[:, a]), p[:, d] - p[:, a])) / 6.0
    return vol
