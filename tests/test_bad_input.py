"""Bad input: a clear thermonet error that names the offending node, spring, parameter
or name; never a Numba typing error, and never a NaN-filled result as the only sign."""

import warnings

import meshio
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import thermonet as tn

TRI = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
PATH = [[0, 1], [1, 2]]


def good_net():
    return tn.Net(TRI, PATH)


@pytest.mark.parametrize("make, words", [
    (lambda: tn.Net([[0, 0, 0], [0, 0, 0], [1, 0, 0]], PATH), ["spring 0", "zero length"]),
    (lambda: tn.Net(TRI, [[0, 1], [1, 2], [1, 0]]), ["springs 0 and 2", "duplicate"]),
    (lambda: tn.Net(TRI, [[0, 1], [2, 2]]), ["spring 1", "both ends on node 2"]),
    (lambda: tn.Net(TRI, PATH, masses=[1.0, 0.0, 1.0]), ["node 1", "mass"]),
    (lambda: tn.Net(TRI, PATH, masses=[1.0, 1.0, -2.0]), ["node 2", "mass"]),
    (lambda: tn.Net(TRI, PATH, masses=[1.0, np.nan, 1.0]), ["node 1", "mass"]),
    (lambda: tn.Net(TRI, PATH, masses="heavy"), ["masses"]),
    (lambda: tn.Net(TRI, PATH, rest_lengths=[1.0, 0.0]), ["spring 1", "rest length"]),
    (lambda: tn.Net(TRI, PATH, rest_lengths=[-1.0, 1.0]), ["spring 0", "rest length"]),
    (lambda: tn.Net([[0, 0, 0], [1, np.nan, 0], [0, 1, 0]], PATH), ["node 1", "non-finite"]),
    (lambda: tn.Net([[0, 0, 0], [1, 0, 0], [0, 1, np.inf]], PATH), ["node 2", "non-finite"]),
    (lambda: tn.Net(TRI, np.zeros((0, 2), int)), ["no springs"]),
    (lambda: tn.Net(TRI, [[0, 3], [1, 2]]), ["spring 0", "0..2"]),
    (lambda: tn.Net(TRI, [[0, 1.5], [1, 2]]), ["integers"]),
    (lambda: tn.Simulation(good_net(), parameters={"C0": [5.0, 0.0]}), ["'C0'", "spring 1", "> 0"]),
    (lambda: tn.Simulation(good_net(), parameters={"C0": -5.0}), ["'C0'", "spring 0", "> 0"]),
    (lambda: tn.Simulation(good_net(), parameters={"theta0": [300.0, -1.0]}), ["'theta0'", "spring 1"]),
    (lambda: tn.Simulation(good_net(), model="quadratic", parameters={"theta0": 0.0}), ["'theta0'", "spring 0"]),
    (lambda: tn.Simulation(good_net(), model="quadratic", parameters={"C0": [1.0, 0.0]}), ["'C0'", "spring 1"]),
    (lambda: tn.Simulation(good_net(), parameters={"c": [1.0, np.inf]}), ["'c'", "spring 1", "not finite"]),
    (lambda: tn.Simulation(good_net(), parameters={"E": 1.0}), ["no parameter", "E", "c, beta, C0, theta0"]),
    (lambda: tn.Simulation(good_net(), parameters={"c": "stiff"}), ["'c'", "not a number"]),
    (lambda: tn.Simulation(good_net(), temperatures=[300.0, 0.0]), ["spring 1", "temperature", "> 0"]),
    (lambda: tn.Simulation(good_net(), temperatures=[-3.0, 300.0]), ["spring 0", "temperature"]),
    (lambda: tn.Simulation(good_net(), temperatures=[np.nan, 300.0]), ["spring 0", "temperature"]),
    (lambda: tn.Simulation(good_net(), temperatures=[300.0] * 3), ["one per spring (2)"]),
    (lambda: tn.Simulation(good_net(), momenta=np.zeros((2, 3))), ["momenta", "(3, 3)"]),
    (lambda: tn.Simulation(good_net(), velocities=[[0, 0, 0], [np.nan, 0, 0], [0, 0, 0]]), ["node 1", "not finite"]),
    (lambda: tn.Simulation(tn.Net(TRI, PATH, anchored=[1]), momenta=[[0, 0, 0], [1, 0, 0], [0, 0, 0]]),
     ["node 1", "anchored"]),
    (lambda: tn.Simulation(good_net(), h=0.0), ["time step", "> 0"]),
    (lambda: tn.Simulation(good_net(), h=np.nan), ["time step"]),
    (lambda: tn.lattice((2, 2, 2), neighbours=7), ["neighbours", "6, 18 or 26"]),
])
def test_bad_input_is_named(make, words):
    with pytest.raises(tn.InputError) as info:
        make()
    message = str(info.value)
    for word in words:
        assert word in message, f"{word!r} not in {message!r}"


@pytest.mark.parametrize("kind, make", [
    ("model", lambda: tn.Simulation(good_net(), model="neo-hookean")),
    ("integrator", lambda: tn.Simulation(good_net(), integrator="rk4")),
    ("integrator", lambda: tn.get_integrator("verlet")),
    ("model", lambda: tn.get_model("Hooke")),
])
def test_unknown_names_list_the_known_ones(kind, make):
    with pytest.raises(tn.UnknownNameError) as info:
        make()
    assert isinstance(info.value, tn.InputError)
    message = str(info.value)
    assert f"unknown {kind}" in message
    known = tn.available_models() if kind == "model" else tn.available_integrators()
    assert len(known) >= 2
    for name in known:
        assert name in message


@pytest.mark.parametrize("cells, words", [
    ([("vertex", np.array([[0], [1]]))], ["no cells that give springs"]),
    ([], ["no cells that give springs"]),
    ([("triangle", np.zeros((0, 3), dtype=int))], ["no cells that give springs"]),
    ([("polygon", np.array([[0, 1, 2]]))], ["no cells", "polygon"]),
    ([("triangle", np.array([[0, 1, 1]]))], ["triangle cell 0", "degenerate", "point 1"]),
    ([("triangle", np.array([[0, 1, 7]]))], ["triangle cell 0", "outside"]),
])
def test_meshes_without_usable_edges(cells, words):
    mesh = meshio.Mesh(np.array(TRI), cells)
    with pytest.raises(tn.MeshError) as info:
        tn.from_meshio(mesh)
    for word in words:
        assert word in str(info.value)


def test_mesh_problems_are_named(tmp_path):
    mesh = meshio.Mesh(np.array(TRI + [[0.0, 0.0, 0.0]]), [("triangle", np.array([[0, 1, 2], [0, 1, 3]]))])
    with pytest.raises(tn.MeshError, match=r"mesh points \[0, 3\] coincide"):
        tn.from_meshio(mesh)
    far = meshio.Mesh(np.array([[0.0, 0.0, 0.0], [1e300, 1e300, 0.0], [0.0, 1.0, 0.0]]),
                      [("line", np.array([[0, 2], [0, 1]]))])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow warning from inside NumPy either
        with pytest.raises(tn.MeshError, match=r"mesh points \[0, 1\] has no finite length"):
            tn.from_meshio(far)
    mesh = meshio.Mesh(np.array(TRI), [("triangle", np.array([[0, 1, 2]]))])
    with pytest.raises(tn.MeshError, match="anchor group 'clamp' does not exist"):
        tn.from_meshio(mesh, anchors="clamp")
    with pytest.raises(tn.MeshError, match="no point-data field 'rho'"):
        tn.from_meshio(mesh, mass="rho")
    with pytest.raises(tn.MeshError, match="density must be > 0"):
        tn.from_meshio(mesh, density=-1.0)
    with pytest.raises(tn.MeshError, match="no such mesh file"):
        tn.read_mesh(tmp_path / "missing.msh")
    garbage = tmp_path / "garbage.msh"
    garbage.write_text("this is not a mesh\n")
    with pytest.raises(tn.MeshError, match="garbage.msh"):
        tn.read_mesh(garbage)


def test_plain_python_numbers_run():
    """Integer lists everywhere: converted, not a Numba typing error."""
    net = tn.Net([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [(0, 1), (1, 2)], masses=[1, 2, 3], rest_lengths=[1, 1])
    sim = tn.Simulation(net, parameters={"c": [100, 50], "beta": 0, "C0": 5, "theta0": 300},
                        temperatures=[400, 500], momenta=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], integrator="CO2", h=1)
    sim.h = 0.01
    sim.run(steps=10)
    assert np.isfinite(sim.state.positions).all()


def test_a_blow_up_stops_with_a_named_spring_not_nans():
    """Two nodes drifting onto each other within one GTR-0 step: the spring length becomes 0.
    The kernel stops in that step and the state is rewound to the last good one (the start)."""
    net = tn.Net([[0.0, 0, 0], [1.0, 0, 0]], [[0, 1]])
    sim = tn.Simulation(net, velocities=[[0.5, 0, 0], [-0.5, 0, 0]], integrator="gtr-0", h=1.0)
    with pytest.raises(tn.SimulationError, match=r"step 1 .*spring 0 \(nodes 0–1\) has stretch l/l0 = 0 .*collapsing"):
        sim.run(steps=3)
    assert sim.step == 0
    np.testing.assert_array_equal(sim.state.positions, net.positions)


def test_a_vanishing_temperature_stops_the_run():
    """The quadratic model's θ(l, η) is affine and reaches zero under strong stretching."""
    sim = tn.Simulation(tn.chain(), model="quadratic", parameters=dict(E=100.0, beta=5.0, C0=0.1, theta0=300.0),
                        temperatures=[10.0, 10.0, 10.0], momenta=[[0, 0, 0], [20, 0, 0], [0, 0, 0], [0, 0, 0]], h=0.01)
    with pytest.raises(tn.SimulationError, match=r"in step \d+ .*spring \d \(nodes \d–\d\) has temperature θ = -?[\d.e+-]+, not > 0"):
        sim.run(steps=300, diagnostics_every=1)
    # the run is rewound to the last good step: every temperature there is still positive
    assert sim.temperatures().min() > 0
    assert sim.diagnostics.theta_min[-1] > 0 and sim.diagnostics.step[-1] == sim.step


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(1, 6),
    edges=st.lists(st.tuples(st.integers(-1, 6), st.integers(-1, 6)), min_size=0, max_size=8),
    coincide=st.booleans(),
)
def test_any_edge_list_gives_a_net_or_an_input_error(n, edges, coincide):
    rng = np.random.default_rng(n)
    x = rng.uniform(-1, 1, (n, 3))
    if coincide and n > 1:
        x[1] = x[0]
    try:
        net = tn.Net(x, np.array(edges, dtype=np.int64).reshape(-1, 2))
    except tn.InputError:
        return
    sim = tn.Simulation(net, temperatures=350.0, integrator="co2", h=1e-3)
    sim.run(steps=5)
    assert np.isfinite(sim.state.positions).all()


def test_velocities_whose_momentum_overflows_are_named_without_a_numpy_warning():
    net = tn.Net([[0, 0, 0], [1, 0, 0]], [[0, 1]], masses=[1.0, 10.0])
    v = np.zeros((2, 3))
    v[1] = [1e308, 0.0, 0.0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(tn.InputError, match=r"node 1: initial momentum m v overflows \(velocity \[1e\+308"):
            tn.Simulation(net, velocities=v)
