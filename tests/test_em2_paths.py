"""EM2 far above the explicit limit: the path "auto" chooses from h·ω_max and the net's size,
every path (kept factorizations included) converging to the same root with the energy exact to
the Newton tolerance, full steps found by continuation in the step instead of substeps, and the
benchmark that measures the paths (its --quick mode)."""

import importlib.util
import math
import os
import warnings

import numpy as np
import pytest

import thermonet as tn
from thermonet.implicit.core.compiled_path import QUIET_STRAIN, SWEEPS_MAX_HW, choose_by_step
from thermonet.implicit.core.large_steps import unrest
from thermonet.stability import stable_step

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..")
#: Newton to its round-off floor (as tests/test_em2.py)
TIGHT = dict(tolerance=1e-15, rtol=1e-12)


def relative_drift(series) -> float:
    s = np.asarray(series, dtype=float)
    return float(np.max(np.abs(s - s[0])) / np.max(np.abs(s[0])))


def scene_simulation(name: str, factor: float, steps: int, **options):
    """A shipped scene with EM2 at ``factor`` × CO2's stable step there (t_end: ``steps`` steps)."""
    from thermonet.scenes.build import build_scene
    from thermonet.scenes.scene import load_scene

    path = os.path.join(ROOT, "scenes", f"{name}.toml")

    def make(integrator, h, extra=()):
        sets = [f"integrator.name={integrator}", f"integrator.h={h!r}", "integrator.check_step=false",
                f"integrator.t_end={h * steps!r}", *extra]
        return build_scene(load_scene(path, sets)).simulation

    probe = make("co2", 1e-3 if name != "bracket" else 1e-7)
    est = stable_step(probe)
    sim = make("em2", factor * est["h_max"], [f"integrator.{k}={v}" for k, v in options.items()])
    return sim, est


# ---------------------------------------------------------------------------------------------
# the choice


def test_the_choice_rule():
    """Sweeps up to SWEEPS_MAX_HW, SuperLU with kept factorizations above; on nets of 25–200
    unknowns SuperLU at every step; the reason names h·ω_max."""
    for size in (24, 201, 2000, 200_000):
        assert choose_by_step(1.0, 0.99 * SWEEPS_MAX_HW, size).linear_solver == "sweeps"
        for hw in (1.01 * SWEEPS_MAX_HW, 20.0, 2e4, np.inf):
            c = choose_by_step(1.0, hw, size)
            assert (c.path, c.linear_solver) == ("sparse", "splu-reuse")
            assert "h·ω_max" in c.reason
    for size in (25, 144, 200):
        for hw in (0.1, 2.0, 0.99 * SWEEPS_MAX_HW, 1e4):
            assert choose_by_step(1.0, hw, size).linear_solver == "splu-reuse"
    c = choose_by_step(0.5, 8.0, 1000)
    assert c.h_omega == 4.0 and c.h == 0.5 and c.path == "compiled"
    # a quiet net (out of balance and motion as a strain): kept factorizations at every step;
    # out of balance: the sweeps near the limit
    for size in (1000, 50000):
        for hw in (0.5, 2.0, 6.0, 0.99 * SWEEPS_MAX_HW, 20.0, 2e4):
            assert choose_by_step(1.0, hw, size, unrest=QUIET_STRAIN).linear_solver == "splu-reuse"
        for unrest in (2 * QUIET_STRAIN, np.inf):
            assert choose_by_step(1.0, 2.0, size, unrest=unrest).linear_solver == "sweeps"
            assert choose_by_step(1.0, 20.0, size, unrest=unrest).linear_solver == "splu-reuse"
    assert choose_by_step(1.0, 2.0, 18, unrest=0.0).linear_solver == "sweeps"  # (the dense LU, made)
    assert "quiet" in choose_by_step(1.0, 2.0, 1000, unrest=0.0).reason


def test_unrest_tells_a_quiet_net_from_one_out_of_balance_or_moving():
    """unrest: 0 at rest in equilibrium; the out-of-balance force as a strain of the stiffest
    spring; the relative displacement of a spring's ends over the step."""
    net = tn.Net([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], [[0, 1], [1, 2]], [1.0, 1.0, 1.0],
                 anchored=[True, False, True])
    sim = tn.Simulation(net, model="hencky", parameters=dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0),
                        temperatures=300.0, integrator="em2", h=0.1, stability_guard="off")
    st = sim.internal_state()
    system = sim.stepper.system
    assert unrest(system, st.positions, st.momenta, st.entropy, 0.1) == 0.0
    x = st.positions.copy()
    x[1, 0] += 1e-3  # one spring stretched, the other compressed: out of balance by about 2e-3
    assert 1e-3 < unrest(system, x, st.momenta, st.entropy, 0.1) < 4e-3
    p = st.momenta.copy()
    p[1, 1] = 2e-3  # 2e-3 relative to its neighbours, over a step of 0.1
    assert unrest(system, st.positions, p, st.entropy, 0.1) == pytest.approx(2e-4, rel=1e-9)


#: the fastest path benchmarks/em2_paths.py measured, per net and step (× CO2's stable step);
#: benchmarks/README.md, "EM2 far above the explicit limit" (at 10× on the bracket, splu without
#: kept factorizations measured within the scatter of splu-reuse: 19 against 21 ms)
MEASURED_FASTEST = {1: "sweeps", 10: "splu-reuse", 100: "splu-reuse", 1e4: "splu-reuse"}
#: … and on the steel part of em2_paths.py (at rest, heated and pushed slowly; "part"): the
#: kept factorizations at every step, 1× and 3× included (benchmarks/README.md, "The steel part")
MEASURED_FASTEST_QUIET = {1: "splu-reuse", 3: "splu-reuse", 10: "splu-reuse", 100: "splu-reuse", 1e4: "splu-reuse"}


@pytest.mark.parametrize("net", ["lattice", "bracket", "part"])
def test_auto_chooses_the_measured_fastest_path(net):
    """At 1×, 10×, 100× and 1e4× CO2's stable step (and 3× on the part), on a lattice and on
    tetrahedral parts (the hot bracket, which rings, and the steel part loaded slowly), "auto"
    (as a run starts: at its first step) takes the path the benchmark measured fastest, and the
    run summary says which and why."""
    bench = _benchmark()
    if net == "part":
        est = stable_step(bench.part_simulation(0.006, "co2", 1e-7))
    for factor, fastest in (MEASURED_FASTEST_QUIET if net == "part" else MEASURED_FASTEST).items():
        if net == "lattice":
            est = stable_step(bench.lattice_simulation(5, "co2", 1.0))
            sim = bench.lattice_simulation(5, "em2", factor * est["h_max"])
        elif net == "part":
            sim = bench.part_simulation(0.006, "em2", factor * est["h_max"])
        else:
            sim, est = scene_simulation("bracket", factor, 10)
        st = sim.stepper.inner if hasattr(sim.stepper, "inner") else sim.stepper
        st.choose_path(sim.internal_state(), sim.h)
        s = st.summary()
        assert s["h_omega_max"] == pytest.approx(2.0 * factor, rel=1e-6)
        assert s["linear_solver"] == ("compiled, sweeps" if fastest == "sweeps" else fastest)
        assert s["newton_path"] == ("compiled" if fastest == "sweeps" else "sparse")
        assert f"h·ω_max = {2.0 * factor:.3g}" in s["path_reason"]


# ---------------------------------------------------------------------------------------------
# every path: the same root, the energy exact


def small_net(factor: float, moving: bool = True, **options):
    """A jittered 18-neighbour 3×2×2 lattice, one node anchored, random masses, pre-stress,
    temperatures and momenta (``moving``; else at rest), gravity; EM2 at ``factor`` × CO2's
    stable step."""
    rng = np.random.default_rng(3)
    base = tn.lattice((3, 2, 2), neighbours=18, jitter=0.2, seed=3)
    anchored = np.zeros(base.n_nodes, dtype=bool)
    anchored[5] = True
    net = tn.Net(base.positions, base.edges, rng.uniform(0.5, 2.0, base.n_nodes), anchored,
                 rest_lengths=base.lengths() * rng.uniform(0.95, 1.05, base.n_springs))
    momenta = rng.normal(0.0, 0.3, (net.n_nodes, 3))
    momenta[anchored] = 0.0
    if not moving:
        momenta[:] = 0.0
    kw = dict(model="hencky", parameters=dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0),
              temperatures=rng.uniform(290.0, 320.0, net.n_springs), momenta=momenta, gravity=[0.0, 0.0, -1.0],
              stability_guard="off", energy_tolerance=None)
    h = factor * stable_step(tn.Simulation(net, integrator="co2", h=1.0, **kw))["h_max"]
    return tn.Simulation(net, integrator="em2", h=h, integrator_options=options, **kw)


PATHS = {
    "sweeps": dict(newton_path="compiled"),
    "dense": dict(newton_path="compiled-dense"),
    "splu": dict(newton_path="sparse", linear_solver="splu"),
    "splu-reuse": dict(newton_path="sparse", linear_solver="splu-reuse"),
    "splu-reuse-double": dict(newton_path="sparse", linear_solver="splu-reuse-double"),
    # (kept factors solved on their elimination tree from the first solve: the test sets
    # TREE_AFTER_SOLVES and TREE_MIN_UNKNOWNS to 0)
    "splu-reuse, tree": dict(newton_path="sparse", linear_solver="splu-reuse"),
    "auto": {},
}


@pytest.mark.parametrize("factor", [1, 30])
def test_every_path_reaches_the_same_root_with_the_energy_exact(factor, monkeypatch):
    """At 1× and 30× CO2's stable step: one step from the same state on each path gives the
    same positions to the Newton tolerance; 40 steps keep the energy to the round-off of the
    tightened Newton tolerance on each path, the kept factorizations' (modified Newton, reused
    across a step's iterations) included, solved by SuperLU or on their elimination tree, and
    "auto" needs no substeps."""
    import thermonet.solvers.direct as direct

    first, drift = {}, {}
    after, least = direct.TREE_AFTER_SOLVES, direct.TREE_MIN_UNKNOWNS
    for name, options in PATHS.items():
        tree = name.endswith("tree")
        monkeypatch.setattr(direct, "TREE_AFTER_SOLVES", 0 if tree else after)
        monkeypatch.setattr(direct, "TREE_MIN_UNKNOWNS", 0 if tree else least)
        sim = small_net(factor, **options, **TIGHT)
        sim.run(steps=1, diagnostics_every=1)
        first[name] = sim.state.positions.copy()
        d = sim.run(steps=40, diagnostics_every=4)
        drift[name] = relative_drift(d.energy)
        s = sim.stepper.summary()
        if name == "auto":  # (the compiled paths at 30×: some steps as substeps, energy exact all the same)
            assert s["retried_steps"] == 0
        if name.startswith("splu-reuse"):
            assert s["reused_factorizations"] > 0 and s["factorizations"] < s["iterations"]
            assert (s["tree_solves"] > 0) == tree
            if tree:  # the run summary says so
                from thermonet.cli.report import format_summary

                assert "solves with kept factors compiled on their elimination tree" in format_summary(sim, name)
    scale = np.abs(first["splu"]).max()
    for name, x in first.items():
        # the roots agree to the tolerance's reach in the unknowns (1e-15 of the largest
        # residual term, amplified by the Newton matrix's conditioning at this h)
        assert np.abs(x - first["splu"]).max() <= 1e-11 * scale, name
    for name, value in drift.items():
        assert value <= 1e-13, (name, value)


def test_kept_factorizations_are_reused_and_dropped():
    """Modified Newton (splu-reuse) at 30× on the small net: fewer factorizations than Newton
    iterations, the same converged residuals as splu, and a factorization of another h is never
    used (the inertia blocks are m/h). Where the predictor took the last step's displacement
    (the net started at rest), Newton starts from the residual the predictor left there instead
    of evaluating it again: the same bits, fewer residual evaluations."""
    runs = {}
    for name in ("splu", "splu-reuse"):
        sim = small_net(30, newton_path="sparse", linear_solver=name)
        sim.run(steps=20, diagnostics_every=10**9)
        runs[name] = sim.stepper.summary()
    quiet = {}
    for again in (False, True):
        sim = small_net(30, moving=False, newton_path="sparse", linear_solver="splu-reuse")
        if again:
            sim.stepper.take_evaluated = lambda u: None
        sim.run(steps=20, diagnostics_every=10**9)
        quiet[again] = sim
    taken, again = quiet[False], quiet[True]
    assert np.array_equal(taken.state.positions, again.state.positions)
    assert np.array_equal(taken.state.entropy, again.state.entropy)
    assert taken.stepper.timers.residuals < again.stepper.timers.residuals
    a, b = runs["splu"], runs["splu-reuse"]
    assert a["factorizations"] == 0  # (plain splu factorizes at every iteration, uncounted)
    assert b["factorizations"] + b["reused_factorizations"] == b["iterations"]
    assert b["factorizations"] <= 0.8 * b["iterations"]
    assert max(a["residual_max"], b["residual_max"]) <= 1e-12
    sim = small_net(30, newton_path="sparse", linear_solver="splu-reuse")
    sim.run(steps=3, diagnostics_every=10**9)
    st = sim.stepper
    kept = st.timers.factorizations
    sim.h = 0.5 * sim.h
    sim.run(steps=1, diagnostics_every=10**9)
    assert st.timers.factorizations > kept and st.solver.h == sim.h


# ---------------------------------------------------------------------------------------------
# full steps


def test_hot_2d_lattice_at_10x_takes_full_steps():
    """scenes/lattice2d.toml (a clamped triangulated plate swinging under gravity, its soft half
    150 K hotter) at 10× CO2's stable step: fewer than 10 % of the steps are redone as substeps
    (measured 2 of 100; before continuation in the step, 29 of 50), the steps the predictor's
    Newton solve misses are solved by continuation as whole steps, and the energy stays exact."""
    sim, _ = scene_simulation("lattice2d", 10, 100)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        d = sim.run(steps=100, diagnostics_every=10)
    s = sim.stepper.summary()
    assert s["linear_solver"] == "splu-reuse" and s["newton_path"] == "sparse"
    assert s["substep_fraction"] == s["retried_steps"] / 100 < 0.1
    assert s["continued_steps"] > 10  # (measured 94): the predictor alone misses most
    assert relative_drift(d.energy) <= 1e-11  # (measured 1.0e-12; default tolerance 1e-12)


def test_continuation_solves_the_step_itself():
    """A step solved by continuation in h is one step of h: the displacement it commits, put
    back into the step's equations at h from the start state, leaves a residual at the Newton
    tolerance (scenes/lattice2d.toml at 10×, its first step: the Newton solve from the predictor
    stalls; no substeps allowed)."""
    sim, _ = scene_simulation("lattice2d", 10, 1, retry=0)
    st = sim.stepper
    start = sim.internal_state()
    x0, p0, eta0 = start.positions.copy(), start.momenta.copy(), start.entropy.copy()
    sim.run(steps=1, diagnostics_every=10**9)
    s = st.summary()
    assert s["continued_steps"] == 1 and s["retried_steps"] == 0
    x1 = sim.internal_state().positions
    u = (x1 - x0)[st.node_of_block].ravel()
    st.begin(x0, p0, eta0, sim.h)
    st.predict(st.u)
    assert st.residual(u) == (0, -1)
    rmax, scale = st.norms
    assert rmax / scale <= 1e-12
    # and the step's equations at h/2 are not what it solved
    st.begin(x0, p0, eta0, 0.5 * sim.h)
    st.predict(st.u)
    st.residual(u)
    assert st.norms[0] / st.norms[1] > 1e-3


# ---------------------------------------------------------------------------------------------
# the benchmark


def _benchmark():
    spec = importlib.util.spec_from_file_location("em2_paths", os.path.join(ROOT, "benchmarks", "em2_paths.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_benchmark_runs_quick(capsys):
    """benchmarks/em2_paths.py --quick: every row measured, and auto's row on the path its
    reason names."""
    rows = _benchmark().main(["--quick"])
    out = capsys.readouterr().out
    assert "auto / fastest" in out
    assert {r["path"] for r in rows} == {"sweeps", "splu-reuse", "auto"}
    for r in rows:
        assert r["failed"] is None and np.isfinite(r["ms"]) and r["ms"] > 0
        if r["path"] == "auto":
            expect = choose_by_step(r["h"], r["h_omega"] / r["h"], r["summary"]["unknowns"]).linear_solver
            assert r["summary"]["linear_solver"] == ("compiled, sweeps" if expect == "sweeps" else expect)


def test_the_direct_solvers_benchmark_runs_quick(capsys):
    """benchmarks/direct_solvers.py --quick: EM2's Newton matrix of the small steel part solved
    by SuperLU in double precision to round-off, with SuperLU's factors on their elimination
    tree to round-off at one and two threads, in single precision to its precision (and by
    PARDISO, and by CHOLMOD's Cholesky of its symmetric part, to round-off where pypardiso and
    cholespy are installed)."""
    spec = importlib.util.spec_from_file_location("direct_solvers", os.path.join(ROOT, "benchmarks", "direct_solvers.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    rows = module.main(["--quick"])
    assert rows["SuperLU double"]["residual"] <= 1e-13
    assert 1e-12 < rows["SuperLU single"]["residual"] <= 1e-4
    assert rows["SuperLU double"]["nnz"] == rows["SuperLU single"]["nnz"] > 0
    assert {"SuperLU's factors on the tree, 1 thread(s)", "SuperLU's factors on the tree, 2 thread(s)"} <= set(rows)
    for name, row in rows.items():
        assert row["factorization_ms"] > 0 and row["solve_ms"] > 0
        if name.startswith(("PARDISO", "SuperLU's factors on the tree", "CHOLMOD")):
            assert row["residual"] <= 1e-13
    assert "| SuperLU double |" in capsys.readouterr().out


def test_the_run_summary_says_which_path_ran_why_and_the_substep_fraction():
    from thermonet.cli.report import format_summary

    sim = small_net(30)  # 105 unknowns
    sim.run(steps=3, diagnostics_every=3)
    line = next(l for l in format_summary(sim, "small").splitlines() if l.strip().startswith("Newton path:"))
    assert "sparse, splu-reuse" in line and "h·ω_max = 60" in line and "105 unknowns (≤ 200)" in line
    assert "substepped steps 0 %" in line
    bench = _benchmark()
    est = stable_step(bench.lattice_simulation(5, "co2", 1.0))
    sim = bench.lattice_simulation(5, "em2", est["h_max"])  # 540 unknowns, 1×
    sim.run(steps=2, diagnostics_every=2)
    line = next(l for l in format_summary(sim, "lattice").splitlines() if l.strip().startswith("Newton path:"))
    assert "Newton path: compiled, sweeps (" in line and "h·ω_max = 2 " in line and "≤ 10" in line


REST_SCENE = """
[net]
mesh = "{mesh}"
[materials.bracket]
youngs_modulus = 200e9
thermal_expansion = 12e-6
density = 7850.0
heat_capacity = 3.6e6
theta0 = 293.15
[initial.temperature]
uniform = 293.15
[effects]
anchors = ["clamp"]
[integrator]
name = "em2"
h = {h!r}
t_end = {t_end!r}
retry = 0
newton_path = "{path}"
energy_tolerance = 1e6  # (the energy at rest is round-off, -1e-13: a relative guard means nothing)
"""


def test_a_part_at_rest_in_equilibrium_takes_steps():
    """A steel part from gmsh (SI units) at rest at θ0: no forces but round-off (its lengths
    differ from the rest lengths by an ulp), so its residual is round-off over a scale of
    round-off, a scaled residual of order 1 that Newton cannot reduce (measured 0.67). Below
    EM2's residual floor it is converged, on the sparse path far above the limit and on the
    compiled path at the limit, and the part stays at rest. (Before the floor, every step
    failed there, 16 substeps included.)"""
    from thermonet.scenes.build import build_scene
    from thermonet.scenes.scene import scene_from_text

    mesh = os.path.join(ROOT, "meshes", "bracket.msh")
    for h, path in ((1e-3, "auto"), (3e-7, "compiled")):
        sim = build_scene(scene_from_text(REST_SCENE.format(mesh=mesh, h=h, t_end=3 * h, path=path))).simulation
        x0 = sim.state.positions.copy()
        sim.run(steps=3, diagnostics_every=3)
        s = sim.stepper.summary()
        assert s["steps"] == 3 and s["retried_steps"] == 0 and s["continued_steps"] == 0
        assert s["residual_max"] > 1e-3  # the scaled residual at rest, round-off over round-off (measured 0.085)
        assert np.abs(sim.state.positions - x0).max() <= 1e-15


def test_a_resumed_run_continues_bit_for_bit(tmp_path):
    """scenes/lattice2d.toml at 10× (kept factorizations, continuation in the step, its memory
    of hard steps): 12 steps in one run, and 6 + a checkpoint + 6 resumed in a new simulation,
    give the same bits."""
    from thermonet.io.checkpoint import load_checkpoint, save_checkpoint

    one, _ = scene_simulation("lattice2d", 10, 12)
    one.run(steps=12, diagnostics_every=6)
    first, _ = scene_simulation("lattice2d", 10, 12)
    first.run(steps=6, diagnostics_every=6)
    assert first.stepper.summary()["continued_steps"] > 0
    save_checkpoint(tmp_path / "c.npz", first.state, {})
    state, _ = load_checkpoint(tmp_path / "c.npz")
    resumed, _ = scene_simulation("lattice2d", 10, 12)
    resumed.load_state(state)
    resumed.run(steps=6, diagnostics_every=6)
    assert one.step == resumed.step == 12
    for name in ("positions", "momenta", "entropy", "thermal_displacement"):
        assert np.array_equal(getattr(one.state, name), getattr(resumed.state, name)), name


def test_a_resumed_run_solving_on_the_elimination_tree_continues_bit_for_bit(tmp_path, monkeypatch):
    """scenes/lattice2d.toml at 10×, its factorizations carried from step to step and solved on
    their elimination tree after 3 solves: 12 steps in one run, and 6 + a checkpoint + 6
    resumed (the factorization rebuilt, with its count of solves), give the same bits."""
    import thermonet.solvers.direct as direct
    from thermonet.io.checkpoint import load_checkpoint, save_checkpoint

    monkeypatch.setattr(direct, "KEPT_ANYWHERE_WORTH", 1.0)  # (carried at this size too)
    monkeypatch.setattr(direct, "TREE_AFTER_SOLVES", 3)
    monkeypatch.setattr(direct, "TREE_MIN_UNKNOWNS", 0)
    one, _ = scene_simulation("lattice2d", 10, 12)
    one.run(steps=12, diagnostics_every=6)
    first, _ = scene_simulation("lattice2d", 10, 12)
    first.run(steps=6, diagnostics_every=6)
    save_checkpoint(tmp_path / "c.npz", first.state, {})
    state, _ = load_checkpoint(tmp_path / "c.npz")
    assert state.extra["factorization_solves"][0] >= 3
    count = state.extra["factorization_tree"]  # (SuperLU's solves toward the first layout; one made)
    assert count[0] >= 3 and count[1] == 1.0
    resumed, _ = scene_simulation("lattice2d", 10, 12)
    resumed.load_state(state)
    resumed.run(steps=6, diagnostics_every=6)
    assert first.stepper.summary()["tree_solves"] > 0 and resumed.stepper.summary()["tree_solves"] > 0
    assert resumed.stepper.solver.factorizations > 1  # (those made after the resume go on the tree as laid out)
    for name in ("superlu_solves", "laid_out"):
        assert getattr(resumed.stepper.solver, name) == getattr(one.stepper.solver, name), name
    assert one.step == resumed.step == 12
    for name in ("positions", "momenta", "entropy", "thermal_displacement"):
        assert np.array_equal(getattr(one.state, name), getattr(resumed.state, name)), name


def small_part(factor: float) -> tn.Simulation:
    """benchmarks/em2_paths.py's steel part at mesh size 8 mm (1 244 springs), heated and pushed
    slowly from rest, EM2 on the path "auto" takes at ``factor`` × CO2's stable step."""
    bench = _benchmark()
    h = stable_step(bench.part_simulation(0.008, "co2", 1.0, threads=1))["h_max"]
    return bench.part_simulation(0.008, "em2", factor * h, threads=1, **bench.PATHS["auto"])


def test_the_staleness_count_renews_a_factorization_only_where_its_steps_take_more_corrections():
    """The rule of solvers.direct.STALE_SHARE on a kept factorization, one step at a time: the
    step that made it is not counted, the next STALE_BASELINE_STEPS set the baseline, steps
    that take as many corrections never renew it, steps that take more renew it once their
    excess reaches STALE_SHARE × worth, and a fresh factorization starts the count again."""
    import thermonet.solvers.direct as direct

    sim = small_part(100)
    sim.run(steps=1, diagnostics_every=10**9)
    solver = sim.stepper.solver.inner

    def step(corrections: int) -> bool:
        solver.staleness[3] = corrections  # (the solves of the step that ends)
        solver.new_step()
        return solver.stale

    solver.factorize(sim.stepper.data, solver.h)
    solver.worth = 100.0  # (so carried from step to step, and renewed after 0.2 × 100 extra corrections)
    assert list(solver.staleness) == [-1.0, 0.0, 0.0, 0.0]
    assert not step(1)  # the step that made it (its solves before the factorization not seen)
    assert [step(c) for c in (2, 2, 3)] == [False] * 3 and solver.staleness[1] == 7.0
    assert not any(step(c) for c in [2, 3, 2] * 100)  # as many as the baseline's mean: never
    beyond = solver.staleness[2]
    renewals = solver.stale_refactorizations
    taken = [step(4) for _ in range(20)]
    assert taken.index(True) == math.ceil((direct.STALE_SHARE * 100.0 - beyond) / (4 - 7 / 3)) - 1
    assert solver.stale_refactorizations == renewals + 1
    solver.factorize(sim.stepper.data, solver.h)
    solver.worth = 100.0
    assert list(solver.staleness) == [-1.0, 0.0, 0.0, 0.0] and not solver.stale
    # (a renewed factorization waits for the tree as any other: the run's count toward a layout)
    assert not solver.laid_out and solver.solves_before_tree == max(0, direct.TREE_AFTER_SOLVES - solver.superlu_solves)


def test_a_resumed_run_renews_a_stale_factorization_where_one_run_does(tmp_path, monkeypatch):
    """The steel part at 8 mm, 100× the explicit limit, its factorization carried from step to
    step (at this size only where told to) and renewed when stale: 60 steps in one run, and 30 +
    a checkpoint (the count of staleness and the factorization's worth with it) + 30 resumed,
    give the same bits; the renewals save corrections, and the energy balance is that of a run
    without them to the Newton tolerance."""
    import thermonet.solvers.direct as direct

    monkeypatch.setattr(direct, "KEPT_ANYWHERE_WORTH", 1.0)
    one = small_part(100)
    one.run(steps=60, diagnostics_every=30)
    done = one.stepper.summary()
    assert done["stale_refactorizations"] >= 2
    from thermonet.cli.report import newton_path_line

    assert (f"{done['factorizations']} factorizations ({done['stale_refactorizations']} because the kept one had "
            f"grown stale)") in newton_path_line(done)
    monkeypatch.setattr(direct, "STALE_SHARE", math.inf)
    never = small_part(100)
    never.run(steps=60, diagnostics_every=30)
    assert never.stepper.summary()["stale_refactorizations"] == 0
    assert done["iterations"] < never.stepper.summary()["iterations"]
    monkeypatch.undo()
    monkeypatch.setattr(direct, "KEPT_ANYWHERE_WORTH", 1.0)
    state, resumed = resumed_halves(lambda: small_part(100), 30, tmp_path / "c.npz")
    assert state.extra["factorization_staleness"][0] > 0  # (a count under way goes with the state)
    assert resumed.stepper.summary()["stale_refactorizations"] >= 1
    assert one.step == resumed.step == 60
    for name in ("positions", "momenta", "entropy", "thermal_displacement"):
        assert np.array_equal(getattr(one.state, name), getattr(resumed.state, name)), name
    # the energy balance (4.4e-9 J of the 0.01 J the bath gives, with or without renewals) moves
    # only at the level of the Newton tolerance (measured 1.6e-13 J)
    balance, balance_never = one.diagnostics.column("energy_balance"), never.diagnostics.column("energy_balance")
    assert np.max(np.abs(balance - balance_never)) < 1e-10 * np.max(np.abs(one.diagnostics.column("heat_in")))


def free_lattice(factor: float, linear_solver: str) -> tn.Simulation:
    """A 4³ 18-neighbour hencky lattice, hot and nowhere held (its rigid motions make the Newton
    matrix's condition number 1 + (h ω_max)²/4), EM2 at ``factor`` × CO2's stable step on the
    sparse path with ``linear_solver``."""
    net = tn.lattice((4, 4, 4), neighbours=18, jitter=0.1, seed=2)
    kw = dict(parameters=dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0), model="hencky",
              temperatures=np.random.default_rng(1).uniform(280.0, 360.0, net.n_springs), energy_tolerance=None,
              stability_guard="off")
    h = factor * stable_step(tn.Simulation(net, integrator="co2", h=1.0, **kw))["h_max"]
    return tn.Simulation(net, integrator="em2", h=h, integrator_options=dict(newton_path="sparse",
                                                                             linear_solver=linear_solver), **kw)


def resumed_halves(make, steps: int, path):
    """``steps`` steps of a simulation ``make()`` makes, a checkpoint at ``path``, and a new one
    resumed from it for ``steps`` more: (the checkpointed state, the resumed simulation)."""
    from thermonet.io.checkpoint import load_checkpoint, save_checkpoint

    first = make()
    first.run(steps=steps, diagnostics_every=steps)
    save_checkpoint(path, first.state, {})
    state, _ = load_checkpoint(path)
    resumed = make()
    resumed.load_state(state)
    resumed.run(steps=steps, diagnostics_every=steps)
    return state, resumed


def test_single_precision_factors_go_double_where_they_cannot_solve(tmp_path, monkeypatch):
    """Kept factors are single precision; on a free net at 1e4× CO2's stable step (condition
    number ~1e8) their first solve leaves a linear residual of the order of the right-hand side,
    so the solver factorizes in double from there on, says why, and the run is the double
    solver's bit for bit; a checkpoint carries the precision, so a resumed run continues bit for
    bit. At 100× single factors solve, to the same root as double ones within the tolerance."""
    import thermonet.solvers.direct as direct
    from thermonet.cli.report import format_summary

    monkeypatch.setattr(direct, "SINGLE_MIN_UNKNOWNS", 0)  # (single factors on this small net too)

    double = free_lattice(1e4, "splu-reuse-double")
    double.run(steps=4, diagnostics_every=2)
    one = free_lattice(1e4, "splu-reuse")
    one.run(steps=4, diagnostics_every=2)
    s = one.stepper.summary()
    assert s["factor_precision"] == "double" and "linear residual" in s["factor_precision_raised"]
    assert double.stepper.summary()["factor_precision"] == "double"
    assert "double precision" in format_summary(one, "em2")
    for name in ("positions", "momenta", "entropy"):
        assert np.array_equal(getattr(one.state, name), getattr(double.state, name)), name

    state, resumed = resumed_halves(lambda: free_lattice(1e4, "splu-reuse"), 2, tmp_path / "c.npz")
    assert state.extra["factorization_precision"][0] == 64.0
    assert resumed.stepper.summary()["factor_precision"] == "double"
    for name in ("positions", "momenta", "entropy"):
        assert np.array_equal(getattr(one.state, name), getattr(resumed.state, name)), name

    single, double = free_lattice(100, "splu-reuse"), free_lattice(100, "splu-reuse-double")
    for sim in (single, double):
        sim.run(steps=3, diagnostics_every=3)
    assert single.stepper.summary()["factor_precision"] == "single"
    x = double.state.positions
    assert 0.0 < np.abs(single.state.positions - x).max() <= 1e-10 * np.abs(x).max()

    # single factors carried from step to step, rebuilt on resume: the same bits
    monkeypatch.setattr(direct, "KEPT_ANYWHERE_WORTH", 1.0)
    one = free_lattice(100, "splu-reuse")
    one.run(steps=4, diagnostics_every=2)
    state, resumed = resumed_halves(lambda: free_lattice(100, "splu-reuse"), 2, tmp_path / "s.npz")
    assert state.extra["factorization_precision"][0] == 32.0 and state.extra["factorization_solves"][0] > 0
    assert resumed.stepper.summary()["reused_factorizations"] > 0
    for name in ("positions", "momenta", "entropy"):
        assert np.array_equal(getattr(one.state, name), getattr(resumed.state, name)), name


def test_a_close_last_displacement_is_taken_without_weighing_the_own_guess(monkeypatch):
    """The steel part of benchmarks/em2_paths.py (coarse mesh) loaded and heated from rest, at
    100× CO2's stable step (kept factorizations): where the last step's displacement leaves a
    scaled residual at most PREVIOUS_TAKEN the predictor takes it without evaluating its own
    guess (which it would not have taken): one residual evaluation a step fewer, the same
    Newton corrections, the same root to the Newton tolerance. With PREVIOUS_TAKEN < 0 both
    guesses are weighed at every step."""
    from thermonet.implicit.em2 import stepper as em2_stepper

    bench = _benchmark()
    h = 100 * stable_step(bench.part_simulation(0.006, "co2", 1e-7))["h_max"]
    sims = {}
    for taken in (em2_stepper.PREVIOUS_TAKEN, -1.0):
        monkeypatch.setattr(em2_stepper, "PREVIOUS_TAKEN", taken)
        sim = bench.part_simulation(0.006, "em2", h, newton_path="sparse", linear_solver="splu-reuse")
        sim.run(steps=12, diagnostics_every=10**9)
        sims[taken > 0] = sim
    close, weighed = sims[True], sims[False]
    # (steps 2–12 may take it: measured 9 of them, the first ones still moving off rest)
    assert close.stepper.timers.residuals <= weighed.stepper.timers.residuals - 8
    assert close.stepper.summary()["iterations"] == weighed.stepper.summary()["iterations"]
    scale = np.abs(weighed.state.positions).max()
    assert np.abs(close.state.positions - weighed.state.positions).max() <= 1e-12 * scale
