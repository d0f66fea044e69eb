"""The explicit kernel's results are bit-for-bit reproducible: one long call equals the same steps
cut into chunks at any step boundaries, and the parallel kernel gives identical arrays on one and
on two threads, and the same as the serial kernel (springs and nodes are each computed by one
thread in a fixed order; the two kicks that meet at a step boundary are separate additions)."""

import numba
import numpy as np
import pytest

import thermonet as tn

# more springs than one block of the spring pass (512), with a partial last block
SHAPE, NEIGHBOURS = (6, 5, 5), 18


def make(model, integrator, uniform, gravity=None, **options):
    rng = np.random.default_rng(11)
    net = tn.lattice(SHAPE, neighbours=NEIGHBOURS, jitter=0.2, seed=3)
    n, m = net.n_nodes, net.n_springs
    anchored = np.zeros(n, dtype=bool)
    anchored[rng.choice(n, 4, replace=False)] = True
    net = tn.Net(net.positions, net.edges, rng.uniform(0.5, 2.0, n), anchored)
    momenta = rng.normal(0.0, 1.0, (n, 3))
    momenta[anchored] = 0.0
    if model == "hencky":
        params = dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0)
    else:
        params = dict(E=80.0, beta=0.2, C0=5.0, theta0=300.0, eta0=0.1)
    if not uniform:
        params = {k: v * rng.uniform(0.9, 1.1, m) for k, v in params.items()}
    return tn.Simulation(net, model=model, parameters=params, temperatures=rng.uniform(250.0, 400.0, m),
                         momenta=momenta, integrator=integrator, h=2e-3, gravity=gravity, **options)


def final_arrays(sim):
    s = sim.state
    return s.positions, s.momenta, s.thermal_displacement, s.entropy


def assert_identical(a, b, what):
    for name, x, y in zip(("x", "p", "phi", "eta"), a, b):
        if x is None and y is None:
            continue
        assert np.array_equal(x, y), f"{what}: {name} differs by up to {np.abs(x - y).max():.3e}"


CASES = [
    ("hencky", "co2", True, None),
    ("hencky", "co4", False, None),
    ("quadratic", "f10", False, (0.0, 0.0, -1.0)),
    ("hencky", "gtr-0", True, (0.0, -9.81, 0.0)),
]
# The threaded kernel is the serial template with its loops split by blocks; a model only supplies
# scalar functions inlined into either. So the threaded checks run the Hencky cases with shared
# parameters, and the other threaded variants, a minute or more of compilation each on a cold
# cache, are not built for them: the quadratic model's, and the per-spring parameter layout's
# (tests/test_loads_heat.py's threaded kernel with loads and heat has that layout).
THREADED_CASES = [case for case in CASES if case[0] == "hencky" and case[2]]
SERIAL_AND_THREADED = [(*case, False) for case in CASES] + [(*case, True) for case in THREADED_CASES]


@pytest.mark.parametrize("model, integrator, uniform, gravity, parallel", SERIAL_AND_THREADED)
def test_chunks_give_the_one_long_call(model, integrator, uniform, gravity, parallel):
    one = make(model, integrator, uniform, gravity, parallel=parallel)
    one.run(steps=60, diagnostics_every=10**9)
    chunked = make(model, integrator, uniform, gravity, parallel=parallel)
    for n in (1, 7, 2, 13, 37):
        chunked.run(steps=n, diagnostics_every=3)  # the cadence cuts these further
    assert chunked.step == one.step == 60
    assert_identical(final_arrays(one), final_arrays(chunked), "chunked vs one call")


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two threads")
@pytest.mark.parametrize("model, integrator, uniform, gravity", THREADED_CASES)
def test_one_and_two_threads_and_the_serial_kernel_agree_bit_for_bit(model, integrator, uniform, gravity):
    results = {}
    try:
        for label, options in {"serial": dict(parallel=False), "1 thread": dict(parallel=True, threads=1),
                               "2 threads": dict(parallel=True, threads=2)}.items():
            sim = make(model, integrator, uniform, gravity, **options)
            sim.run(steps=50, diagnostics_every=10)
            results[label] = final_arrays(sim)
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    assert_identical(results["1 thread"], results["2 threads"], "1 vs 2 threads")
    assert_identical(results["serial"], results["2 threads"], "serial vs parallel kernel")


def test_a_chunk_starts_from_the_previous_closing_kick_only_when_the_state_is_that_one():
    """A call keeps its closing kick's forces and temperatures and the next call from the same
    state starts from them (no second evaluation at an observer stop); a loaded state, though it
    has the same step, must be evaluated afresh."""
    sim = make("hencky", "co2", True)
    sim.run(steps=5, diagnostics_every=5)
    kept_state, kept_step = sim.stepper._boundary
    assert kept_state is sim.internal_state() and kept_step == 5
    state = sim.state
    state.positions = state.positions + 1e-3 * np.sin(np.arange(state.positions.size)).reshape(-1, 3)
    sim.load_state(state)  # same step, other positions: the kept forces are stale
    sim.run(steps=5, diagnostics_every=5)
    fresh = make("hencky", "co2", True)
    fresh.load_state(state)
    fresh.run(steps=5, diagnostics_every=5)
    assert_identical(final_arrays(fresh), final_arrays(sim), "after load_state")


@pytest.mark.parametrize("model, integrator, uniform, gravity, parallel", SERIAL_AND_THREADED)
def test_rows_reduced_by_the_closing_kick_equal_the_stand_alone_reduction(model, integrator, uniform, gravity,
                                                                          parallel):
    """A diagnostics stop's sums come from the closing kick of the call that ends there; they must
    be those of the stand-alone reduction of the same state (the same terms, the same block
    order: bit for bit serial, round-off of a sum when threaded)."""
    from thermonet.diagnostics import measure

    sim = make(model, integrator, uniform, gravity, parallel=parallel)
    sim.run(steps=12, diagnostics_every=4)
    fused = sim.stepper.closing_sums(sim.internal_state()) is not None
    assert fused == (sim.integrator.kicks[-1] != 0.0)  # schemes without a closing kick reduce apart
    row, alone = sim.diagnostics.rows[-1], measure(sim.system, sim.internal_state(), parallel)
    for key, value in alone.items():
        if parallel:
            assert row[key] == pytest.approx(value, rel=1e-13, abs=1e-13 * abs(alone["energy"])), key
        else:
            assert row[key] == value, key


def test_mechanical_rows_reduced_by_the_closing_kick_equal_the_stand_alone_reduction():
    from thermonet.diagnostics import measure

    net = tn.lattice(SHAPE, neighbours=NEIGHBOURS, jitter=0.2, seed=3)
    v = np.random.default_rng(5).normal(0.0, 1.0, (net.n_nodes, 3))
    sim = tn.Simulation(net, velocities=v, thermal=False, integrator="co2", h=2e-3, gravity=(0, 0, -1), parallel=False)
    sim.run(steps=12, diagnostics_every=4)
    assert sim.stepper.closing_sums(sim.internal_state()) is not None
    row, alone = sim.diagnostics.rows[-1], measure(sim.system, sim.internal_state(), False)
    assert {k: row[k] for k in alone} == alone


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two threads")
def test_a_run_with_threads_leaves_numbas_thread_count_as_it_found_it():
    """threads=1 holds for that simulation's runs only: a later simulation without ``threads``
    (or a study, or a benchmark's next case) runs on Numba's own setting again."""
    before = numba.get_num_threads()
    sim = make("hencky", "co2", True, parallel=True, threads=1)
    sim.run(steps=3, diagnostics_every=3)
    assert numba.get_num_threads() == before
