"""Loads and heat flow together: one energy balance H − H(0) − W − ΣQ, of order 2 and without
drift; chunked and resumed runs bit-identical; around an implicit integrator too. (The
CUDA simulator against the CPU: tests/test_loads_cuda.py.)"""

import numpy as np
import pytest

import thermonet as tn
from thermonet.heat import Bath, Source
from thermonet.loads import Drive, Force

QUIET = dict(stability_guard="off", energy_tolerance=None)
PARAMETERS = dict(c=100, beta=1.0, C0=1.0, theta0=300, g=0.4)


def strip(n=6):
    """A 2 × n strip of triangles (springs along, across and one diagonal per cell), rest
    lengths those of the drawn positions; node groups "left" (x = 0), "right" (x = n)."""
    x = np.array([[i, j, 0.0] for i in range(n + 1) for j in range(2)])
    k = lambda i, j: 2 * i + j  # noqa: E731
    edges = [(k(i, 0), k(i, 1)) for i in range(n + 1)]
    edges += [(k(i, j), k(i + 1, j)) for i in range(n) for j in range(2)]
    edges += [(k(i, 0), k(i + 1, 1)) for i in range(n)]
    edges = np.array(edges)
    rest = np.linalg.norm(x[edges[:, 1]] - x[edges[:, 0]], axis=1)
    return tn.Net(x, edges, np.ones(len(x)), rest_lengths=rest,
                  node_groups={"left": [k(0, 0), k(0, 1)], "right": [k(n, 0), k(n, 1)]})


def varied_parameters():
    """PARAMETERS per spring of the strip, stiffness and coupling varied by up to 10 % (g and C
    shared: the GPU sweep order's blocks still pair, see the thread-count test). The explicit
    runs here all take them: one kernel variant to compile (per-spring parameters, the layout of
    a continuum part's springs), not a second one for uniform parameters."""
    m = strip().n_springs
    rng = np.random.default_rng(9)
    varied = {k: np.full(m, float(v)) for k, v in PARAMETERS.items()}
    varied["c"] *= rng.uniform(0.9, 1.1, m)
    varied["beta"] *= rng.uniform(0.9, 1.1, m)
    return varied


def loaded_hot_strip(h, integrator="co2", parameters=None, **kw):
    net = strip()
    if parameters is None:
        parameters = varied_parameters() if integrator == "co2" else PARAMETERS
    rng = np.random.default_rng(5)
    theta = 300 + 150 * rng.random(net.n_springs)
    return tn.Simulation(net, parameters=parameters, temperatures=theta, h=h, integrator=integrator,
                         baths={"cold": Bath("left", 250.0)},
                         sources={"s": Source([0, 1], {"amplitude": 5.0, "frequency": 0.5, "offset": 2.0})},
                         loads={"shake": Drive("right", {"x": {"amplitude": 0.05, "frequency": 0.7}}),
                                "push": Force("right", [0.0, 0.3, 0.0], total=True)},
                         **QUIET, **kw)


def balance(h, t_end=2.0, integrator="co2"):
    sim = loaded_hot_strip(h, integrator)
    d = sim.run(t_end=t_end, diagnostics_every=max(1, round(0.02 / h)))
    return d


def test_the_energy_balance_counts_work_and_heat_and_is_order_2():
    coarse, fine = balance(0.004), balance(0.002)
    for d in (coarse, fine):
        # the drive's work and the bath's heat are real; the balance is the splitting's error
        assert np.max(np.abs(d.work)) > 10.0 and np.max(np.abs(d.heat_in)) > 100.0
        assert np.max(np.abs(d.energy_balance)) < 1e-3 * np.max(np.abs(d.energy))
        np.testing.assert_allclose(d.energy_balance, d.energy - d.energy[0] - d.work - (d.heat_in - d.heat_in[0]),
                                   rtol=0, atol=1e-12 * np.max(np.abs(d.energy)))
    ratio = np.max(np.abs(coarse.energy_balance)) / np.max(np.abs(fine.energy_balance))
    assert 3.0 < ratio < 5.0, ratio


def test_the_balance_with_loads_and_heat_does_not_drift():
    d = balance(0.004, t_end=200.0)
    b = np.abs(d.energy_balance)
    k = len(b) // 10
    assert b[-k:].max() < 2.0 * b[:2 * k].max(), (b[:2 * k].max(), b[-k:].max())
    assert np.all(np.diff(d.entropy_produced) >= 0)


def test_chunked_and_resumed_runs_with_loads_and_heat_are_bit_identical(tmp_path):
    from thermonet.io.checkpoint import load_checkpoint, save_checkpoint

    # (conduction every step: calls of 7 steps; cycles cut by calls: tests/test_heat_flow.py)
    one = loaded_hot_strip(0.004, conduction_every=1)
    one.run(steps=400, diagnostics_every=400)
    chunked = loaded_hot_strip(0.004, conduction_every=1)
    for _ in range(4):
        chunked.run(steps=100, diagnostics_every=7)
    first = loaded_hot_strip(0.004, conduction_every=1)
    first.run(steps=150, diagnostics_every=50)
    save_checkpoint(tmp_path / "c.npz", first.state, {})
    state, _ = load_checkpoint(tmp_path / "c.npz")
    resumed = loaded_hot_strip(0.004, conduction_every=1)
    resumed.load_state(state)
    resumed.run(steps=250, diagnostics_every=50)
    for other in (chunked, resumed):
        assert np.array_equal(one.state.positions, other.state.positions)
        assert np.array_equal(one.state.momenta, other.state.momenta)
        assert np.array_equal(one.state.entropy, other.state.entropy)
        assert np.array_equal(one.state.extra["load_work"], other.state.extra["load_work"])
        assert np.array_equal(one.state.extra["heat"]["entry_heat"], other.state.extra["heat"]["entry_heat"])


def same_bits(a, b):
    for f in ("positions", "momenta", "thermal_displacement", "entropy"):
        assert np.array_equal(getattr(a.state, f), getattr(b.state, f)), f
    assert np.array_equal(a.state.extra["load_work"], b.state.extra["load_work"])
    for k in ("produced", "entry_heat", "entry_flux"):
        assert np.array_equal(a.state.extra["heat"][k], b.state.extra["heat"][k]), k


@pytest.mark.parametrize("every, order", [(1, "cpu"), ((4, 2), "cpu"), (1, "cuda")])
def test_the_threaded_kernel_with_loads_and_heat_does_not_depend_on_the_thread_count(every, order):
    """One threaded kernel carries both effects (each alone would be a threaded variant of its own
    to compile): one and two threads give the same bits, in chunks that cut conduction cycles (of
    4 steps with 2 sub-sweeps in one case), and
    the serial kernel's bits for everything but the loads' reductions' round-off. In the GPU's
    sweep order (one junction per block, 4 blocks per colour) the serial kernel takes a colour's
    blocks in pairs, and so does the threaded one with a pool of two threads (one block at a time
    with more): the same bits. Per-spring parameters (:func:`varied_parameters`): this is also
    the suite's threaded kernel for that parameter layout."""

    def make(**kw):
        k, j = every if isinstance(every, tuple) else (every, 1)
        sim = loaded_hot_strip(0.004, conduction_every=k, conduction_sweeps=j, **kw)
        sim.system.heat.use_order_of(order)
        return sim

    serial = make()
    serial.run(steps=240, diagnostics_every=240)
    runs = {}
    for threads in (1, 2):
        sim = make(parallel=True, threads=threads)
        for n in (3, 37, 200):
            sim.runner.advance(n)
        runs[threads] = sim
    same_bits(runs[1], runs[2])
    for k in ("produced", "entry_heat", "entry_flux"):
        assert np.array_equal(serial.state.extra["heat"][k], runs[2].state.extra["heat"][k]), k
    assert np.array_equal(serial.state.entropy, runs[2].state.entropy)
    np.testing.assert_allclose(runs[2].state.positions, serial.state.positions, rtol=0, atol=1e-13)


def test_loads_with_conduction_around_an_implicit_integrator_keep_the_balance_of_order_2():
    coarse, fine = balance(0.008, 1.0, "gtr-1/2"), balance(0.004, 1.0, "gtr-1/2")
    ratio = np.max(np.abs(coarse.energy_balance)) / np.max(np.abs(fine.energy_balance))
    assert 3.0 < ratio < 5.0, ratio
    assert np.all(np.diff(fine.entropy_produced) >= 0)
