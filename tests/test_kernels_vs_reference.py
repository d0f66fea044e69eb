"""The Numba kernels against the plain NumPy reference (thermonet.reference), step for step.

Both start from the same state (read back from the Simulation in the user's numbering); the
kernel runs through the public API, the reference applies the spec's formulas directly. The
two differ only in the order of floating-point operations, so they must agree to round-off:
a few steps amplify a 1e-16 relative difference by at most a small factor here.
"""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import thermonet as tn
from thermonet import reference as ref
from thermonet.paper import (CHAIN_MOMENTA, CHAIN_PARAMETERS, CHAIN_TEMPERATURES, TRIANGLE_MOMENTA,
                             TRIANGLE_PARAMETERS, TRIANGLE_TEMPERATURES)

INTEGRATORS = ("gtr-0", "gtr-1", "co2", "f10", "nm2", "co4", "co6")
ROUND_OFF = 1e-12  # relative to the size of each compared array


def random_lattice_case(model="hencky", seed=1, anchors=True):
    """A jittered 18-neighbour lattice with random masses, momenta, temperatures and
    per-spring parameters, some nodes anchored."""
    rng = np.random.default_rng(seed)
    net = tn.lattice((3, 2, 2), neighbours=18, jitter=0.2, seed=seed)
    n, m = net.n_nodes, net.n_springs
    anchored = np.zeros(n, dtype=bool)
    if anchors:
        anchored[rng.choice(n, 3, replace=False)] = True
    net = tn.Net(net.positions, net.edges, rng.uniform(0.5, 2.0, n), anchored,
                 rest_lengths=net.rest_lengths * rng.uniform(0.9, 1.1, m))
    momenta = rng.normal(0.0, 2.0, (n, 3))
    momenta[anchored] = 0.0
    if model == "hencky":
        params = {"c": rng.uniform(50, 150, m), "beta": rng.uniform(0.1, 0.3, m),
                  "C0": rng.uniform(3, 6, m), "theta0": rng.uniform(250, 350, m)}
    else:
        params = {"E": rng.uniform(50, 150, m), "beta": rng.uniform(0.1, 0.3, m), "C0": rng.uniform(3, 6, m),
                  "theta0": rng.uniform(250, 350, m), "eta0": rng.uniform(-1, 1, m)}
    temperatures = rng.uniform(250, 600, m)
    return net, model, params, temperatures, momenta


CASES = {
    "chain": lambda: (tn.chain(), "hencky", CHAIN_PARAMETERS, CHAIN_TEMPERATURES, CHAIN_MOMENTA),
    "triangle": lambda: (tn.triangle(), "hencky", TRIANGLE_PARAMETERS, TRIANGLE_TEMPERATURES, TRIANGLE_MOMENTA),
    "lattice-hencky": lambda: random_lattice_case("hencky", seed=1),
    "lattice-quadratic": lambda: random_lattice_case("quadratic", seed=2),
}


def start(case, integrator, h, **options):
    net, model, params, temperatures, momenta = case
    sim = tn.Simulation(net, model=model, parameters=params, temperatures=temperatures, momenta=momenta,
                        integrator=integrator, h=h, **options)
    rnet = ref.ReferenceNet.build(net, model, params)
    s = sim.state
    return sim, rnet, ref.ReferenceState(s.positions, s.momenta, s.thermal_displacement, s.entropy)


def assert_round_off(actual, expected, what):
    scale = max(np.abs(expected).max(), 1e-300)
    err = np.abs(actual - expected).max() / scale
    assert err <= ROUND_OFF, f"{what}: relative difference {err:.2e}"


@pytest.mark.parametrize("case_name", list(CASES))
def test_initial_entropy_and_fields_match_the_reference(case_name):
    case = CASES[case_name]()
    net, model, params, temperatures, momenta = case
    sim, rnet, s0 = start(case, "co2", 0.01)
    assert_round_off(sim.state.entropy, rnet.entropies(net.positions, np.broadcast_to(temperatures, (net.n_springs,))),
                     "initial entropy")
    assert_round_off(sim.temperatures(), rnet.temperatures(s0.x, s0.eta), "temperatures")
    assert_round_off(sim.tensions(), rnet.tensions(s0.x, s0.eta), "tensions")
    assert_round_off(sim.lengths(), rnet.lengths(s0.x), "lengths")
    sim.run(steps=0)
    assert sim.diagnostics.energy[0] == pytest.approx(rnet.energy(s0.x, s0.p, s0.eta), rel=1e-13)


@pytest.mark.parametrize("integrator", INTEGRATORS)
@pytest.mark.parametrize("case_name", list(CASES))
def test_kernel_step_matches_reference_step(case_name, integrator):
    case = CASES[case_name]()
    h = 0.005
    sim, rnet, s = start(case, integrator, h)
    reference_step = ref.steps()[integrator]
    for n_steps in (1, 4):  # one step, then a chunk in one compiled call
        sim.run(steps=n_steps, diagnostics_every=10**9)
        s = ref.run(rnet, s, reference_step, h, n_steps)
        got = sim.state
        assert_round_off(got.positions, s.x, f"{integrator} positions")
        assert_round_off(got.momenta, s.p, f"{integrator} momenta")
        if integrator == "nm2":
            assert np.all(got.thermal_displacement == 0.0)
        else:
            assert_round_off(got.thermal_displacement, s.phi, f"{integrator} Φ")
        assert np.array_equal(got.entropy, s.eta)


def test_reference_forces_are_minus_the_gradient_of_the_internal_energy():
    """The reference's own scatter checked against finite differences of Σ U(l(x), η)."""
    net, model, params, temperatures, momenta = random_lattice_case("hencky", seed=3)
    rnet = ref.ReferenceNet.build(net, model, params)
    eta = rnet.entropies(net.positions, temperatures)
    x = net.positions + np.random.default_rng(3).normal(0, 0.02, net.positions.shape)
    f = rnet.forces(x, eta)

    def potential(y):
        return np.sum(rnet.law.internal_energy(rnet.lengths(y), eta, rnet.rest_lengths, rnet.parameters))

    delta = 1e-4
    for a in np.flatnonzero(~net.anchored)[:6]:
        for k in range(3):
            e = np.zeros_like(x)
            e[a, k] = delta
            # 4th-order central difference
            g = (-potential(x + 2 * e) + 8 * potential(x + e) - 8 * potential(x - e) + potential(x - 2 * e)) / (12 * delta)
            assert -g == pytest.approx(f[a, k], abs=1e-6 * np.abs(f).max())
    assert np.all(f[net.anchored] == 0.0)


def test_parallel_kernel_gives_the_serial_result():
    net = tn.lattice((6, 5, 4), neighbours=26, jitter=0.2, seed=5)
    rng = np.random.default_rng(5)
    anchored = np.zeros(net.n_nodes, dtype=bool)
    anchored[:7] = True
    net = tn.Net(net.positions, net.edges, rng.uniform(0.5, 2, net.n_nodes), anchored)
    momenta = rng.normal(0, 1, (net.n_nodes, 3))
    momenta[anchored] = 0.0
    temperatures = rng.uniform(250, 600, net.n_springs)
    states = {}
    for label, options in {"serial": dict(parallel=False), "parallel": dict(parallel=True),
                           "parallel-1-thread": dict(parallel=True, threads=1)}.items():
        sim = tn.Simulation(net, temperatures=temperatures, momenta=momenta, integrator="co4", h=0.002, **options)
        assert sim.parallel == options["parallel"]
        sim.run(steps=50, diagnostics_every=10**9)
        states[label] = sim.state
    import numba

    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    base = states["serial"]
    for label in ("parallel", "parallel-1-thread"):
        got = states[label]
        assert_round_off(got.positions, base.positions, f"{label} positions")
        assert_round_off(got.momenta, base.momenta, f"{label} momenta")
        assert_round_off(got.thermal_displacement, base.thermal_displacement, f"{label} Φ")
        assert np.array_equal(got.entropy, base.entropy)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    n_nodes=st.integers(3, 12),
    seed=st.integers(0, 2**31 - 1),
    edge_fraction=st.floats(0.2, 1.0),
    n_anchors=st.integers(0, 2),
    integrator=st.sampled_from(INTEGRATORS),
)
def test_random_nets_match_the_reference(n_nodes, seed, edge_fraction, n_anchors, integrator):
    """Any topology (random graph on random points), any masses, anchors and momenta."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, (n_nodes, 3))
    pairs = np.array([(a, b) for a in range(n_nodes) for b in range(a + 1, n_nodes)])
    keep = rng.random(len(pairs)) < edge_fraction
    keep[rng.integers(len(pairs))] = True
    edges = pairs[keep][:, rng.permutation(2)]  # random orientation
    anchored = np.zeros(n_nodes, dtype=bool)
    anchored[rng.choice(n_nodes, n_anchors, replace=False)] = True
    net = tn.Net(x, edges, rng.uniform(0.5, 2, n_nodes), anchored, rest_lengths=None)
    momenta = rng.normal(0, 1, (n_nodes, 3))
    momenta[anchored] = 0.0
    case = (net, "hencky", {"c": 50.0}, rng.uniform(250, 500, net.n_springs), momenta)
    h = 0.002
    sim, rnet, s = start(case, integrator, h)
    sim.run(steps=3, diagnostics_every=10**9)
    s = ref.run(rnet, s, integrator, h, 3)
    assert_round_off(sim.state.positions, s.x, "positions")
    assert_round_off(sim.state.momenta, s.p, "momenta")
