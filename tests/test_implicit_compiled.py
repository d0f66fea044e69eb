"""The compiled Newton path of the implicit integrators (implicit/core/compiled_newton.py,
implicit/core/compiled_path.py) against the sparse path: the same steps to the Newton tolerance
(dense LU on small nets, matrix-free sweeps on larger ones), chunking that changes nothing,
failures reported alike, and the automatic choice."""

import numpy as np
import pytest

import thermonet as tn
from thermonet.errors import InputError
from thermonet.integrators.base import StepFailure
from thermonet.implicit.core.compiled_newton import lu_factor, lu_solve


def lattice_simulation(cells, integrator, h=0.01, gravity=(0.0, 0.0, -9.81), threads=None, **options):
    """A jittered lattice of ``cells`` with node 0 anchored, gravity, random momenta and
    temperatures; uniform parameters (one compiled kernel variant for every case here)."""
    rng = np.random.default_rng(7)
    base = tn.lattice(cells, jitter=0.15, seed=2)
    anchored = np.zeros(base.n_nodes, dtype=bool)
    anchored[0] = True
    net = tn.Net(base.positions, base.edges, np.full(base.n_nodes, 1.0), anchored, rest_lengths=base.lengths() * 0.95)
    momenta = rng.normal(0.0, 2.0, (net.n_nodes, 3))
    momenta[anchored] = 0.0
    return tn.Simulation(net, model="hencky", parameters=dict(c=100.0, beta=0.5, C0=2.0, theta0=300.0),
                         temperatures=rng.uniform(250.0, 700.0, net.n_springs), momenta=momenta, gravity=gravity,
                         integrator=integrator, h=h, integrator_options=options,
                         **({} if threads is None else dict(parallel=threads)))


#: Newton to its round-off floor (as tests/test_em2.py)
TIGHT = dict(tolerance=1e-15, rtol=1e-12)
CASES = [("gtr-1/2", {}), ("gtr-alpha", dict(alpha=0.3)), ("ho4", {})]
#: EM2 (its own predictor, damped corrections, atol at the positions' round-off) where its
#: sparse path's linear solver is the compiled one's kind (its own chain test below)
WITH_EM2 = CASES + [("em2", {})]


def run_both(make, steps):
    """(compiled, sparse) simulations from ``make(newton_path)`` after ``steps`` steps."""
    out = []
    for path in ("compiled", "sparse"):
        sim = make(path)
        sim.run(steps=steps, diagnostics_every=10**9)
        out.append(sim)
    return out


def assert_same_states(a, b, rtol):
    """Positions, momenta (mechanical) and Φ, entropy, temperatures (thermal) agree."""
    sa, sb = a.state, b.state
    for name in ("positions", "momenta", "thermal_displacement", "entropy"):
        x, y = getattr(sa, name), getattr(sb, name)
        scale = np.abs(y).max()
        assert np.abs(x - y).max() <= rtol * scale, name
    ta, tb = a.temperatures(), b.temperatures()
    assert np.abs(ta - tb).max() <= rtol * np.abs(tb).max()


@pytest.mark.parametrize("integrator,options", CASES)
@pytest.mark.parametrize("path", ["compiled", "compiled-dense"])
def test_compiled_path_equals_sparse_path_on_the_chain(integrator, options, path):
    compiled, sparse = run_both(
        lambda p: tn.chain_simulation(integrator, h=0.01, integrator_options=dict(
            options, newton_path=path if p == "compiled" else p)), 200)
    kind = "dense" if path == "compiled-dense" else "sweeps"
    assert compiled.stepper.summary()["linear_solver"] == f"compiled, {kind}"
    assert sparse.stepper.summary()["linear_solver"] == "splu"
    assert_same_states(compiled, sparse, 1e-10)
    assert compiled.stepper.summary()["iterations"] == sparse.stepper.summary()["iterations"]


@pytest.mark.parametrize("integrator,options", WITH_EM2)
@pytest.mark.parametrize("cells,path", [((1, 1, 1), "compiled-dense"), ((2, 2, 2), "compiled")])
def test_compiled_path_equals_sparse_path_with_anchor_and_gravity(integrator, options, cells, path):
    """(1, 1, 1): 7 free nodes, dense solves; (2, 2, 2): 26 free nodes, matrix-free sweeps (the
    sparse path's linear solver: SuperLU, then the matrix-free one)."""
    compiled, sparse = run_both(
        lambda p: lattice_simulation(cells, integrator, newton_path=path if p == "compiled" else p, **options), 40)
    kind = "dense" if path == "compiled-dense" else "sweeps"
    assert compiled.stepper.summary()["linear_solver"] == f"compiled, {kind}"
    assert sparse.stepper.compiled is None
    assert_same_states(compiled, sparse, 1e-10)
    # the anchored node stayed where it was, and gravity acted (the centre of mass fell)
    assert np.array_equal(compiled.state.positions[0], compiled.net.positions[0])
    assert compiled.state.positions[:, 2].mean() < compiled.net.positions[:, 2].mean() - 1e-3


@pytest.mark.parametrize("integrator", ["gtr-1/2", "ho4", "em2"])
@pytest.mark.parametrize("cells,path", [((1, 1, 1), "compiled-dense"), ((2, 2, 2), "compiled")])
def test_many_steps_per_call_equal_one_step_per_call(integrator, cells, path):
    many = lattice_simulation(cells, integrator, newton_path=path)
    many.run(steps=12, diagnostics_every=10**9)
    one = lattice_simulation(cells, integrator, newton_path=path)
    for _ in range(12):
        one.run(steps=1, diagnostics_every=10**9)
    for name in ("positions", "momenta", "thermal_displacement", "entropy"):
        assert np.array_equal(getattr(many.state, name), getattr(one.state, name)), name
    assert many.stepper.summary()["iterations"] == one.stepper.summary()["iterations"]


@pytest.mark.parametrize("path,solver", [("compiled-dense", "splu"), ("compiled", "matfree")])
def test_em2_compiled_path_equals_sparse_path_on_the_chain(path, solver):
    """EM2 on the chain against the sparse path with the like linear solves (LU; sweeps with
    Jacobi finishing steps): the same steps, iterations and Newton atol (which follows the
    positions' round-off, per step on both paths)."""
    sims = [tn.chain_simulation("em2", h=0.01, integrator_options=dict(newton_path=path)),
            tn.chain_simulation("em2", h=0.01, integrator_options=dict(newton_path="sparse", linear_solver=solver))]
    for sim in sims:
        sim.run(steps=200, diagnostics_every=10**9)
    compiled, sparse = sims
    kind = "dense" if path == "compiled-dense" else "sweeps"
    assert compiled.stepper.summary()["linear_solver"] == f"compiled, {kind}"
    assert sparse.stepper.compiled is None
    assert_same_states(compiled, sparse, 1e-11)  # measured: 0 (LU), 3e-12 (sweeps)
    assert compiled.stepper.summary()["iterations"] == sparse.stepper.summary()["iterations"]
    assert compiled.stepper.options.atol == sparse.stepper.options.atol > 0.0


def test_em2_damped_steps_far_above_the_explicit_limit_agree():
    """At 10× CO2's stable step the corrections are shortened and line-searched (measured on the
    sparse path: 182 of 288 corrections searched, 79 shortened): the compiled path takes the same
    iterations, and its energy is kept exactly."""
    h = 1.04  # 10 × CO2's h_max on the chain (0.104)
    sims = [tn.chain_simulation("em2", h=h, integrator_options=dict(newton_path=p, linear_solver=s))
            for p, s in (("compiled-dense", "auto"), ("sparse", "splu"))]
    energies = [sim.run(steps=50, diagnostics_every=5).energy for sim in sims]
    compiled, sparse = sims
    assert compiled.stepper.summary()["iterations"] == sparse.stepper.summary()["iterations"]
    assert compiled.stepper.summary()["iterations"] > 4 * 50  # damped: more than Newton's usual 2–3
    assert_same_states(compiled, sparse, 1e-8)  # measured 1.2e-9 (the two LUs' round-off, amplified)
    e = np.asarray(energies[0])
    assert np.abs(e - e[0]).max() <= 1e-12 * abs(e[0])  # measured 1.2e-13


def test_em2_energy_over_many_steps_with_sweeps():
    """2e4 steps of the chain on the compiled path with matrix-free sweeps (the dense one: the
    1e5-step test of tests/test_em2.py): energy, angular momentum about the anchored node and
    entropy kept to Newton's round-off floor."""
    sim = tn.chain_simulation("em2", h=0.01, integrator_options=dict(newton_path="compiled", **TIGHT))
    eta0 = sim.state.entropy.copy()
    d = sim.run(steps=20_000, diagnostics_every=2_000)
    assert sim.stepper.summary()["linear_solver"] == "compiled, sweeps" and sim.step == 20_000
    e = np.asarray(d.energy)
    assert np.abs(e - e[0]).max() <= 1e-13 * abs(e[0])  # measured: 2.1e-15, L 2.8e-13
    L = np.column_stack([d.Lx, d.Ly, d.Lz])
    assert np.linalg.norm(L - L[0], axis=1).max() <= 1e-12 * np.linalg.norm(L[0])
    assert np.array_equal(sim.state.entropy, eta0)


def test_em2_threaded_compiled_path_gives_the_serial_numbers():
    """EM2's threaded kernels inside the compiled driver (sweeps), with gravity and an anchor:
    the serial run's states, bit for bit (fixed summation orders; the shared node rows write
    the residual's arrays from within the threaded loop)."""
    serial, threaded = (lattice_simulation((2, 2, 2), "em2", threads=t, newton_path="compiled") for t in (False, True))
    assert threaded.stepper.kernels_parallel and not serial.stepper.kernels_parallel
    for sim in (serial, threaded):
        sim.run(steps=20, diagnostics_every=10**9)
    assert threaded.stepper.summary()["linear_solver"] == "compiled, sweeps"
    for name in ("positions", "momenta", "thermal_displacement", "entropy"):
        assert np.array_equal(getattr(serial.state, name), getattr(threaded.state, name)), name


def failure_of(sim, steps):
    with pytest.raises(StepFailure) as info:
        sim.run(steps=steps, diagnostics_every=10**9)
    return info.value


@pytest.mark.parametrize("integrator,compiled_path", [
    ("gtr-1/2", "compiled"), ("gtr-1/2", "compiled-dense"), ("ho4", "compiled"), ("ho4", "compiled-dense"),
    # EM2's predictor leaves a first residual whose square the sweeps' forcing term allows for:
    # the last residual then depends on the linear solver (splu on the sparse path)
    ("em2", "compiled-dense")])
def test_failures_are_reported_as_on_the_sparse_path(integrator, compiled_path):
    """No convergence (an unreachable tolerance in one iteration), with and without retries:
    the same StepFailure, details and state left at the step's start."""
    failures, states = [], []
    for path in (compiled_path, "sparse"):
        sim = tn.chain_simulation(integrator, h=0.01, integrator_options=dict(
            newton_path=path, tolerance=1e-300, max_iterations=1, retry=1))
        x0 = sim.state.positions.copy()
        failures.append(failure_of(sim, 5))
        states.append((x0, sim.state.positions.copy()))
    compiled, sparse = failures
    assert compiled.steps_done == sparse.steps_done == 0
    for key in ("step", "reason", "retries"):
        assert compiled.details[key] == sparse.details[key], key
    # the worst node is where the last residual (near round-off here) peaks: the same only where
    # the linear solves are (an LU each); with sweeps, named all the same
    for key in ("worst_node", "worst_spring"):
        assert compiled.details[key] is not None
        if compiled_path == "compiled-dense":
            assert compiled.details[key] == sparse.details[key], key
    assert "no convergence in 1 iterations" in str(compiled)
    np.testing.assert_allclose(compiled.details["residual_history"], sparse.details["residual_history"],
                               rtol=1e-6, atol=1e-14)  # (the last one near round-off)
    for x0, x in states:
        assert np.array_equal(x0, x)


@pytest.mark.parametrize("integrator", ["gtr-1/2", "ho4"])
def test_a_failure_within_a_chunk_keeps_the_steps_before_it(integrator):
    """A step that needs a second Newton iteration (near t = 7.4 on the chain) where one is
    allowed, after some hundred good ones: the good steps are committed, the failing step is
    named alike on both paths."""
    failures = []
    for path in ("compiled", "sparse"):
        sim = tn.chain_simulation(integrator, h=0.012, integrator_options=dict(newton_path=path, max_iterations=1))
        failures.append((failure_of(sim, 700), sim.state.positions.copy(), sim.state.step))
    (fc, xc, kc), (fs, xs, ks) = failures
    assert fc.steps_done == fs.steps_done > 0
    assert kc == ks == fc.steps_done
    assert fc.details["reason"] == fs.details["reason"]
    np.testing.assert_allclose(xc, xs, rtol=1e-8, atol=1e-10)


def test_retry_with_substeps_on_the_compiled_path():
    """A step too large for one Newton iteration succeeds as substeps; reported as retried."""
    stats = []
    for path in ("compiled", "sparse"):
        sim = tn.chain_simulation("ho4", h=0.08, integrator_options=dict(newton_path=path, max_iterations=1, retry=3))
        with pytest.warns(RuntimeWarning, match="substeps"):
            sim.run(steps=3, diagnostics_every=10**9)
        stats.append((sim.stepper.summary(), sim.state.positions.copy()))
    (sc, xc), (ss, xs) = stats
    assert sc["retried_steps"] == ss["retried_steps"] > 0
    assert sc["substeps_max"] == ss["substeps_max"] > 1
    np.testing.assert_allclose(xc, xs, rtol=1e-9)


def test_the_automatic_choice():
    assert tn.chain_simulation("ho4").stepper.summary()["linear_solver"] == "compiled, dense"  # 18 unknowns
    assert lattice_simulation((2, 2, 2), "gtr-1/2").stepper.summary()["linear_solver"] == "compiled, sweeps"
    assert tn.chain_simulation("em2").stepper.summary()["linear_solver"] == "compiled, dense"  # 9 unknowns
    assert lattice_simulation((2, 2, 2), "em2").stepper.summary()["linear_solver"] == "compiled, sweeps"
    assert tn.chain_simulation("em2", integrator_options=dict(newton_path="sparse")).stepper.compiled is None
    dense = tn.chain_simulation("gtr-1/2", integrator_options=dict(newton_path="compiled-dense"))
    assert dense.stepper.summary()["linear_solver"] == "compiled, dense"
    # an explicit linear solver, or newton_path="sparse", selects the sparse path
    assert tn.chain_simulation("ho4", integrator_options=dict(linear_solver="splu")).stepper.compiled is None
    assert tn.chain_simulation("ho4", integrator_options=dict(newton_path="sparse")).stepper.compiled is None
    with pytest.raises(InputError, match="newton_path"):
        tn.chain_simulation("ho4", integrator_options=dict(newton_path="fast"))


def test_dense_lu_solves_like_numpy():
    rng = np.random.default_rng(1)
    for n in (1, 5, 40):
        A = rng.normal(size=(n, n)) + n * np.eye(n) * rng.choice([-1, 1], n)
        A[[0, -1]] = A[[-1, 0]]  # needs pivoting
        b = rng.normal(size=n)
        LU, piv, x = A.copy(), np.zeros(n, dtype=np.int64), b.copy()
        assert lu_factor(LU, piv)
        lu_solve(LU, piv, x)
        np.testing.assert_allclose(x, np.linalg.solve(A, b), rtol=1e-10, atol=1e-12)
    assert not lu_factor(np.zeros((3, 3)), np.zeros(3, dtype=np.int64))


@pytest.mark.parametrize("path,solver", [("sparse", "splu"), ("compiled-dense", "compiled, dense"),
                                         ("Compiled", "compiled, sweeps")])
def test_a_scene_chooses_the_newton_path(path, solver):
    """[integrator] newton_path reaches the stepper (a bad value: tests/scenes_bad/)."""
    from thermonet.scenes import scene_from_text

    text = f'[net]\ngenerator = "chain"\n[integrator]\nname = "em2"\nh = 0.01\nsteps = 1\nnewton_path = "{path}"\n'
    sim = scene_from_text(text, file="inline.toml").build().simulation
    assert sim.stepper.summary()["linear_solver"] == solver
