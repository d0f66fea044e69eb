"""HO4's predictor extrapolates from the previous step (implicit/core/start.py): the series
a + (h/2) ȧ + (h²/8) ä for the stage acceleration gains its next term from the last committed
step's stage acceleration, read from the unknowns that step converged to. Only after a committed
step of the same h; it changes the Newton guess, not the solution."""

import numpy as np
import pytest

import thermonet as tn
from test_implicit_newton import hot_lattice_ho4 as hot_lattice
from thermonet.implicit.ho4.stepper import HO4Stepper


def predicted(sim, extrapolate: bool, h=None):
    """(the predicted unknowns, their scaled residual) from the current state, with or without
    the history the last committed step left (restored afterwards: the marker, and the
    unknowns that step converged to, which the prediction overwrites)."""
    st, s = sim.stepper, sim.internal_state()
    marker = st.work.start.history[0]
    converged = st.u.copy()
    if not extrapolate:
        st.work.start.history[0] = 0.0
    st.begin(s.positions, s.momenta, s.entropy, sim.h if h is None else h)
    assert st.work.start.history[0] == 0.0  # the start kernel consumed it
    u = st.u.copy()
    assert st.residual(st.u) == (0, -1)
    rho = st.norms[0] / st.norms[1]
    st.u[:] = converged
    st.work.start.history[0] = marker
    return u, rho


def test_the_extrapolation_makes_the_guess_better_and_the_steps_cheaper():
    """Over 12 steps of the hot lattice the extrapolated guess's scaled residual is below the
    series' (median ratio ≥ 2), so fewer steps need a finishing Jacobi step; the steps end where
    the series predictor's steps end, to the Newton tolerance's size."""
    sim = hot_lattice()
    ratios = []
    for _ in range(12):
        u_series, rho_series = predicted(sim, extrapolate=False)
        u_extrap, rho_extrap = predicted(sim, extrapolate=True)
        assert not np.array_equal(u_series, u_extrap)
        ratios.append(rho_series / rho_extrap)
        sim.run(steps=1, diagnostics_every=10**9)
    assert np.median(ratios) >= 2.0, ratios

    runs = {}
    for extrapolate in (True, False):
        run = hot_lattice()
        if not extrapolate:
            coefficients = run.stepper.predictor_coefficients
            run.stepper.predictor_coefficients = lambda h: coefficients(h) * np.array([1, 1, 1, 1, 0, 1])
        run.stepper.timers.__init__()
        run.run(steps=20, diagnostics_every=10**9)
        assert run.stepper.summary()["residual_max"] <= 1e-12
        runs[extrapolate] = run
    t, series = runs[True].stepper.timers, runs[False].stepper.timers
    assert t.linear_solves == series.linear_solves == 20  # one full iteration per step in both
    assert t.jacobi_steps < series.jacobi_steps  # fewer finishing (local Jacobi) steps
    scale = np.abs(runs[False].state.momenta).max()
    assert np.abs(runs[True].state.momenta - runs[False].state.momenta).max() <= 1e-11 * scale
    assert np.abs(runs[True].state.positions - runs[False].state.positions).max() <= 1e-11


def test_the_history_is_used_only_after_a_committed_step_of_the_same_h():
    """A committed step leaves its h as the marker; a step of another h, or one after the
    marker was consumed (begin without a commit: a retried or abandoned attempt), predicts by
    the series alone, bit for bit."""
    sim = hot_lattice(steps=3)
    st = sim.stepper
    assert st.work.start.history[0] == sim.h
    series, _ = predicted(sim, extrapolate=False, h=0.5 * sim.h)
    other_h, _ = predicted(sim, extrapolate=True, h=0.5 * sim.h)
    np.testing.assert_array_equal(series, other_h)

    s = sim.internal_state()
    st.begin(s.positions, s.momenta, s.entropy, sim.h)  # consumes the marker, commits nothing
    first = st.u.copy()
    st.begin(s.positions, s.momenta, s.entropy, sim.h)
    again = st.u.copy()
    st.work.start.history[0] = 0.0
    st.begin(s.positions, s.momenta, s.entropy, sim.h)
    assert not np.array_equal(first, again)
    np.testing.assert_array_equal(again, st.u)


@pytest.mark.parametrize("path", ["compiled", "sparse"])
def test_a_new_step_size_starts_from_the_series(path):
    """Changing h between runs: the first step of the new h does not extrapolate from the old
    h's stage (the marker differs), and the run stays converged."""
    net = tn.lattice((4, 4, 4), jitter=0.1, seed=2)
    rng = np.random.default_rng(1)
    sim = tn.Simulation(net, model="hencky", parameters=dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0),
                        temperatures=rng.uniform(300.0, 600.0, net.n_springs),
                        momenta=rng.normal(0.0, 1.0, (net.n_nodes, 3)), integrator="ho4", h=0.01,
                        integrator_options=dict(newton_path=path))
    sim.run(steps=3, diagnostics_every=10**9)
    assert sim.stepper.work.start.history[0] == 0.01
    sim.h = 0.005
    series, _ = predicted(sim, extrapolate=False)
    extrap, _ = predicted(sim, extrapolate=True)
    np.testing.assert_array_equal(series, extrap)
    sim.run(steps=3, diagnostics_every=10**9)
    assert sim.stepper.work.start.history[0] == 0.005
    assert sim.stepper.summary()["residual_max"] <= 1e-12
    assert isinstance(sim.stepper, HO4Stepper)


@pytest.mark.parametrize("path", ["compiled", "sparse"])
def test_a_run_continued_from_its_state_is_bit_for_bit_the_uninterrupted_one(path):
    """The history travels with the state (``state.extra``, so in checkpoints): a new simulation
    loading the state after 10 steps predicts its next step as the uninterrupted run does, and
    ends where it ends, bit for bit."""
    def make():
        net = tn.lattice((4, 4, 4), jitter=0.1, seed=2)
        rng = np.random.default_rng(1)
        return tn.Simulation(net, model="hencky", parameters=dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0),
                             temperatures=rng.uniform(300.0, 600.0, net.n_springs),
                             momenta=rng.normal(0.0, 1.0, (net.n_nodes, 3)), integrator="ho4", h=0.01,
                             integrator_options=dict(newton_path=path))

    whole = make()
    whole.run(steps=20, diagnostics_every=10**9)
    first = make()
    first.run(steps=10, diagnostics_every=10**9)
    assert first.state.extra["predictor_history"][-1] == 0.01
    second = make()
    second.load_state(first.state)
    second.run(steps=10, diagnostics_every=10**9)
    np.testing.assert_array_equal(whole.state.positions, second.state.positions)
    np.testing.assert_array_equal(whole.state.momenta, second.state.momenta)
