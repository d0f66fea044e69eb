"""Loads in the explicit CPU kernel: forces, driven groups, reactions, work and the balance
H − H(0) − W (docs/theory.md §7; docs/loads.md)."""

import numpy as np
import pytest

import thermonet as tn
from thermonet.errors import InputError
from thermonet.loads import Drive, Force, TimeFunction


def bar(n=4, mass=1.0, anchor=True):
    """n springs of rest length 1 along x; node 0 anchored (optionally), groups "grip" (node n),
    "all"."""
    x = np.zeros((n + 1, 3))
    x[:, 0] = np.arange(n + 1)
    edges = np.column_stack([np.arange(n), np.arange(1, n + 1)])
    anchored = np.zeros(n + 1, dtype=bool)
    anchored[0] = anchor
    return tn.Net(x, edges, np.full(n + 1, mass), anchored, rest_lengths=np.ones(n),
                  node_groups={"grip": [n], "base": [0], "all": np.arange(n + 1)})


def test_a_constant_total_force_on_a_free_net_gives_it_momentum_f_t_to_round_off():
    net = tn.lattice((1, 1, 1), neighbours=18, jitter=0.1, seed=2)
    net.node_groups["all"] = np.arange(net.n_nodes)
    net.anchored[:] = False
    rng = np.random.default_rng(3)
    F = np.array([0.7, -0.3, 1.1])
    sim = tn.Simulation(net, h=2e-3, temperatures=300 + 50 * rng.random(net.n_springs),
                        loads={"push": Force("all", F, total=True)})
    sim.run(steps=500, diagnostics_every=50)
    d = sim.diagnostics
    np.testing.assert_allclose(d.linear_momentum, d.time[:, None] * F[None, :], rtol=0, atol=1e-12)
    # the work of a constant force is f · (displacement of the group's mass-weighted centre); the
    # balance is then the splitting's own energy error (the springs are not in equilibrium)
    assert d.work[-1] == pytest.approx(0.5 * F @ F / net.masses.sum() * d.time[-1] ** 2, rel=1e-9)
    assert np.max(np.abs(d.energy_balance)) < 1e-6 * abs(d.energy[0])
    np.testing.assert_allclose(d.push_Fx, F[0])


def sine_pulled(h, steps, integrator="co2"):
    sim = tn.Simulation(bar(3), h=h, integrator=integrator, temperatures=[300, 320, 310],
                        loads={"shake": Drive("grip", {"x": {"amplitude": 0.05, "frequency": 0.4},
                                                       "y": TimeFunction.linear(0.02)})})
    sim.run(steps=steps, diagnostics_every=max(1, steps // 200))
    return sim.diagnostics


def test_the_balance_with_a_driven_group_stays_bounded_without_drift_over_1e5_steps():
    d = sine_pulled(5e-3, 100_000)
    b = np.abs(d.energy_balance)
    assert np.max(np.abs(d.work)) > 1.0  # the drive does real work back and forth
    k = len(b) // 10
    assert b.max() < 1e-3 * np.max(np.abs(d.energy))
    assert b[-k:].max() < 2.0 * b[:2 * k].max() + 1e-12  # no drift: the last tenth stays where the start was


@pytest.mark.parametrize("integrator, order", [("co2", 2), ("co4", 4)])
def test_the_balance_converges_at_the_integrators_order(integrator, order):
    errs = []
    hs = [0.02, 0.01, 0.005]
    for h in hs:
        d = sine_pulled(h, int(round(2.0 / h)), integrator)
        errs.append(np.max(np.abs(d.energy_balance)))
    slopes = np.diff(np.log(errs)) / np.diff(np.log(hs))
    assert np.all(np.abs(slopes - order) < 0.3), (errs, slopes)


def test_a_slowly_pulled_bar_follows_the_static_tension_and_cools_adiabatically():
    """Two springs in series, the middle node free and light, pulled by a slow smooth ramp (half a
    cosine wave, so that its start excites no oscillation worth the name): the reaction
    equals the static tension T(l, θ(l, η)) at the current mean length (quasi-static), and the
    temperatures follow the closed form θ(l, η) = θ0 exp((η − β ln(l/l0))/C0): cooling."""
    net = bar(2, mass=1e-2)
    P = dict(c=100.0, beta=0.5, C0=5.0, theta0=300.0)
    ramp = TimeFunction.sine(amplitude=0.1, frequency=1 / 80, phase=-np.pi / 2, offset=0.1)  # 0 → 0.2 over 40
    sim = tn.Simulation(net, parameters=P, h=1e-3, loads={"pull": Drive("grip", {"x": ramp})})
    eta = sim.state.entropy.copy()
    sim.run(steps=40_000, diagnostics_every=1000)
    d = sim.diagnostics
    l = 1.0 + d.pull_ux / 2.0  # the mean spring length
    L = np.log(l)
    theta = P["theta0"] * np.exp((eta[0] - P["beta"] * L) / P["C0"])
    tension = (P["c"] * L - P["beta"] * (theta - P["theta0"])) / l
    moving = d.time > 0.5
    np.testing.assert_allclose(-d.pull_Rx[moving], tension[moving], rtol=1e-3)
    np.testing.assert_allclose(sim.temperatures(), theta[-1], rtol=1e-4)
    assert np.all(np.diff(d.theta_max) < 0)  # the Kelvin effect: cooling as it stretches (β > 0)
    assert sim.temperatures().max() < P["theta0"] - 2.5
    assert np.max(np.abs(d.energy_balance)) < 1e-4 * np.max(np.abs(d.work))


def linear_tip(A, Omega, k, m, n, t):
    """Longitudinal displacement of the free end of n equal springs (stiffness k, masses m, the
    last node free) whose first node moves as A sin(Ω t), from rest: the linear chain's modes."""
    K = 2.0 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)
    K[-1, -1] = 1.0
    w2, V = np.linalg.eigh(k / m * K)
    g = V.T @ np.eye(n)[0] * (k / m) * A  # the support's pull on node 1, in modal coordinates
    w = np.sqrt(w2)
    q = np.empty((len(w), len(t)))
    for j in range(len(w)):
        if abs(w[j] - Omega) < 1e-9 * w[j]:
            q[j] = g[j] / (2 * w[j]) * (np.sin(w[j] * t) / w[j] - t * np.cos(w[j] * t))
        else:
            q[j] = g[j] / (w2[j] - Omega ** 2) * (np.sin(Omega * t) - Omega / w[j] * np.sin(w[j] * t))
    return (V @ q)[-1], w


@pytest.mark.parametrize("resonant", [True, False])
def test_a_sine_driven_support_excites_the_chain_as_its_transfer_function_says(resonant):
    n, c, A = 3, 100.0, 1e-6  # small: the linear regime (strains stay below 1e-4 at resonance)
    net = bar(n, anchor=False)
    _, w = linear_tip(A, 1.0, c, 1.0, n, np.zeros(1))
    Omega = w[0] if resonant else 0.6 * w[0]
    h = 4e-3
    steps = int(20 * 2 * np.pi / w[0] / h)
    sim = tn.Simulation(net, parameters=dict(c=c), thermal=False, h=h,
                        loads={"support": Drive("base", {"x": {"amplitude": A, "frequency": Omega / (2 * np.pi)}},
                                                free=False)})
    tip = []
    sim.run(steps=steps, diagnostics_every=steps, observers=[(20, lambda s: tip.append(s.state.positions[-1, 0] - n))])
    t = np.arange(len(tip)) * 20 * h
    expected, _ = linear_tip(A, Omega, c, 1.0, n, t)
    tip = np.array(tip)
    scale = np.max(np.abs(expected))
    assert np.max(np.abs(tip - expected)) < 0.03 * scale
    quarter = len(t) // 4
    growth = np.max(np.abs(tip[-quarter:])) / np.max(np.abs(tip[:quarter]))
    if resonant:
        assert growth > 3.0
    else:
        assert growth < 1.5


def loaded():
    net = bar(5)
    net.node_groups["mid"] = [2, 3]
    loads = {"pull": Drive("grip", {"x": {"table": [[0, 0], [0.1, 0.02], [0.5, 0.05]]}}, free=True),
             "push": Force("mid", {"y": {"amplitude": 0.3, "frequency": 2.0}, "z": 0.1})}
    return tn.Simulation(net, h=1e-3, temperatures=np.linspace(280, 330, 5), gravity=[0, 0, -1.0], loads=loads)


def same(a, b):
    for f in ("positions", "momenta", "thermal_displacement", "entropy"):
        np.testing.assert_array_equal(getattr(a.state, f), getattr(b.state, f))
    np.testing.assert_array_equal(a.state.extra["load_work"], b.state.extra["load_work"])


def test_runs_with_loads_do_not_depend_on_chunks_or_a_checkpoint():
    # (thread counts: tests/test_loads_heat.py, whose one threaded kernel carries loads and heat)
    whole = loaded()
    whole.run(steps=300, diagnostics_every=300)
    cut = loaded()
    for k in (1, 7, 100, 192):
        cut.run(steps=k, diagnostics_every=max(1, k // 3))
    same(whole, cut)
    resumed = loaded()
    first = loaded()
    first.run(steps=120, diagnostics_every=40)
    resumed.load_state(first.state)
    resumed.run(steps=180, diagnostics_every=60)
    same(whole, resumed)


def test_held_axes_stay_put_and_free_axes_move():
    for free in (False, True):
        sim = tn.Simulation(bar(2), thermal=False, h=1e-3, gravity=[0, -1.0, 0],
                            loads={"pull": Drive("grip", {"x": TimeFunction.linear(0.1)}, free=free)})
        sim.run(steps=500, diagnostics_every=100)
        grip = sim.state.positions[-1]
        assert grip[0] == pytest.approx(2.05, abs=1e-12)
        if free:
            assert grip[1] < -1e-3  # it falls under gravity, held only in x
        else:
            assert grip[1] == 0.0 and grip[2] == 0.0
        assert np.max(np.abs(sim.diagnostics.energy_balance)) < 1e-6


@pytest.mark.parametrize("loads, message", [
    ({"pull": Drive("base", velocity=[1, 0, 0])}, r"loads\.pull\.group: node 0 is anchored"),
    ({"pull": Drive("grip", {"x": {"table": [[0, 0], [1, 1], [0.5, 2]]}})}, r"loads\.pull\.displacement\.x\.table: times must increase"),
    ({"pull": Drive("grip", {"x": {"table": [[0, 0], [1, float("nan")]]}})}, r"loads\.pull\.displacement\.x: a non-finite number in the time function table of 2 points"),
    ({"push": Force("nowhere", [1, 0, 0])}, r"loads\.push\.group: no node group 'nowhere'"),
    ({"pull": Drive([], velocity=[1, 0, 0])}, r"loads\.pull\.group: the group has no nodes"),
    ({"a": Drive("grip", velocity=[1, 0, 0]), "b": Drive([4], velocity=[0, 1, 0])}, r"loads\.b\.group: node 4 is also in loads\.a"),
    ({"pull": Drive("grip")}, r"loads\.pull: give exactly one of displacement or velocity"),
    ({"push": Force("grip", {"w": 1})}, r"loads\.push\.force: expected one time function per axis"),
])
def test_bad_loads_are_input_errors_naming_the_key(loads, message):
    with pytest.raises(InputError, match=message):
        tn.Simulation(bar(4), h=1e-3, loads=loads)


@pytest.mark.parametrize("integrator", ["gtr-1/2", "ho4"])
def test_loads_split_around_an_implicit_step_keep_the_balance_at_second_order(integrator):
    """Implicit integrators take loads by Strang splitting around their step (thermonet.loads.implicit):
    the balance H − H(0) − W converges at order 2 (the splitting's, whatever the scheme's), and a
    run cut into chunks gives the same bits."""
    errs, hs = [], [0.02, 0.01, 0.005]
    for h in hs:
        sim = tn.Simulation(bar(3), h=h, integrator=integrator, temperatures=[300, 320, 310],
                            loads={"shake": Drive("grip", {"x": {"amplitude": 0.05, "frequency": 0.4},
                                                           "y": TimeFunction.linear(0.02)}),
                                   "push": Force([2], {"z": {"amplitude": 0.3, "frequency": 0.7}})})
        steps = int(round(2.0 / h))
        sim.run(steps=steps, diagnostics_every=steps // 40)
        errs.append(np.max(np.abs(sim.diagnostics.energy_balance)))
        assert np.max(np.abs(sim.diagnostics.work)) > 0.1
    slopes = np.diff(np.log(errs)) / np.diff(np.log(hs))
    assert np.all(np.abs(slopes - 2.0) < 0.2), (errs, slopes)
    cut = tn.Simulation(bar(3), h=hs[-1], integrator=integrator, temperatures=[300, 320, 310],
                        loads={"shake": Drive("grip", {"x": {"amplitude": 0.05, "frequency": 0.4},
                                                       "y": TimeFunction.linear(0.02)}),
                               "push": Force([2], {"z": {"amplitude": 0.3, "frequency": 0.7}})})
    for n in (7, 93, 300):
        cut.run(steps=n, diagnostics_every=n)
    same(sim, cut)


def test_an_implicit_integrator_refuses_a_drive_free_in_some_axes():
    with pytest.raises(InputError, match=r"loads\.pull\.free: integrator 'ho4' is implicit"):
        tn.Simulation(bar(2), h=1e-3, integrator="ho4", loads={"pull": Drive("grip", velocity=[1, 0, 0], free=True)})


def test_a_blown_up_loaded_run_is_rewound_with_its_work_to_the_last_good_step():
    def make():
        return tn.Simulation(bar(2), h=1e-3, stretch_bounds=(0.5, 1.5), energy_tolerance=None,
                             stability_guard="off", loads={"pull": Drive("grip", velocity=[1.0, 0, 0])})

    bad = make()
    with pytest.raises(tn.SimulationError, match="left the admissible states"):
        bad.run(steps=3000, diagnostics_every=100)
    good = make()
    good.run(steps=bad.step, diagnostics_every=100)
    assert 500 < bad.step < 3000
    same(bad, good)


def test_the_kernel_with_loads_follows_a_plain_numpy_co2_with_loads():
    """The CO2 step with a drive and a force written out in NumPy (thermonet.reference's forces;
    the drive's nodes set after the drift, kicks at the stage times, work by the kicks'
    quadrature) against the compiled kernel, 60 steps."""
    from dataclasses import replace

    from thermonet import reference as ref

    net = bar(3)
    temps = np.array([300.0, 330.0, 290.0])
    drive_x = TimeFunction.sine(0.05, 0.7, phase=0.3)
    drive_y = TimeFunction.linear(0.02)
    force = [TimeFunction.table([[0, 0.0], [0.03, 0.4], [1, 0.1]]), None, TimeFunction.constant(-0.2)]
    h, steps = 2e-3, 60
    sim = tn.Simulation(net, h=h, temperatures=temps,
                        loads={"pull": Drive("grip", {"x": drive_x, "y": drive_y}), "push": Force([2], force)})
    sim.run(steps=steps, diagnostics_every=steps)

    rnet = ref.ReferenceNet.build(net, "hencky")
    driven = np.zeros(4, dtype=bool)
    driven[3] = True
    fixed = replace(rnet, anchored=rnet.anchored | driven)   # the drive's node is not free
    springs_only = replace(rnet, anchored=np.zeros(4, dtype=bool))
    x, p = net.positions.copy(), np.zeros((4, 3))
    eta = rnet.entropies(x, temps)
    phi = np.zeros(3)
    X3 = net.positions[3] - np.array([drive_x(0.0), drive_y(0.0), 0.0])
    work = np.zeros(2)

    def kick(x, t, tau):
        f, theta = fixed.forces_and_temperatures(x, eta)
        fv = np.array([0.0 if c is None else c(t) for c in force])
        fr = np.array([0.0 if c is None else c.rate(t) for c in force])
        f[2] += fv
        reaction = springs_only.forces(x, eta)[3]
        work[0] += tau * -(reaction @ np.array([drive_x.rate(t), drive_y.rate(t), 0.0]))
        work[1] += tau * -(fr @ x[2])
        return f, theta

    for n in range(steps):
        t0, t1 = n * h, (n + 1) * h
        f0, th0 = kick(x, t0, 0.5 * h)
        p = p + 0.5 * h * f0
        phi = phi + 0.5 * h * th0
        v = p / net.masses[:, None]
        v[fixed.anchored] = 0.0
        x = x + h * v
        x[3] = X3 + np.array([drive_x(t1), drive_y(t1), 0.0])
        f1, th1 = kick(x, t1, 0.5 * h)
        p = p + 0.5 * h * f1
        phi = phi + 0.5 * h * th1
    s = sim.state
    np.testing.assert_allclose(s.positions, x, rtol=0, atol=1e-13)
    np.testing.assert_allclose(s.momenta, p, rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.thermal_displacement, phi, rtol=1e-13)
    np.testing.assert_allclose(s.extra["load_work"], work, rtol=1e-11, atol=1e-15)
