"""Fourier conduction, baths and sources (docs/theory.md §5): the checks of §5.8 and more."""

import numpy as np
import pytest

import thermonet as tn
from thermonet.errors import InputError
from thermonet.heat import Bath, Source
from thermonet.heat.graph import pair_graph
from thermonet.layout import build_layout

QUIET = dict(stability_guard="off", energy_tolerance=None)


def chain_net(n_springs: int, spacing: float = 1.0) -> tn.Net:
    x = np.zeros((n_springs + 1, 3))
    x[:, 0] = spacing * np.arange(n_springs + 1)
    edges = np.column_stack([np.arange(n_springs), np.arange(1, n_springs + 1)])
    return tn.Net(x, edges, masses=np.ones(n_springs + 1),
                  node_groups={"left": np.array([0]), "right": np.array([n_springs]),
                               "empty": np.array([], dtype=np.int64)},
                  spring_groups={"middle": np.array([n_springs // 2])})


def test_junction_rule_on_a_star_and_the_colouring():
    # four springs meeting at node 0, conductances 1, 2, 3, 4: κ_ef = g_e g_f / 10
    net = tn.Net([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0]], [[0, 1], [0, 2], [0, 3], [0, 4]])
    layout = build_layout(net, renumber=False)
    g = np.array([1.0, 2.0, 3.0, 4.0])
    graph = pair_graph(layout, g[None, :])
    assert graph.n_pairs == 6
    for a, b, k in zip(graph.first, graph.second, graph.kappa[:, 0]):
        assert k == pytest.approx(g[a] * g[b] / g.sum())
    ptr = graph.colour_ptr
    for c in range(graph.n_colours):  # no spring twice in a colour
        springs = np.r_[graph.first[ptr[c]:ptr[c + 1]], graph.second[ptr[c]:ptr[c + 1]]]
        assert len(set(springs.tolist())) == len(springs)
    assert graph.n_colours == 3  # K4's edges need exactly three colours


@pytest.mark.parametrize("n_springs, n_pairs", [(50, 400), (20, 2000)])
def test_pair_colouring_is_the_greedy_one_beyond_64_colours(n_springs, n_pairs):
    """The compiled colouring (bit masks of 64 colours a word) against greedy colouring in plain
    Python: each pair, in order, the smallest colour free at both its springs; on dense random
    pair lists that need one word and several."""
    from thermonet.heat.graph import colour_pairs

    rng = np.random.default_rng(n_pairs)
    first, second = rng.integers(0, n_springs, (2, n_pairs))
    keep = first != second
    first, second = first[keep], second[keep]
    taken = [set() for _ in range(n_springs)]
    expected = []
    for e, f in zip(first.tolist(), second.tolist()):
        c = 0
        while c in taken[e] or c in taken[f]:
            c += 1
        taken[e].add(c)
        taken[f].add(c)
        expected.append(c)
    colours = colour_pairs(first, second, n_springs)
    assert colours.tolist() == expected
    assert (max(expected) >= 128) == (n_springs == 20)


def cycle(every) -> dict:
    """The Simulation's arguments for a conduction cycle ``every``: k, or (k, j) with j sub-sweeps."""
    k, j = every if isinstance(every, tuple) else (every, 1)
    return dict(conduction_every=k, conduction_sweeps=j)


def steps_of(every) -> int:
    """The cycle's k."""
    return every[0] if isinstance(every, tuple) else every


def two_springs(C, g, h: float, every=1):
    """(θ0 − θ1 at t = 2, its exact value, the final C-weighted mean, the exact one, diagnostics)."""
    C, g = np.asarray(C, dtype=float), np.asarray(g, dtype=float)
    sim = tn.Simulation(chain_net(2), parameters=dict(c=100, beta=0.0, C0=C, theta0=300, g=g), temperatures=[800, 400],
                        h=h, renumber=False, **cycle(every), **QUIET)
    d = sim.run(t_end=2.0, diagnostics_every=10 * steps_of(every))
    kappa = g[0] * g[1] / g.sum()  # two springs at the middle node
    reduced = C[0] * C[1] / C.sum()
    theta = sim.temperatures()
    return (theta[0] - theta[1], 400.0 * np.exp(-kappa * 2.0 / reduced), (C * theta).sum() / C.sum(),
            (C[0] * 800 + C[1] * 400) / C.sum(), d)


@pytest.mark.parametrize("every", [1, 5, (5, 2)])
def test_two_springs_relax_along_the_exact_exponential_with_energy_to_round_off(every):
    # equal rates g/C at the junction: the node-star exchange is the exact flow, whatever k h
    gap, exact, mean, exact_mean, d = two_springs([5.0, 2.0], [1.75, 0.7], 0.01, every)
    assert gap == pytest.approx(exact, rel=1e-12)
    assert mean == pytest.approx(exact_mean, rel=1e-14)
    assert np.max(np.abs(d.energy - d.energy[0])) < 1e-12 * abs(d.energy[0])
    # the production log is the entropy gained (no baths)
    assert d.entropy_produced[-1] == pytest.approx(d.entropy[-1] - d.entropy[0], rel=1e-12)
    # unequal rates: the common temperature exactly, the exponential to second order in k h
    errors = []
    for h in (0.02, 0.01):
        gap, exact, mean, exact_mean, d = two_springs([5.0, 2.0], [0.7, 0.7], h, every)
        assert mean == pytest.approx(exact_mean, rel=1e-14)
        assert np.max(np.abs(d.energy - d.energy[0])) < 1e-12 * abs(d.energy[0])
        errors.append(abs(gap - exact))
    assert 3.6 < errors[0] / errors[1] < 4.4, errors


def fourier_decay_rate(h: float, n_springs: int = 16, mode: int = 3, t_end: float = 2.0, every: int = 1) -> float:
    net = chain_net(n_springs)
    C, g, amp = 2.0, 1.0, 1e-3
    e = np.arange(n_springs)
    q = np.pi * mode / n_springs
    theta0 = 300.0 * (1 + amp * np.cos(q * (e + 0.5)))  # a Neumann eigenvector of the chain
    sim = tn.Simulation(net, parameters=dict(c=100, beta=0.0, C0=C, theta0=300, g=g), temperatures=theta0, h=h,
                        renumber=False, **cycle(every), **QUIET)
    sim.run(t_end=t_end, diagnostics_every=steps_of(every))
    shape = np.cos(q * (e + 0.5))
    a0 = shape @ (theta0 - 300.0)
    a1 = shape @ (sim.temperatures() - 300.0)
    return -np.log(a1 / a0) / t_end


def test_a_fourier_mode_decays_at_the_lattice_rate_with_order_2():
    q = np.pi * 3 / 16
    exact = (2 * 0.5 / 2.0) * (1 - np.cos(q))  # κ = g/2 between neighbours, C = 2
    hs = np.array([0.2, 0.1, 0.05])
    errors = np.array([abs(fourier_decay_rate(h) - exact) for h in hs])
    assert errors[-1] < 1e-3 * exact
    slope = np.polyfit(np.log(hs), np.log(errors), 1)[0]
    assert 1.8 < slope < 2.2, (errors, slope)


def test_multirate_conduction_is_second_order_in_k_h():
    # h fixed, conduction every k steps: the decay converges at order 2 in k h
    q = np.pi * 3 / 16
    exact = (2 * 0.5 / 2.0) * (1 - np.cos(q))
    ks = np.array([40, 20, 10])
    errors = np.array([abs(fourier_decay_rate(0.005, every=int(k)) - exact) for k in ks])
    slope = np.polyfit(np.log(ks), np.log(errors), 1)[0]
    assert 1.8 < slope < 2.2, (errors, slope)


def test_sub_sweeps_are_the_shorter_cycles_sweeps_and_second_order_in_k_h_over_j():
    # β = 0: the steps leave temperatures alone, so a cycle of 12 steps swept 3 times at each
    # boundary (half sweeps reverse, forward, reverse | forward, reverse, forward over 2 h) runs
    # the very half sweeps of a cycle of 4 steps swept once: the same temperatures to round-off
    q = np.pi * 3 / 16
    exact = (2 * 0.5 / 2.0) * (1 - np.cos(q))
    h = 0.005
    assert fourier_decay_rate(h, t_end=2.4, every=(12, 3)) == pytest.approx(
        fourier_decay_rate(h, t_end=2.4, every=4), rel=1e-10)
    # with j even too (forward, reverse | forward, reverse over 3 h: the cycle of 6 steps)
    assert fourier_decay_rate(h, t_end=2.4, every=(12, 2)) == pytest.approx(
        fourier_decay_rate(h, t_end=2.4, every=6), rel=1e-10)
    # k fixed, j sub-sweeps: order 2 in k h / j
    js = np.array([2, 4, 8])
    errors = np.array([abs(fourier_decay_rate(h, t_end=2.4, every=(48, int(j))) - exact) for j in js])
    slope = np.polyfit(np.log(js), np.log(errors), 1)[0]
    assert -2.2 < slope < -1.8, (errors, slope)


@pytest.mark.parametrize("sweeps", [2, 3])
def test_a_boundary_with_sub_sweeps_is_its_half_sweeps_one_after_the_other_bit_for_bit(sweeps):
    # the sweep kernel with j sub-sweeps (its colours fused across the 2j half sweeps: no baths)
    # against 2j calls of one half sweep each, alternately reverse and forward, the j-th a reverse
    # one (temperatures only: the entropy update deferred), the factors the same
    from thermonet.heat.logs import heat_logs
    from thermonet.heat.passes import DEFER_FINISH, FORWARD, REVERSE, heat_kernels

    net = tn.lattice((12, 3, 3), neighbours=6, jitter=0.2, seed=29)
    theta = np.random.default_rng(29).uniform(300.0, 1500.0, net.n_springs)
    sim = tn.Simulation(net, parameters=dict(c=100, beta=1.0, C0=1.0, theta0=300, g=0.4), temperatures=theta,
                        h=0.01, **QUIET)
    heat = sim.system.heat
    order = heat.star_order("cpu")  # (two colours of two blocks: fused and paired)
    assert order.n_colours == 2 and order.n_blocks == 4 and len(heat.entry_spring) == 0
    _, sweep = heat_kernels(sim.system.model, False, True)
    state = sim.internal_state()
    logs = heat_logs(state, heat)
    start = np.empty(net.n_springs)
    tau = 0.05
    at_once = sim.layout.springs_to_internal(theta).astype(float)
    sweep(heat.record(tau, logs, sweeps=sweeps), at_once, start, state.entropy.copy(), tau, 0.0,
          REVERSE | FORWARD | DEFER_FINISH)
    one_by_one = sim.layout.springs_to_internal(theta).astype(float)
    for half in range(2 * sweeps):
        sweep(heat.record(tau, logs, sweeps=1), one_by_one, start, state.entropy.copy(), tau, 0.0,
              (REVERSE if (sweeps - 1 - half) % 2 == 0 else FORWARD) | DEFER_FINISH)
    assert np.array_equal(at_once, one_by_one)
    assert not np.array_equal(at_once, sim.layout.springs_to_internal(theta))  # heat moved


def test_a_state_saved_before_sub_sweeps_continues_with_one_sweep():
    # heat logs whose cycle holds (k, origin) only, as checkpoints wrote them before sub-sweeps
    net, theta = hot_jittered_net(31)

    def make():
        return tn.Simulation(net, parameters=dict(c=100, beta=1.0, C0=1.0, theta0=300, g=0.4), temperatures=theta,
                             h=0.004, conduction_every=4, **QUIET)

    one = make()
    one.run(steps=40, diagnostics_every=4)
    old = make()
    old.runner.advance(6)  # inside a cycle of 4
    state = old.state
    assert list(state.extra["heat"]["cycle"]) == [4.0, 0.0, 1.0]
    state.extra["heat"]["cycle"] = state.extra["heat"]["cycle"][:2].copy()
    resumed = make()
    resumed.load_state(state)
    resumed.run(steps=34, diagnostics_every=34)
    assert resumed.conduction_cycle.k == 4 and resumed.conduction_cycle.sweeps == 1
    assert np.array_equal(one.state.entropy, resumed.state.entropy)
    assert np.array_equal(one.state.positions, resumed.state.positions)


def test_auto_picks_the_cycle_from_the_rate_the_step_and_the_cadences():
    from thermonet.heat.multirate import choose_cycle

    # λ h = 0.02: up to 15 steps within λ k h ≤ 0.3, so 10 of the series 1, 2, 5, 10, …
    assert choose_cycle("auto", 0.2, 0.1, [20, 40])[0] == 10
    # the largest divisor of 10 that divides the cadences and the run's length (8 steps: 2)
    k, sweeps, why = choose_cycle("auto", 0.2, 0.1, [8, 8])
    assert (k, sweeps) == (2, 1) and "divides the output cadences and the run's length, 8" in why
    # λ h = 2.5 > 0.3: every step, and the reason says that no k meets the tolerance
    k, sweeps, why = choose_cycle("auto", 25.0, 0.1, [10])
    assert (k, sweeps) == (1, 1) and "λ h = 2.5 > 0.3" in why and "≤" not in why
    # λ h = 0.08 (the thermal-shock scene), outputs every 10 steps: one sweep would allow k = 2
    # (λ k h = 0.16); 10 steps with 3 sub-sweeps (λ k h / 3 = 0.27, λ k h = 0.8 ≤ 1) cost about
    # (0.5 + 3 × 0.8) / 10 = 0.29 adiabatic steps per step against (0.5 + 0.8) / 2 = 0.65
    k, sweeps, why = choose_cycle("auto", 8.0, 0.01, [10, 50])
    assert (k, sweeps) == (10, 3) and "λ k h / 3 = 0.267 ≤ 0.3" in why and "0.29" in why and "0.65" in why
    # where sub-sweeps save less than 0.05 steps per step, none (λ h = 0.02, outputs every 20
    # steps: k = 10 costs 0.13, k = 20 with 2 sub-sweeps 0.105); every 100 steps: k = 50 with 4
    # (λ k h / 4 = 0.25) costs 0.074
    assert choose_cycle("auto", 0.2, 0.1, [20])[:2] == (10, 1)
    assert choose_cycle("auto", 0.2, 0.1, [100])[:2] == (50, 4)
    # an integer k takes j as given (default 1)
    assert choose_cycle(10, 8.0, 0.01, [10], sweeps=3)[:2] == (10, 3)
    assert choose_cycle(10, 8.0, 0.01, [10])[:2] == (10, 1)


def hot_jittered_net(seed: int = 3) -> tuple[tn.Net, np.ndarray]:
    net = tn.lattice((3, 3, 2), neighbours=18, jitter=0.2, seed=seed)
    rng = np.random.default_rng(seed)
    return net, rng.uniform(300.0, 1500.0, net.n_springs)


@pytest.mark.parametrize("every", [1, 10, (10, 3)])
def test_entropy_never_decreases_and_the_production_log_is_the_entropy_gained(every):
    net, theta = hot_jittered_net()
    sim = tn.Simulation(net, parameters=dict(c=200, beta=2.0, C0=1.0, theta0=300, g=0.5), temperatures=theta,
                        h=0.005, **cycle(every), **QUIET)
    d = sim.run(steps=10_000, diagnostics_every=steps_of(every))
    steps = np.diff(d.entropy)
    assert steps.min() > -1e-12 * np.abs(d.entropy).max(), steps.min()
    assert d.entropy[-1] - d.entropy[0] > 1.0  # it did mix
    assert np.max(np.abs(d.entropy_balance)) < 1e-11 * abs(d.entropy[-1] - d.entropy[0])
    # momenta of a free net stay exact
    assert np.abs(d.linear_momentum).max() < 1e-11 and np.abs(d.angular_momentum).max() < 1e-10


def energy_oscillation(h: float, steps: int, every: int = 1) -> tuple[float, float]:
    net, theta = hot_jittered_net(5)
    sim = tn.Simulation(net, parameters=dict(c=100, beta=1.0, C0=1.0, theta0=300, g=0.3), temperatures=theta,
                        velocities=np.random.default_rng(1).normal(0, 0.3, (net.n_nodes, 3)), h=h,
                        **cycle(every), **QUIET)
    k = steps_of(every)
    d = sim.run(steps=steps, diagnostics_every=max(k, steps // 2000 // k * k))
    e = d.energy
    tenth = len(e) // 10
    drift = abs(e[-tenth:].mean() - e[:tenth].mean())
    return float(np.max(np.abs(e - e[0]))), float(drift)


@pytest.mark.parametrize("every", [1, 5, (10, 2)])
def test_energy_bounded_without_drift_and_its_oscillation_is_order_2(every):
    osc, drift = energy_oscillation(0.004, 100_000, every)
    assert drift < 0.2 * osc
    osc_half, _ = energy_oscillation(0.002, 20_000, every)
    osc_full, _ = energy_oscillation(0.004, 10_000, every)
    assert 3.0 < osc_full / osc_half < 5.0, (osc_full, osc_half)


def steady_chain(h: float, n: int = 8, g: float = 2.0, hot: float = 600.0, cold: float = 300.0, every: int = 1):
    sim = tn.Simulation(chain_net(n), parameters=dict(c=100, beta=0.0, C0=1.0, theta0=300, g=g), temperatures=300.0,
                        h=h, baths={"hot": Bath("left", hot), "cold": Bath("right", cold)}, renumber=False,
                        **cycle(every), **QUIET)
    d = sim.run(t_end=200.0, diagnostics_every=round(1 / h))
    return sim, d


@pytest.mark.parametrize("every", [1, 4, (4, 2)])
def test_a_chain_between_two_baths_reaches_the_linear_profile_and_the_series_heat_flow(every):
    n, g, hot, cold = 8, 2.0, 600.0, 300.0
    e = np.arange(n)
    profile = hot - (hot - cold) * (2 * e + 1) / (2 * n)  # 2n half-springs of conductance g in series
    series = g / (2 * n) * (hot - cold)
    errors, flows = [], []
    k, j = every if isinstance(every, tuple) else (every, 1)
    for h in (0.05 * j / k, 0.025 * j / k):  # the conduction step k h / j: 0.05, then 0.025
        sim, d = steady_chain(h, every=every)
        errors.append(np.abs(sim.temperatures() - profile).max())
        rate = (d.heat_hot[-1] - d.heat_hot[-2]) / (d.time[-1] - d.time[-2])
        flows.append(abs(rate / series - 1))
        cold_rate = (d.heat_cold[-1] - d.heat_cold[-2]) / (d.time[-1] - d.time[-2])
        assert cold_rate == pytest.approx(-rate, rel=1e-9)  # steady: what enters leaves
        assert np.max(np.abs(d.energy_balance)) < 1e-10 * d.heat_hot[-1]
        # Clausius: S − S(0) = Σ Q/θ_b + production, production ≥ 0
        assert np.max(np.abs(d.entropy_balance)) < 1e-12 * (np.abs(d.entropy_in).max() + d.entropy_produced[-1])
        assert np.all(np.diff(d.entropy_produced) >= 0)
    # the splitting's steady state is the exact one up to O(h²)
    assert errors[1] < 2e-5 * hot and flows[1] < 5e-4
    assert 3.5 < errors[0] / errors[1] < 4.5 and 3.5 < flows[0] / flows[1] < 4.5, (errors, flows)


def bath_balance(h: float, every: int = 1) -> float:
    net, theta = hot_jittered_net(7)
    net.node_groups["hot"] = np.arange(4)
    sim = tn.Simulation(net, parameters=dict(c=100, beta=2.0, C0=1.0, theta0=300, g=0.4), temperatures=theta,
                        h=h, baths={"b": Bath("hot", {"start": 300.0, "end": 900.0, "duration": 1.0})},
                        sources={"s": Source(np.arange(5), {"amplitude": 20.0, "frequency": 1.0, "offset": 10.0})},
                        **cycle(every), **QUIET)
    d = sim.run(t_end=2.0, diagnostics_every=max(steps_of(every), round(0.01 / h)))
    return float(np.max(np.abs(d.energy_balance)))


@pytest.mark.parametrize("every", [1, 5, (5, 2)])
def test_with_baths_and_sources_the_energy_balance_is_order_2(every):
    coarse, fine = bath_balance(0.004, every), bath_balance(0.002, every)
    assert 3.0 < coarse / fine < 5.0, (coarse, fine)


def test_no_conductance_is_bit_identical_to_no_conduction():
    net, theta = hot_jittered_net(11)
    common = dict(temperatures=theta, h=0.004, velocities=np.full((net.n_nodes, 3), 0.1), **QUIET)
    a = tn.Simulation(net, parameters=dict(c=100, beta=1.0, C0=1.0, theta0=300), **common)
    b = tn.Simulation(net, parameters=dict(c=100, beta=1.0, C0=1.0, theta0=300, g=0.0), conduction=True, **common)
    a.run(steps=300, diagnostics_every=100)
    b.run(steps=300, diagnostics_every=100)
    assert a.integrator.name == "co2" and b.integrator.name == "co2+conduction"
    assert np.array_equal(a.state.positions, b.state.positions)
    assert np.array_equal(a.state.momenta, b.state.momenta)
    assert np.array_equal(a.state.entropy, b.state.entropy)


@pytest.mark.parametrize("every", [1, 4, (4, 3)])
def test_chunked_and_resumed_runs_are_bit_identical(tmp_path, every):
    # (thread counts: tests/test_loads_heat.py, whose one threaded kernel carries loads and heat)
    from thermonet.io.checkpoint import load_checkpoint, save_checkpoint

    net, theta = hot_jittered_net(13)
    net.node_groups["hot"] = np.arange(3)

    def make(**kw):
        return tn.Simulation(net, parameters=dict(c=100, beta=1.0, C0=1.0, theta0=300, g=0.4), temperatures=theta,
                             h=0.004, baths={"b": Bath("hot", 700.0)}, sources={"s": Source([0, 1], 5.0)},
                             **cycle(every), **QUIET, **kw)

    one = make()
    one.run(steps=400, diagnostics_every=400)
    chunked = make()
    for _ in range(4):
        chunked.run(steps=100, diagnostics_every=4)
    # calls that end inside a conduction cycle (as a run interrupted and checkpointed there)
    inside = make()
    for n in (3, 7, 1, 389):
        inside.runner.advance(n)
    first = make()
    first.runner.advance(150)
    save_checkpoint(tmp_path / "c.npz", first.state, {})
    state, _ = load_checkpoint(tmp_path / "c.npz")
    resumed = make()
    resumed.load_state(state)
    resumed.runner.advance(250)
    # a call that ends a cycle reduces its row's sums in the kernel, after the sweep changed η:
    # the same bits as the stand-alone reduction of the state it ends in
    from thermonet.diagnostics import measure

    direct = measure(one.system, one.internal_state(), one.parallel)
    for key in ("internal", "kinetic", "theta_min", "theta_max", "px", "Lz"):
        assert one.diagnostics.rows[-1][key] == direct[key], key
    for other in (chunked, inside, resumed):
        assert np.array_equal(one.state.positions, other.state.positions)
        assert np.array_equal(one.state.entropy, other.state.entropy)
        for k in ("produced", "entry_heat", "entry_flux"):
            assert np.array_equal(one.state.extra["heat"][k], other.state.extra["heat"][k]), k


def test_conduction_around_an_implicit_integrator_keeps_its_balances():
    net, theta = hot_jittered_net(17)
    sim = tn.Simulation(net, parameters=dict(c=100, beta=1.0, C0=1.0, theta0=300, g=0.4), temperatures=theta,
                        integrator="gtr-alpha", integrator_options={"alpha": 0.5}, h=0.004, **QUIET)
    d = sim.run(steps=200, diagnostics_every=20)
    assert np.all(np.diff(d.entropy) > -1e-12)
    assert np.max(np.abs(d.entropy_balance)) < 1e-11
    assert d.entropy[-1] > d.entropy[0]
    assert np.max(np.abs(d.energy - d.energy[0])) < 1e-3 * abs(d.energy[0])


@pytest.mark.parametrize("kwargs, message", [
    (dict(parameters=dict(g=-1.0)), "parameter 'g' of spring 0 must be finite and ≥ 0"),
    (dict(parameters=dict(g=np.nan)), "must be finite and ≥ 0"),
    (dict(parameters=dict(g=1.0), baths={"hot": Bath("nowhere", 500.0)}), "baths.hot.group: no node group"),
    (dict(parameters=dict(g=1.0), baths={"hot": Bath("left", -5.0)}), "baths.hot.temperature: a bath temperature must be > 0, got -5 at t = 0"),
    (dict(parameters=dict(g=1.0), baths={"hot": Bath("left", {"start": 300.0, "end": -300.0, "duration": 2.0})}),
     "baths.hot.temperature: a bath temperature must stay > 0, but 300 → -300 over t ∈ \\[0, 2\\] reaches 0 at t = 1"),
    (dict(parameters=dict(g=1.0), baths={"hot": Bath("empty", 500.0)}), "baths.hot.group: node group 'empty' holds no node"),
    (dict(parameters=dict(g=1.0), baths={"hot": Bath("left", {"table": [[0, 300], [0, 400]]})}),
     "baths.hot.temperature.table: times must increase strictly"),
    (dict(parameters=dict(g=1.0), thermal=False), "conduction needs thermal coupling on"),
    (dict(baths={"hot": Bath("left", 500.0)}), "baths need conduction on"),
    (dict(conduction=True), "no conductance 'g' is given"),
    (dict(parameters=dict(g=1.0), sources={"s": Source("nope", 1.0)}), "sources.s.group: no spring group"),
    (dict(parameters=dict(g=1.0), baths={"a": Bath("left", 500.0), "b": Bath([0], 400.0)}), "node 0 is already in bath 'a'"),
    (dict(parameters=dict(g=1.0), conduction_sweeps=2), 'conduction_sweeps: set it with a whole conduction_every'),
    (dict(parameters=dict(g=1.0), conduction_every=2, conduction_sweeps=0),
     "conduction_sweeps: expected a whole number of sub-sweeps ≥ 1, got 0"),
])
def test_bad_heat_input_names_the_key(kwargs, message):
    kwargs = dict(kwargs)
    params = dict(c=10, beta=0.1, C0=1.0, theta0=300)
    params.update(kwargs.pop("parameters", {}))
    with pytest.raises(InputError, match=message):
        tn.Simulation(chain_net(4), parameters=params, **kwargs)


def test_state_copies_do_not_share_the_heat_logs_and_orders_are_honest():
    from thermonet.explicit.splitting import BM4, CO4

    net, theta = hot_jittered_net(19)
    sim = tn.Simulation(net, parameters=dict(c=100, beta=1.0, C0=1.0, theta0=300, g=0.4), temperatures=theta,
                        h=0.004, **QUIET)
    sim.run(steps=10, diagnostics_every=10)
    state = sim.internal_state()
    copy = state.copy()
    assert copy.extra["heat"]["produced"] is not state.extra["heat"]["produced"]
    assert np.array_equal(copy.extra["heat"]["produced"], state.extra["heat"]["produced"])
    # conduction caps the order at 2; thermal waves keep it only in a composition
    assert CO4.with_heat(True, False).order == 2 and CO4.with_heat(False, True).order == 4
    assert BM4.with_heat(False, True).order == 2


@pytest.mark.parametrize("every", [1, (5, 2)])
def test_conduction_around_em2_keeps_energy_exact_and_entropy_rising(every):
    net, theta = hot_jittered_net(23)
    sim = tn.Simulation(net, parameters=dict(c=100, beta=1.0, C0=1.0, theta0=300, g=0.4), temperatures=theta,
                        velocities=np.random.default_rng(4).normal(0, 0.3, (net.n_nodes, 3)), integrator="em2",
                        integrator_options={"tolerance": 1e-15, "rtol": 1e-12}, h=0.01, **cycle(every), **QUIET)
    d = sim.run(steps=60, diagnostics_every=5)
    assert np.max(np.abs(d.energy - d.energy[0])) < 1e-11 * abs(d.energy[0])
    assert np.all(np.diff(d.entropy) > -1e-12 * np.abs(d.entropy).max()) and d.entropy[-1] > d.entropy[0]
    assert np.max(np.abs(d.entropy_balance)) < 1e-10


@pytest.mark.parametrize("failing", [0, 1])
def test_a_step_that_fails_around_an_implicit_integrator_gives_back_entropy_and_logs(failing, monkeypatch):
    """Conduction every 2 steps around EM2: the first step of a cycle opens it with a forward
    half sweep before the inner step, the second closes it after. A step whose inner integrator
    fails (the opening one, whose sweep already ran, or the closing one) leaves the state as the
    step found it (η and every heat log, bit for bit), and the failure counts the steps done."""
    from thermonet.heat.stepper import ConductionAround
    from thermonet.integrators.base import StepFailure

    net, theta = hot_jittered_net(23)
    sim = tn.Simulation(net, parameters=dict(c=100, beta=1.0, C0=1.0, theta0=300, g=0.4), temperatures=theta,
                        integrator="em2", h=0.01, **cycle(2), **QUIET)
    sim.run(steps=2, diagnostics_every=2)
    around = sim.stepper
    while not isinstance(around, ConductionAround):
        around = around.inner
    state = sim.internal_state()
    inner_advance = around.inner.advance
    calls = []

    def advance(s, n, h, measure=False):
        calls.append(n)
        if len(calls) == failing + 1:
            raise StepFailure("made to fail")
        return inner_advance(s, n, h)

    monkeypatch.setattr(around.inner, "advance", advance)
    if failing:  # (the opening step, done, is what the failing closing step starts from)
        around.advance(state, 1, sim.h)
        state.step, state.time = state.step + 1, state.time + sim.h
    before = state.copy()
    with pytest.raises(StepFailure) as failed:
        around.advance(state, 1, sim.h)
    assert failed.value.steps_done == 0
    assert np.array_equal(state.entropy, before.entropy)
    for key, value in before.extra["heat"].items():
        assert np.array_equal(state.extra["heat"][key], value), key
