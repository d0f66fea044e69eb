"""The Newton machinery of the implicit integrators: exact Jacobian, quadratic convergence,
loud and safe failure, retry, options, and availability by name (API and CLI)."""

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

import thermonet as tn
from thermonet.implicit.core.newton import NewtonOptions, NewtonTimers, newton
from thermonet.paper import CHAIN_MOMENTA, CHAIN_TEMPERATURES


def random_simulation(integrator, h, seed=3, **options):
    """A jittered 3×2×2 lattice with face diagonals, one anchored node, random masses, rest
    lengths (pre-stress), temperatures and momenta, and a strong thermal coupling so the
    Jacobian's thermal terms are large."""
    rng = np.random.default_rng(seed)
    base = tn.lattice((3, 2, 2), neighbours=18, jitter=0.2, seed=seed)
    anchored = np.zeros(base.n_nodes, dtype=bool)
    anchored[5] = True
    net = tn.Net(base.positions, base.edges, rng.uniform(0.5, 2.0, base.n_nodes), anchored,
                 rest_lengths=base.lengths() * rng.uniform(0.8, 1.2, base.n_springs))
    momenta = rng.normal(0.0, 3.0, (net.n_nodes, 3))
    momenta[anchored] = 0.0
    return tn.Simulation(net, model="hencky", parameters=dict(c=rng.uniform(50, 150, net.n_springs), beta=2.0, C0=1.0,
                                                              theta0=300.0),
                         temperatures=rng.uniform(200.0, 900.0, net.n_springs), momenta=momenta,
                         integrator=integrator, h=h, integrator_options=options,
                         stability_guard="off", energy_tolerance=None)  # solver tests, some beyond the limit


def residual_at(stepper, u):
    status, spring = stepper.residual(u)
    assert status == 0
    return stepper.R.copy()


@pytest.mark.parametrize("integrator, options", [("gtr-1/2", {}), ("gtr-alpha", {"alpha": 0.3}), ("ho4", {})])
def test_jacobian_matches_finite_differences(integrator, options):
    sim = random_simulation(integrator, h=0.05, **options)
    st, s = sim.stepper, sim._state
    st.begin(s.positions, s.momenta, s.entropy, sim.h)
    st.predict(st.u)
    rng = np.random.default_rng(0)
    u = st.u + rng.normal(0.0, 0.02, st.u.shape)  # away from the solution
    residual_at(st, u)
    st.jacobian(st.data)
    J = st.pattern.matrix(st.data.copy()).toarray()
    eps = 1e-6
    J_fd = np.empty_like(J)
    for j in range(len(u)):
        up, um = u.copy(), u.copy()
        up[j] += eps
        um[j] -= eps
        J_fd[:, j] = (residual_at(st, up) - residual_at(st, um)) / (2 * eps)
    # the blocks coupling different nodes (springs' thermal and elastic terms) must be sizeable
    coupling = J.copy()
    for k in range(st.pattern.n_free):
        b = st.pattern.block
        coupling[b * k:b * (k + 1), b * k:b * (k + 1)] = 0.0
    assert np.abs(coupling).max() > 1e-2 * np.abs(J).max()
    assert np.abs(J - J_fd).max() <= 1e-6 * np.abs(J).max()


@pytest.mark.parametrize("integrator", ["gtr-1/2", "ho4"])
def test_newton_converges_quadratically(integrator):
    """From the crude guess x¹ = x⁰ (so several iterates lie above round-off), the scaled
    residuals fall as ρ_{k+1} ≤ ρ_k² until they reach the round-off floor."""
    sim = tn.chain_simulation(integrator, h=0.05)
    sim.run(steps=3, diagnostics_every=10**9)
    st, s = sim.stepper, sim._state
    st.begin(s.positions, s.momenta, s.entropy, sim.h)
    st.u[:] = 0.0
    result = newton(st, st.u, NewtonOptions(tolerance=1e-15), st.solver, NewtonTimers())
    assert result.converged
    rho = np.array(result.history)
    above = [(a, b) for a, b in zip(rho[:-1], rho[1:]) if b > 1e-14]
    assert len(above) >= 2, rho
    for a, b in above:
        assert b <= a**2, rho
    assert rho[-1] < 1e-15
    # one compiled residual serves the compiled driver (sim.run) and this Python iteration: a
    # literal argument from the driver would have compiled it a second time
    assert len(st.kernels.residual.signatures) == 1, st.kernels.residual.signatures


def test_absurd_step_fails_loudly_and_keeps_the_state():
    """Quadratic model (whose temperature can reach zero) on the chain with h = 10."""
    sim = tn.Simulation(tn.chain(), model="quadratic", parameters=dict(E=100, beta=0.2, C0=5, theta0=300),
                        temperatures=CHAIN_TEMPERATURES, momenta=CHAIN_MOMENTA, integrator="gtr-1/2", h=10.0)
    before = sim.state
    with pytest.raises(tn.SimulationError) as info:
        sim.run(steps=3)
    err = info.value
    assert isinstance(err, tn.integrators.StepFailure)
    assert err.steps_done == 0
    msg = str(err)
    assert "step 0 -> 1" in msg and "t = 0 -> 10" in msg and "temperature" in msg
    assert err.details["worst_spring"] == 2 and "worst spring 2" in msg
    assert err.details["worst_node"] in (2, 3)
    after = sim.state
    assert sim.step == 0 and sim.time == 0.0
    for name in ("positions", "momenta", "thermal_displacement", "entropy"):
        assert np.array_equal(getattr(after, name), getattr(before, name)), name


def test_failure_at_a_later_step_keeps_the_last_good_state():
    def make():
        return tn.Simulation(tn.chain(), model="quadratic", parameters=dict(E=100, beta=0.2, C0=5, theta0=300),
                             temperatures=CHAIN_TEMPERATURES, momenta=CHAIN_MOMENTA, integrator="gtr-1/2", h=1.0,
                             stability_guard="off", energy_tolerance=None)  # far beyond the limit on purpose

    sim = make()
    with pytest.raises(tn.SimulationError) as info:
        sim.run(steps=5, diagnostics_every=10**9)  # one chunk of 5 steps
    assert info.value.steps_done == 1 and sim.step == 1 and sim.time == 1.0
    assert "step 1 -> 2" in str(info.value)
    good = make()
    good.run(steps=1)
    assert np.array_equal(sim.state.positions, good.state.positions)
    assert np.array_equal(sim.state.momenta, good.state.momenta)
    assert sim.diagnostics.rows[-1]["step"] == 1


def test_non_convergence_names_the_residual_history_then_retry_recovers():
    """HO4 at h = 0.3 on the chain needs more than 2 Newton iterations per step."""
    sim = tn.chain_simulation("ho4", h=0.3, integrator_options=dict(max_iterations=2))
    with pytest.raises(tn.SimulationError) as info:
        sim.run(steps=2)
    err = info.value
    history = err.details["residual_history"]
    assert len(history) == 3 and history[-1] > 1e-12
    assert "no convergence in 2 iterations" in str(err) and "scaled residual history" in str(err)
    assert err.details["worst_node"] in (1, 2, 3)  # free nodes of the chain, user numbering
    assert sim.step == 0

    sim = tn.chain_simulation("ho4", h=0.3, integrator_options=dict(max_iterations=2, retry=3))
    with pytest.warns(RuntimeWarning, match="substeps"):
        diag = sim.run(steps=1, diagnostics_every=1)
    substeps = int(diag.substeps_max[-1])
    assert diag.retried_steps[-1] == 1 and substeps >= 2
    assert sim.stepper.summary()["retried_steps"] == 1 and sim.step == 1
    # the substeps are steps of the same method: the same as a run at the substep size
    fine = tn.chain_simulation("ho4", h=0.3 / substeps)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fine.run(steps=substeps)
    assert np.abs(fine.state.positions - sim.state.positions).max() < 1e-10


def test_options_are_checked():
    with pytest.raises(tn.InputError):
        tn.chain_simulation("ho4", h=0.01, integrator_options=dict(tolerance=-1.0))
    with pytest.raises(tn.InputError):
        tn.chain_simulation("ho4", h=0.01, integrator_options=dict(linear_solver="cholesky"))
    with pytest.raises(tn.InputError):
        tn.get_integrator("gtr-alpha", alpha=1.5)
    assert tn.get_integrator("gtr-half") is tn.get_integrator("gtr-1/2")
    assert not tn.get_integrator("ho4").explicit and tn.get_integrator("ho4").order == 4


@pytest.mark.parametrize("integrator", ["gtr-1/2", "ho4"])
def test_iterative_solvers_and_splu_agree(integrator):
    runs = {}
    for solver in ("splu", "gmres", "matfree"):
        sim = random_simulation(integrator, h=0.01, seed=5, linear_solver=solver)
        sim.run(steps=10, diagnostics_every=10**9)
        runs[solver] = sim.state
        assert sim.stepper.summary()["linear_solver"] == solver
        assert sim.stepper.summary()["iterations_max"] <= 3
    scale = np.abs(runs["splu"].momenta).max()
    for solver in ("gmres", "matfree"):
        assert np.abs(runs["splu"].momenta - runs[solver].momenta).max() <= 1e-11 * scale, solver


@pytest.mark.parametrize("integrator", ["gtr-1/2", "ho4"])
def test_matrix_free_product_is_the_assembled_jacobian(integrator):
    sim = random_simulation(integrator, h=0.05, linear_solver="splu")
    st, s = sim.stepper, sim._state
    st.begin(s.positions, s.momenta, s.entropy, sim.h)
    st.predict(st.u)
    u = st.u + np.random.default_rng(1).normal(0.0, 0.02, st.u.shape)
    residual_at(st, u)
    st.jacobian(st.data)
    st.linearize()
    J = st.pattern.matrix(st.data.copy())
    v = np.random.default_rng(2).normal(size=st.u.shape)
    r = np.empty_like(v)
    st.sweep(v.copy(), np.zeros_like(v), r, False)
    assert np.abs(-r - J @ v).max() <= 1e-12 * np.abs(J @ v).max()


def test_matrix_free_falls_back_to_gmres_when_the_sweeps_stall():
    """At h = 0.04 on this stiff net the springs rival the inertia and the inertia-preconditioned
    sweeps diverge; GMRES on the same product takes over and the step matches SuperLU's."""
    runs = {}
    for solver in ("splu", "matfree"):
        sim = random_simulation("ho4", h=0.04, seed=5, linear_solver=solver)
        sim.run(steps=2, diagnostics_every=10**9)
        runs[solver] = sim
    assert runs["matfree"].stepper.solver.fallbacks > 0
    scale = np.abs(runs["splu"].state.momenta).max()
    assert np.abs(runs["splu"].state.momenta - runs["matfree"].state.momenta).max() <= 1e-10 * scale


def test_threaded_kernels_give_the_serial_numbers():
    """Residual, linearization, sweeps and update are per-spring then per-node loops with a
    fixed summation order, so threads do not change a single bit. (The quadratic model's iterated
    thermal solve, hot and uneven: the kernel variants test_implicit_thermal's fallback test
    compiles, so the suite compiles them once.)"""
    net = tn.lattice((4, 4, 4), jitter=0.1, seed=2)
    temperatures = np.random.default_rng(0).uniform(300.0, 600.0, net.n_springs)
    states = []
    for parallel in (False, True):
        sim = tn.Simulation(net, model="quadratic", parameters=dict(E=100.0, beta=0.2, C0=5.0, theta0=300.0, eta0=0.1),
                            temperatures=temperatures,
                            momenta=np.random.default_rng(1).normal(0.0, 1.0, (net.n_nodes, 3)), integrator="ho4",
                            h=0.01, parallel=parallel, integrator_options=dict(linear_solver="matfree"))
        # these five steps take no local Jacobi step: begin() need not compile one (31 s cold)
        sim.stepper._subset_compiled = True
        sim.run(steps=5, diagnostics_every=10**9)
        states.append(sim.state)
    for name in ("positions", "momenta", "thermal_displacement", "entropy"):
        assert np.array_equal(getattr(states[0], name), getattr(states[1], name)), name


def test_cli_runs_an_implicit_integrator(tmp_path):
    from thermonet.cli.main import main

    scene = Path(__file__).resolve().parents[1] / "scenes" / "chain.toml"
    assert main(["run", str(scene), "--integrator", "ho4", "--out", str(tmp_path), "--quiet", "--t-end", "0.05"]) == 0
    data = np.genfromtxt(tmp_path / "diagnostics.csv", delimiter=",", names=True)
    assert "newton_iterations" in data.dtype.names and "newton_residual" in data.dtype.names
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["newton"]["iterations_max"] <= 3 and summary["newton"]["residual_max"] <= 1e-12


def test_a_residual_near_the_tolerance_is_finished_by_jacobi_steps(monkeypatch):
    """On the benchmark-like lattice most HO4 steps end one Newton iteration at 1–1000× the
    tolerance; inertia-preconditioned corrections then bring them below it. Same states as
    full Newton iterations, to the tolerance's size, with fewer sweeps."""
    import thermonet.implicit.core.newton_policy as policy

    def lattice_run():
        net = tn.lattice((10, 10, 10), jitter=0.1, seed=1)
        rng = np.random.default_rng(0)
        sim = tn.Simulation(net, model="hencky", parameters=dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0),
                            temperatures=rng.uniform(300.0, 600.0, net.n_springs),
                            momenta=rng.normal(0.0, 1.0, (net.n_nodes, 3)), integrator="ho4", h=0.012,
                            integrator_options=dict(linear_solver="matfree"))
        sim.run(steps=12, diagnostics_every=10**9)
        return sim

    short = lattice_run()
    monkeypatch.setattr(policy, "JACOBI_RANGE", 0.0)
    full = lattice_run()
    assert short.stepper.timers.jacobi_steps >= 3 and full.stepper.timers.jacobi_steps == 0
    for sim in (short, full):
        assert sim.stepper.summary()["residual_max"] <= 1e-12
    # each Jacobi finish stands in for a full iteration: fewer of those, and fewer sweeps
    assert short.stepper.totals["iterations"] < full.stepper.totals["iterations"]
    assert short.stepper.solver.iterations < full.stepper.solver.iterations
    scale = np.abs(full.state.momenta).max()
    assert np.abs(short.state.momenta - full.state.momenta).max() <= 1e-11 * scale
    assert np.abs(short.state.positions - full.state.positions).max() <= 1e-11


def _newton_on_a_linear_problem(full_error, jacobi_factor, promised=None):
    """Newton on R(u) = u − b whose full solves are off by the relative ``full_error``, whose
    Jacobi steps leave ``jacobi_factor`` of the residual, and whose sweeps showed a contraction
    ``promised`` (default: jacobi_factor); the linear solves and Jacobi steps made, and the
    result."""
    calls = {"solve": 0, "jacobi": 0}

    class Problem:
        b = np.linspace(1.0, 2.0, 7)

        def residual(self, u):
            self.R = u - self.b
            self.Rabs = np.abs(self.b)
            return 0, -1

        def linearize(self):
            pass

    class Solver:
        assembled = False
        contraction = jacobi_factor if promised is None else promised

        def solve(self, rhs, target=0.0, settled=0.0):
            calls["solve"] += 1
            return rhs * (1.0 - full_error)

        def jacobi(self, rhs):
            calls["jacobi"] += 1
            return rhs * (1.0 - jacobi_factor)

    result = newton(Problem(), np.zeros(7), NewtonOptions(), Solver(), NewtonTimers())
    return calls, result


def test_a_jacobi_step_that_does_not_contract_hands_back_to_full_iterations():
    """The 'full' solve is off by ε = 5e-12 on purpose, the Jacobi step goes the wrong way:
    after it, Newton must solve fully again instead of repeating it."""
    calls, result = _newton_on_a_linear_problem(5e-12, 2.0, promised=0.01)
    assert result.converged and calls == {"solve": 2, "jacobi": 1}
    rho = result.history
    assert rho[0] == 1.0 and 1e-12 < rho[1] <= 1e-11 and rho[2] > rho[1] and rho[3] <= 1e-12


def test_jacobi_steps_are_taken_while_their_contraction_says_two_reach_the_tolerance():
    """From 500× the tolerance: at a contraction of 0.01 two Jacobi steps finish; sweeps that
    contracted by 0.3 say three would be needed: a full solve instead; a Jacobi step that
    achieves 0.3 where 0.01 was promised hands back to a full solve (150 · 0.3² > 1); above
    JACOBI_RANGE × the tolerance, full solves whatever the promise."""
    calls, result = _newton_on_a_linear_problem(5e-10, 0.01)
    assert result.converged and calls == {"solve": 1, "jacobi": 2}
    assert 1e-12 < result.history[2] < 1e-11 and result.history[3] <= 1e-12
    calls, result = _newton_on_a_linear_problem(5e-10, 0.3)
    assert result.converged and calls == {"solve": 2, "jacobi": 0}
    calls, result = _newton_on_a_linear_problem(5e-10, 0.3, promised=0.01)
    assert result.converged and calls == {"solve": 2, "jacobi": 1}
    calls, result = _newton_on_a_linear_problem(5e-8, 1e-3)
    assert result.converged and calls == {"solve": 2, "jacobi": 0}


@pytest.mark.parametrize("integrator", ["gtr-1/2", "ho4"])
def test_uniform_parameter_kernels_give_the_per_spring_kernels_numbers(integrator):
    """With every spring's parameters equal the kernels read one shared column (UNIFORM); the
    kernels that stream the (k, m) array must give the same bits."""
    from thermonet.implicit.core.schemes import implicit_kernels

    net = tn.lattice((5, 4, 4), jitter=0.1, seed=3)
    rng = np.random.default_rng(2)
    sim = tn.Simulation(net, model="hencky", parameters=dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0),
                        temperatures=rng.uniform(300.0, 600.0, net.n_springs),
                        momenta=rng.normal(0.0, 1.0, (net.n_nodes, 3)), integrator=integrator, h=0.01,
                        integrator_options=dict(linear_solver="matfree"))
    st, s = sim.stepper, sim._state
    assert st.springs.P.shape[1] == 1
    outputs = []
    for kernels, P in ((st.kernels, st.springs.P),
                       (implicit_kernels(sim.model, st.scheme, sim.parallel, False, st.rate), sim.system.parameters)):
        st.kernels, st.springs = kernels, st.springs._replace(P=P)
        st.begin(s.positions, s.momenta, s.entropy, sim.h)
        st.predict(st.u)
        assert st.residual(st.u) == (0, -1)
        st.linearize()
        assert st.finish(s.thermal_displacement, st._new) == (0, -1)
        outputs.append([a.copy() for a in (st.prediction, st.R, st.Rabs, st.work.jc, *st._new)])
    for a, b in zip(*outputs):
        np.testing.assert_array_equal(a, b)


@pytest.fixture
def series_predictor(monkeypatch):
    """HO4's predictor without its extrapolation from the previous step (the series alone,
    implicit/core/start.py): on this lattice the extrapolated guess is good enough that one
    Newton iteration converges, and these tests are about the finishing Jacobi steps that a
    larger residual needs (a hotter regime, or the first step after a restart)."""
    from thermonet.implicit.ho4.stepper import HO4Stepper

    coefficients = HO4Stepper.predictor_coefficients

    def series(self, h):
        c = coefficients(self, h)
        c[:, 4] = 0.0
        return c

    monkeypatch.setattr(HO4Stepper, "predictor_coefficients", series)


def hot_lattice_ho4(model="hencky", steps=40, beta=0.2, speed=1.0, **options):
    """The benchmark's lattice, smaller (6³ cells), after ``steps`` steps: hot enough that one
    Newton iteration from the series predictor (``series_predictor``) leaves a residual above
    the tolerance at a few nodes (the quadratic model gets there with beta 0.5 and speed 2)."""
    net = tn.lattice((6, 6, 6), jitter=0.1, seed=1)
    rng = np.random.default_rng(0)
    params = (dict(c=100.0, beta=beta, C0=5.0, theta0=300.0) if model != "quadratic"
              else dict(E=100.0, beta=beta, C0=5.0, theta0=300.0, eta0=0.1))
    sim = tn.Simulation(net, model=model, parameters=params, temperatures=rng.uniform(300.0, 600.0, net.n_springs),
                        momenta=speed * rng.normal(0.0, 1.0, (net.n_nodes, 3)), integrator="ho4", h=0.01,
                        integrator_options=dict(linear_solver="matfree", **options))
    sim.run(steps=steps, diagnostics_every=10**9)
    return sim


def one_newton_iteration(sim):
    st, s = sim.stepper, sim.internal_state()
    st.begin(s.positions, s.momenta, s.entropy, sim.h)
    st.predict(st.u)
    st.residual(st.u)
    st.linearize()
    st.u -= st.solver.solve(st.R, 0.1 * st.options.tolerance * st.norms[1])
    st.residual(st.u)
    return st


@pytest.mark.parametrize("model", ["hencky", "quadratic"])
def test_a_local_jacobi_step_leaves_the_residual_a_full_evaluation_gives(model, series_predictor):
    """The step moves only the nodes with large rows and recomputes the residual only at their
    springs and those springs' ends: bit for bit a full evaluation's for the closed-form thermal
    solve ("hencky"); for an iterated solve ("quadratic"), within its tolerance (the springs not
    recomputed keep the temperatures solved from the last seeds)."""
    sim = hot_lattice_ho4(model) if model == "hencky" else hot_lattice_ho4(model, beta=0.5, speed=2.0)
    st = one_newton_iteration(sim)
    fraction = 0.1 * st.options.tolerance
    before = st.u.copy()
    rows = np.abs(st.R).reshape(-1, 6).max(axis=1) > fraction * st.norms[1]
    assert 0 < rows.sum() < 0.05 * len(rows)  # a few nodes, as in the benchmark's later regime
    status, spring, increment = st.local_jacobi(st.u, fraction)
    assert status == 0 and increment > 0
    moved = np.abs(st.u - before).reshape(-1, 6).max(axis=1) > 0
    assert np.array_equal(moved, rows)
    local = (st.R.copy(), st.Rabs.copy(), st.norms, st.work.th0.copy(), st.work.th1.copy(), st.residuals.peak.copy())
    st.residual(st.u)
    full = (st.R, st.Rabs, st.norms, st.work.th0, st.work.th1, st.residuals.peak)
    # the per-node maxima the node selection reads are those of the rows
    assert np.array_equal(st.residuals.peak, np.stack([np.abs(st.R).reshape(-1, 6).max(axis=1),
                                             st.Rabs.reshape(-1, 6).max(axis=1)]))
    if model == "hencky":
        for a, b in zip(local, full):
            assert np.array_equal(a, b)
    else:
        scale = st.norms[1]
        assert np.abs(local[0] - full[0]).max() <= 1e-13 * scale
        assert np.abs(local[3] - full[3]).max() <= 1e-10 * np.abs(full[3]).max()


def test_local_jacobi_steps_replace_global_ones_with_the_same_states(monkeypatch, series_predictor):
    """In the hot regime the finishing Jacobi steps are local (no full residual, no sweep), and
    the steps end where global Jacobi steps end, to the tolerance's size. Where too many nodes
    are above the threshold, a global step is taken instead."""
    from thermonet.implicit.core.stepper import ImplicitStepper

    local = hot_lattice_ho4()
    local.stepper.timers.__init__()
    local.run(steps=20, diagnostics_every=10**9)
    monkeypatch.setattr(ImplicitStepper, "LOCAL_MAX_FRACTION", 0.0)  # every local step declines
    both = hot_lattice_ho4()
    both.stepper.timers.__init__()
    both.run(steps=20, diagnostics_every=10**9)
    t, g = local.stepper.timers, both.stepper.timers
    assert t.local_steps == t.jacobi_steps >= 3 and g.local_steps == 0 and g.jacobi_steps >= 3
    assert t.residuals == 40 < g.residuals  # two full evaluations per step: predictor, iteration
    assert local.stepper.summary()["residual_max"] <= 1e-12 and both.stepper.summary()["residual_max"] <= 1e-12
    scale = np.abs(both.state.momenta).max()
    assert np.abs(local.state.momenta - both.state.momenta).max() <= 1e-11 * scale
    assert np.abs(local.state.positions - both.state.positions).max() <= 1e-11


def test_the_compiled_path_takes_the_same_local_jacobi_steps(series_predictor):
    """The compiled Newton driver finishes with HO4's local Jacobi steps as the sparse path does
    (implicit/core/local_jacobi._local_jacobi), test for test: the same states bit for bit."""
    sparse = hot_lattice_ho4(steps=0)
    compiled = hot_lattice_ho4(steps=0, newton_path="compiled")
    assert compiled.stepper.compiled is not None and sparse.stepper.compiled is None
    for sim in (sparse, compiled):
        sim.stepper.timers.__init__()
        sim.run(steps=60, diagnostics_every=10**9)
    assert sparse.stepper.timers.local_steps >= 3
    np.testing.assert_array_equal(sparse.state.positions, compiled.state.positions)
    np.testing.assert_array_equal(sparse.state.momenta, compiled.state.momenta)
    np.testing.assert_array_equal(sparse.state.thermal_displacement, compiled.state.thermal_displacement)


def test_a_nan_residual_row_shows_in_the_norm():
    """max() passes over NaN; a residual row that is NaN must still make the scaled residual
    not finite (Newton then stops with 'residual not finite' instead of iterating on NaN)."""
    sim = hot_lattice_ho4(steps=1)
    st, s = sim.stepper, sim._state
    st.begin(s.positions, s.momenta, s.entropy, sim.h)
    st.predict(st.u)
    p = s.momenta.copy()
    a = int(st.node_of_block[7])
    p[a, 1] = np.nan
    st.step_start = st.step_start._replace(p=p)  # (only the residual's node rows read it)
    assert st.residual(st.u) == (0, -1)
    assert np.isnan(st.R[6 * 7 + 1]) and st.norms[0] == np.inf
    assert st.residuals.peak[0, 7] == np.inf


def test_the_matfree_solve_stops_a_sweep_early_only_when_the_update_settles_it():
    """``settled``: the sweeps stop once the residual the last update leaves, estimated as the
    measured residual times the worst contraction of the solve, is below it. The solve then
    takes one sweep fewer than one that must measure its residual below the same bound, and the
    du it returns does leave a linear residual below the bound (checked with a product)."""
    sim = hot_lattice_ho4(steps=1)
    st, s = sim.stepper, sim.internal_state()
    st.begin(s.positions, s.momenta, s.entropy, sim.h)
    st.predict(st.u)
    st.residual(st.u)
    st.linearize()
    bound = 0.1 * st.options.tolerance * st.norms[1]
    solver = st.solver
    sweeps = []
    residuals = []
    for settled in (0.0, bound):
        before = solver.iterations
        du = solver.solve(st.R, bound, settled).copy()
        sweeps.append(solver.iterations - before)
        r = np.empty_like(du)
        st.sweep(du, st.R, r, False)  # r = R − J du (no update)
        residuals.append(np.abs(r).max())
    assert sweeps[1] == sweeps[0] - 1 and sweeps[1] >= 2
    assert residuals[0] <= bound and residuals[1] <= bound
