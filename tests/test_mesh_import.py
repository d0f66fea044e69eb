"""Mesh import: unique edges of every supported cell type, lumped masses,
groups from cell sets and gmsh physical groups, and a .msh written by the real gmsh."""

from itertools import combinations

import meshio
import numpy as np
import pytest

import thermonet as tn

# Unit reference cells in meshio's (VTK's) vertex order, and their edges written out by hand.
SQUARE = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
CELLS = {
    "line": ([[0, 0, 0], [1, 0, 0]], {(0, 1)}, 1.0),
    "triangle": ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], {(0, 1), (1, 2), (0, 2)}, 0.5),
    "quad": (SQUARE, {(0, 1), (1, 2), (2, 3), (0, 3)}, 1.0),
    "tetra": ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], set(combinations(range(4), 2)), 1.0 / 6.0),
    "hexahedron": (
        SQUARE + [[x, y, 1] for x, y, _ in SQUARE],
        {(0, 1), (1, 2), (2, 3), (0, 3), (4, 5), (5, 6), (6, 7), (4, 7), (0, 4), (1, 5), (2, 6), (3, 7)},
        1.0,
    ),
    "wedge": (
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1]],
        {(0, 1), (1, 2), (0, 2), (3, 4), (4, 5), (3, 5), (0, 3), (1, 4), (2, 5)},
        0.5,
    ),
    "pyramid": (
        SQUARE + [[0.5, 0.5, 1.0]],
        {(0, 1), (1, 2), (2, 3), (0, 3), (0, 4), (1, 4), (2, 4), (3, 4)},
        1.0 / 3.0,
    ),
}


def edge_set(net, point_ids=None):
    """The net's springs as a set of sorted (mesh point, mesh point) pairs."""
    ids = net.point_ids if point_ids is None else point_ids
    return {tuple(sorted(map(int, ids[e]))) for e in net.edges}


@pytest.mark.parametrize("cell_type", list(CELLS))
def test_one_cell_gives_its_edges(cell_type):
    points, edges, _ = CELLS[cell_type]
    mesh = meshio.Mesh(np.array(points, dtype=float), [(cell_type, np.arange(len(points))[None, :])])
    net = tn.from_meshio(mesh)
    assert edge_set(net) == edges
    np.testing.assert_array_equal(net.positions, mesh.points[net.point_ids])
    np.testing.assert_allclose(net.rest_lengths, net.lengths())


@pytest.mark.parametrize("cell_type", list(CELLS))
def test_two_cells_sharing_a_side_give_unique_edges(cell_type):
    """The cell and its mirror image through the plane x = 0 (or the point reflection for a line)
    share a side; shared edges must appear once. Extra unused points are dropped."""
    points, edges, _ = CELLS[cell_type]
    pts = np.array(points, dtype=float)
    k = len(pts)
    mirror = pts * [-1, 1, 1]
    on_plane = np.flatnonzero(pts[:, 0] == 0)  # these vertices are shared by both cells
    extra = np.array([[5.0, 5.0, 5.0]])  # a point in no cell
    all_points = np.vstack([pts, mirror, extra])
    second = np.arange(k, 2 * k)
    second[on_plane] = on_plane
    mesh = meshio.Mesh(all_points, [(cell_type, np.array([np.arange(k), second]))])
    net = tn.from_meshio(mesh)
    expected = edges | {tuple(sorted((int(second[a]), int(second[b])))) for a, b in edges}
    assert edge_set(net) == expected
    assert net.n_springs == len(expected)
    assert 2 * k not in set(net.point_ids)  # the unused point is not a node
    assert net.n_nodes == len(np.unique(np.concatenate([np.arange(k), second])))


def test_mixed_cells_share_edges():
    """A tetrahedron with triangles on two of its faces and a line on one edge: 6 springs."""
    points, edges, _ = CELLS["tetra"]
    mesh = meshio.Mesh(np.array(points, dtype=float), [
        ("tetra", np.array([[0, 1, 2, 3]])),
        ("triangle", np.array([[0, 1, 2], [1, 2, 3]])),
        ("line", np.array([[3, 0]])),
        ("vertex", np.array([[0]])),
    ])
    assert edge_set(tn.from_meshio(mesh)) == edges
    only_surface = tn.from_meshio(mesh, cell_types=["triangle"])
    assert edge_set(only_surface) == {(0, 1), (1, 2), (0, 2), (2, 3), (1, 3)}


@pytest.mark.parametrize("cell_type", list(CELLS))
def test_lumped_masses_sum_to_density_times_measure(cell_type):
    points, _, measure = CELLS[cell_type]
    scale = np.array([2.0, 3.0, 0.5])  # a stretched cell, so measure is not 1
    factor = np.prod(scale[: {"line": 1, "triangle": 2, "quad": 2}.get(cell_type, 3)])
    pts = np.array(points, dtype=float) * scale
    mesh = meshio.Mesh(pts, [(cell_type, np.arange(len(pts))[None, :])])
    net = tn.from_meshio(mesh, density=7.0)
    assert net.masses.sum() == pytest.approx(7.0 * measure * factor, rel=1e-13)
    np.testing.assert_allclose(net.masses, net.masses[0])  # shared equally among the vertices


def test_lumped_masses_of_a_cube_split_into_six_tetrahedra_and_its_faces():
    """Kuhn's split of the unit cube; boundary triangles present too: only the cells of the
    highest dimension carry mass."""
    corners = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=float)
    tets = np.array([[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]])
    mesh = meshio.Mesh(corners, [("tetra", tets), ("triangle", np.array([[0, 1, 3], [0, 2, 3]]))])
    net = tn.from_meshio(mesh, density=2.5)
    assert net.masses.sum() == pytest.approx(2.5, rel=1e-14)
    assert net.n_springs == 12 + 6 + 1  # cube edges, one diagonal per face, the body diagonal 0–7
    uniform = tn.from_meshio(mesh, mass=0.25)
    np.testing.assert_array_equal(uniform.masses, 0.25)
    mesh.point_data["m"] = np.arange(1.0, 9.0)
    from_field = tn.from_meshio(mesh, mass="m")
    np.testing.assert_array_equal(from_field.masses, np.arange(1.0, 9.0)[from_field.point_ids])


def test_cell_sets_give_node_and_spring_groups():
    points, edges, _ = CELLS["tetra"]
    pts = np.vstack([points, [[1.0, 1.0, 1.0]]])
    tets = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    mesh = meshio.Mesh(pts, [("tetra", tets)], cell_sets={"left": [np.array([0])], "right": [np.array([1])]})
    net = tn.from_meshio(mesh, anchors=["left"])
    ids = net.point_ids
    assert set(ids[net.node_groups["left"]]) == {0, 1, 2, 3}
    assert set(ids[net.node_groups["right"]]) == {1, 2, 3, 4}
    springs_left = {tuple(sorted(map(int, ids[net.edges[e]]))) for e in net.spring_groups["left"]}
    springs_right = {tuple(sorted(map(int, ids[net.edges[e]]))) for e in net.spring_groups["right"]}
    assert springs_left == set(combinations([0, 1, 2, 3], 2))
    assert springs_right == set(combinations([1, 2, 3, 4], 2))
    assert set(ids[net.anchored]) == {0, 1, 2, 3}


def test_a_msh_file_written_by_gmsh_imports(tmp_path):
    gmsh = pytest.importorskip("gmsh")
    path = tmp_path / "box.msh"
    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("box")
        gmsh.model.occ.addBox(0, 0, 0, 2.0, 1.0, 0.5)
        gmsh.model.occ.synchronize()
        bottom = [tag for dim, tag in gmsh.model.getEntities(2)
                  if abs(gmsh.model.occ.getCenterOfMass(dim, tag)[2]) < 1e-12]
        gmsh.model.addPhysicalGroup(3, [1], name="body")
        gmsh.model.addPhysicalGroup(2, bottom, name="bottom")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.4)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()

    net = tn.read_mesh(path, density=3.0, anchors="bottom")
    raw = meshio.read(path)
    tets = np.concatenate([b.data for b in raw.cells if b.type == "tetra"])
    expected = {tuple(sorted(map(int, p))) for t in tets for p in combinations(t, 2)}
    assert edge_set(net) == expected
    faces = {tuple(sorted(map(int, f))) for t in tets for f in combinations(t, 3)}
    # a tetrahedral mesh of a box is a ball: Euler characteristic V − E + F − T = 1
    assert net.n_nodes - net.n_springs + len(faces) - len(tets) == 1
    assert net.masses.sum() == pytest.approx(3.0 * 2.0 * 1.0 * 0.5, rel=1e-12)
    assert {"body", "bottom"} <= set(net.node_groups)
    np.testing.assert_array_equal(np.sort(net.spring_groups["body"]), np.arange(net.n_springs))
    on_bottom = np.abs(net.positions[:, 2]) < 1e-12
    np.testing.assert_array_equal(net.anchored, on_bottom)
    assert on_bottom.sum() > 3

    sim = tn.Simulation(net, temperatures=400.0, velocities=np.where(on_bottom[:, None], 0.0, [0.0, 0.0, 0.3]),
                        integrator="co2", h=2e-4)  # h_max ≈ 3.4e-4 once the hot net moves
    sim.run(steps=250)
    np.testing.assert_array_equal(sim.state.positions[on_bottom], net.positions[on_bottom])
    assert np.abs(sim.state.positions[~on_bottom] - net.positions[~on_bottom]).max() > 1e-4


def test_renumbering_is_invisible():
    """The engine reorders nodes and springs internally (RCM); everything read back is in the
    user's numbering, the same as a run without renumbering."""
    base = tn.lattice((4, 3, 3), neighbours=18, jitter=0.2, seed=11)
    rng = np.random.default_rng(11)
    # shuffle the user's numbering so the internal order surely differs from it
    perm = rng.permutation(base.n_nodes)
    inv = np.argsort(perm)
    net = tn.Net(base.positions[perm], inv[base.edges][rng.permutation(base.n_springs)],
                 rng.uniform(0.5, 2, base.n_nodes), anchored=[0, 5])
    momenta = rng.normal(0, 1, (net.n_nodes, 3))
    momenta[[0, 5]] = 0.0
    theta = rng.uniform(250, 500, net.n_springs)
    stiffness = rng.uniform(50, 150, net.n_springs)
    runs = {}
    for renumber in (True, False):
        sim = tn.Simulation(net, temperatures=theta, momenta=momenta, parameters={"c": stiffness},
                            integrator="co2", h=2e-3, renumber=renumber)
        start = sim.state
        np.testing.assert_array_equal(start.positions, net.positions)
        np.testing.assert_array_equal(start.momenta, momenta)
        sim.run(steps=100, diagnostics_every=10)
        runs[renumber] = sim
    lay = runs[True].layout
    assert not np.array_equal(lay.node_order, np.arange(net.n_nodes))
    assert not np.array_equal(lay.spring_order, np.arange(net.n_springs))
    a, b = runs[True], runs[False]
    for got, want in ((a.state.positions, b.state.positions), (a.state.momenta, b.state.momenta),
                      (a.state.thermal_displacement, b.state.thermal_displacement),
                      (a.temperatures(), b.temperatures()), (a.tensions(), b.tensions()), (a.lengths(), b.lengths())):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())
    np.testing.assert_array_equal(a.state.entropy, b.state.entropy)
    np.testing.assert_allclose(a.diagnostics.energy, b.diagnostics.energy, rtol=1e-13)
