"""The hard-case suite: stiff, strongly deformed, nearly collapsed, thermally extreme
and long runs, each with the bound it was measured to meet (docs/robustness.md has the table).

Bounds are the measured figure rounded up by at most about 3×, so a regression that doubles
an error is still caught while round-off differences between machines are not.
"""

import warnings

import numpy as np
import pytest

import thermonet as tn
from thermonet.stability import stable_step
from thermonet.step_policy import REFUSE, SAFETY, StepWarning, UnstableStepError, check_step

#: the run-time guards off (stable step re-estimated, energy departure): these cases run at or
#: beyond the stability limit on purpose, to measure it or to see the other safeguards act
UNGUARDED = dict(stability_guard="off", energy_tolerance=None)


def drift(series) -> float:
    """max |q(t) − q(0)| over a diagnostics series."""
    series = np.asarray(series)
    return float(np.max(np.abs(series - series[0])))


def angular_drift(d) -> float:
    """max |L(t) − L(0)| / |L(0)| (vector norm)."""
    L = np.column_stack([d.Lx, d.Ly, d.Lz])
    return float(np.max(np.linalg.norm(L - L[0], axis=1)) / np.linalg.norm(L[0]))


# ---------------------------------------------------------------------------------------------
# stiff


def stiff_lattice(h=1.0, **kw):
    """c = 1e6 on a jittered 3×3×3-cell lattice (64 nodes, 144 springs), random momenta."""
    net = tn.lattice((3, 3, 3), jitter=0.1, seed=1)
    momenta = np.random.default_rng(0).normal(size=(net.n_nodes, 3))
    return tn.Simulation(net, parameters=dict(c=1e6, beta=0.2), temperatures=400.0, momenta=momenta, h=h, **kw)


def test_stiff_lattice_at_half_the_limit_is_bounded():
    sim = stiff_lattice()
    sim.h = 0.5 * stable_step(sim)["h_max"]  # ≈ 5.0e-4
    assert check_step(sim).verdict == "ok"
    d = sim.run(steps=10_000, diagnostics_every=100)
    e = d.energy
    # measured: 8.0e-5 relative; second half no larger than the first (no growth)
    assert drift(e) / e[0] < 2.5e-4
    half = len(e) // 2
    assert np.max(np.abs(e[half:] - e[0])) <= 1.2 * np.max(np.abs(e[:half] - e[0]))
    assert drift(d.entropy) == 0.0
    assert max(drift(d.px), drift(d.py), drift(d.pz)) < 1e-10 * 100


def test_stiff_lattice_at_twice_the_limit_is_refused_and_never_returns_nans():
    sim = stiff_lattice()
    h_max = stable_step(sim)["h_max"]
    sim.h = 2.0 * h_max
    with pytest.raises(UnstableStepError, match=r"h = .* is 2× the stability limit h_max ≈ .* use h ≤"):
        check_step(sim)
    with pytest.warns(StepWarning):
        verdict = check_step(sim, allow_unstable=True)
    assert verdict.verdict == "allowed" and verdict.ratio == pytest.approx(2.0)
    # run anyway: either stopped with a named error, or a finite (if meaningless) state
    try:
        sim.run(steps=2000, diagnostics_every=10)
    except tn.SimulationError as exc:
        assert "step" in str(exc)
    else:
        assert np.isfinite(sim.state.positions).all() and np.isfinite(sim.diagnostics.energy).all()


@pytest.mark.parametrize("factor, verdict", [(0.5, "ok"), (0.9, "ok"), (1.2, "warn"), (1.5, "warn")])
def test_policy_verdicts(factor, verdict):
    sim = stiff_lattice()
    sim.h = factor * stable_step(sim)["h_max"] * (1 - 1e-9)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert check_step(sim).verdict == verdict
    assert (len(caught) == 1) == (verdict == "warn")
    assert SAFETY == 0.9 and REFUSE == 1.5  # the documented fractions


def test_policy_is_silent_for_a_user_integrator_without_interval():
    from thermonet.explicit.splitting import CO2
    from thermonet.integrators import Integrator

    class Mine(Integrator):  # an implicit-looking user integrator: no kicks, no declared interval
        name, order, explicit = "mine", 2, False

        def make_stepper(self, system, **options):
            return CO2.make_stepper(system, **options)

    net = tn.lattice((2, 2, 2))
    sim = tn.Simulation(net, parameters=dict(c=1e6), integrator=Mine(), h=1.0)
    assert check_step(sim).verdict == "unknown"


# ---------------------------------------------------------------------------------------------
# large deformation


@pytest.mark.parametrize("integrator, h, energy_bound, entropy_bound", [
    ("co2", 1e-4, 1e-7, 0.0),      # measured 3.0e-8, entropy bit-exact
    ("ho4", 1e-3, 3e-8, 1e-12),    # measured 8.0e-9, entropy to Newton tolerance (1.3e-13)
])
def test_chain_with_ten_times_the_momenta(integrator, h, energy_bound, entropy_bound):
    sim = tn.chain_simulation(integrator, h=h, momentum_scale=10.0)
    stretches = []
    d = sim.run(t_end=2.0, diagnostics_every=10, observers=[(100, lambda s: stretches.append(s.lengths().max()))])
    assert max(stretches) > 10.0  # the springs reach hundreds of rest lengths (measured 477)
    e = d.energy
    assert drift(e) / e[0] < energy_bound
    assert drift(d.entropy) <= entropy_bound * abs(d.entropy[0])
    assert angular_drift(d) <= 1e-10


# ---------------------------------------------------------------------------------------------
# near collapse


def collapsing_spring(h):
    """One hencky spring (anchored at node 0), node 1 thrown at node 0 with exactly the kinetic
    energy that the spring stores at λ = 1e-3 (β = 0 for that; the thermal part is a passenger)."""
    L = np.log(1e-3)
    v = np.sqrt(2 * 0.5 * L * L)
    net = tn.Net([[0, 0, 0], [1, 0, 0]], [[0, 1]], masses=[1.0, 1.0], anchored=[0])
    return tn.Simulation(net, parameters=dict(c=1.0, beta=0.0), velocities=[[0, 0, 0], [-v, 0, 0]], h=h, **UNGUARDED)


def test_a_spring_driven_to_a_thousandth_and_back():
    sim = collapsing_spring(1e-4)
    lengths = []
    d = sim.run(t_end=0.6, diagnostics_every=10, observers=[(1, lambda s: lengths.append(s.lengths()[0]))])
    assert min(lengths) == pytest.approx(1e-3, rel=0.01)  # measured 0.9972e-3
    assert lengths[-1] > 1.0  # and back beyond its rest length
    e = d.energy
    # measured 8.4e-4 at the turning point, where ω = √(c (1 − L))/l ≈ 2.8e3 so h ω ≈ 0.28
    assert drift(e) / e[0] < 2e-3
    assert abs(e[-1] - e[0]) / e[0] < 2e-3


def test_a_collapse_with_a_coarse_step_never_returns_nans():
    """The policy sees ω = 1 at rest and lets h = 1e-2 through; at the turning point hω ≈ 28.
    Measured: energy error 105 % without non-finite values (in-kernel detection may stop it)."""
    sim = collapsing_spring(1e-2)
    assert check_step(sim).verdict == "ok"
    try:
        sim.run(t_end=1.0, diagnostics_every=1)
    except tn.SimulationError as exc:
        assert "spring 0" in str(exc) or "node 1" in str(exc)
    assert np.isfinite(sim.state.positions).all()


# ---------------------------------------------------------------------------------------------
# thermal extremes


def hot_and_cold(factor):
    """An 18-neighbour 4×4×4 lattice, springs with x < 2 at 10 θ0 and the others at 0.1 θ0
    (c = 1e4, β = 0.2: the hot half expands ~5 %, the cold one contracts), random momenta,
    h = factor · h_max; run to the same time 2500 h_max·0.5 whatever the factor."""
    net = tn.lattice((4, 4, 4), neighbours=18, jitter=0.1, seed=4)
    mid = net.positions[net.edges].mean(axis=1)[:, 0]
    theta = np.where(mid < 2.0, 3000.0, 30.0)
    momenta = np.random.default_rng(5).normal(size=(net.n_nodes, 3))
    sim = tn.Simulation(net, parameters=dict(c=1e4, beta=0.2), temperatures=theta, momenta=momenta, h=1.0)
    h_max = stable_step(sim)["h_max"]
    sim.h = factor * h_max
    return sim, sim.run(t_end=2500 * h_max, diagnostics_every=int(round(25 / factor)))


def test_hot_region_next_to_a_cold_one():
    sim, d = hot_and_cold(0.5)
    temps = sim.temperatures()
    assert temps.min() < 31 and temps.max() > 2990  # still 10 θ0 next to 0.1 θ0 (no conduction)
    e = d.energy
    err = drift(e) / e[0]
    assert err < 1.5e-4  # measured 5.2e-5
    assert drift(d.entropy) == 0.0
    p0 = np.linalg.norm([d.px[0], d.py[0], d.pz[0]])
    assert max(drift(d.px), drift(d.py), drift(d.pz)) <= 1e-10 * max(p0, 1.0)
    assert angular_drift(d) <= 1e-10
    # the energy error is the integrator's O(h²) oscillation, not a drift: halving h quarters it
    _, d2 = hot_and_cold(0.25)
    assert 3.0 < err / (drift(d2.energy) / d2.energy[0]) < 5.0  # measured 3.9


# ---------------------------------------------------------------------------------------------
# long run


def test_a_million_steps_of_co2_on_the_triangle():
    sim = tn.triangle_simulation("co2", h=1e-3)
    d = sim.run(steps=10**6, diagnostics_every=1000)  # ~0.4 s in the compiled loop
    e = d.energy
    n = len(e) // 10
    amplitude = np.ptp(e)  # measured 1.2e-2
    assert abs(e[-n:].mean() - e[:n].mean()) < amplitude  # measured 3.7e-4: no drift
    assert amplitude / e[0] < 1e-5
    assert drift(d.entropy) == 0.0
    for q in (d.px, d.py, d.pz, d.Lx, d.Ly, d.Lz):
        assert drift(q) <= 1e-10 * max(1.0, abs(q[0]))


# ---------------------------------------------------------------------------------------------
# implicit under stress


def hot_coupled_net(integrator, factor):
    """A 26-neighbour 2×2×2 lattice, c = 1e4, β = 50 and θ = 10 θ0: the adiabatic stiffness is
    ~150× the elastic one; h = factor · h_max of the integrator's measured interval."""
    net = tn.lattice((2, 2, 2), neighbours=26, jitter=0.1, seed=2)
    momenta = np.random.default_rng(1).normal(scale=5.0, size=(net.n_nodes, 3))
    momenta -= momenta.mean(axis=0)
    kw = dict(parameters=dict(c=1e4, beta=50.0, C0=5.0, theta0=300.0), temperatures=3000.0, momenta=momenta,
              integrator=integrator, **UNGUARDED)
    sim = tn.Simulation(net, h=1.0, **kw)
    h = factor * stable_step(sim)["h_max"]
    return tn.Simulation(net, h=h, **kw), kw, net


@pytest.mark.parametrize("integrator, energy_bound", [("ho4", 2e-2), ("gtr-1/2", 0.1)])  # measured 7.2e-3, 4.4e-2
def test_implicit_near_its_limit_converges_and_conserves(integrator, energy_bound):
    sim, _, _ = hot_coupled_net(integrator, 0.9)
    d = sim.run(steps=300, diagnostics_every=10)
    newton = sim.conservation_summary()["_run"]["newton"]
    assert newton["retried_steps"] == 0 and newton["residual_max"] <= 1e-12
    e = d.energy
    assert drift(e) / e[0] < energy_bound
    assert drift(d.entropy) <= 1e-13 * abs(d.entropy[0])  # measured 1.4e-15
    assert max(drift(d.px), drift(d.py), drift(d.pz)) < 1e-11
    assert angular_drift(d) < 1e-9


@pytest.mark.parametrize("integrator", ["ho4", "gtr-1/2"])
def test_implicit_far_beyond_its_limit_fails_with_state_intact(integrator):
    sim, kw, net = hot_coupled_net(integrator, 3.0)
    with pytest.raises(tn.SimulationError, match=rf"{integrator}: step (\d+) -> \d+ .* failed: .*state left at step"):
        sim.run(steps=300, diagnostics_every=10)
    done = sim.step
    assert 0 < done < 300
    again = tn.Simulation(net, h=sim.h, **kw)
    again.run(steps=done)
    np.testing.assert_array_equal(sim.state.positions, again.state.positions)
    np.testing.assert_array_equal(sim.state.entropy, again.state.entropy)


# ---------------------------------------------------------------------------------------------
# stability intervals: every integrator, just inside bounded, just outside unbounded or stopped


def linear_spring_energy_growth(integrator, hw, steps=2000, **options):
    """max energy error over the second half of a run of a linear spring (quadratic model, β = 0,
    ω² = 50) at h = hw/ω, over that of the first half; inf when the run stops or is non-finite."""
    net = tn.Net([[0, 0, 0], [1, 0, 0]], [[0, 1]], masses=[1.0, 2.0], anchored=[0], rest_lengths=[1.0])
    sim = tn.Simulation(net, model="quadratic", parameters=dict(E=100.0, beta=0.0),
                        momenta=[[0, 0, 0], [0.01, 0, 0]], integrator=integrator, h=hw / np.sqrt(50.0),
                        integrator_options=options, **UNGUARDED)
    try:
        with np.errstate(all="ignore"):
            e = sim.run(steps=steps, diagnostics_every=10).energy
    except tn.SimulationError:
        assert np.isfinite(sim.state.positions).all() or sim.integrator.explicit
        return np.inf
    if not np.isfinite(e).all():
        return np.inf
    half = len(e) // 2
    return np.max(np.abs(e[half:] - e[0])) / max(np.max(np.abs(e[1:half] - e[0])), 1e-300)


# Newton's scaled-residual floor on this small-amplitude oscillation is ~1.2e-12 near hω = 2.8,
# just above the default tolerance 1e-12 (reported to the implicit solver's owner): 1e-10 here.
# The interval is the scheme's, not its Newton path's: the sparse path solves the same equations
# to the same tolerance (the compiled path gives its states and failures:
# tests/test_implicit_compiled.py), and it spares the suite compiling a Newton driver for the
# quadratic model that no other test runs.
SPARSE = {"newton_path": "sparse"}
IMPLICIT = {"ho4": {"tolerance": 1e-10, **SPARSE}, "gtr-1/2": SPARSE, "gtr-alpha": {"alpha": 0.25, **SPARSE}}


@pytest.mark.parametrize("name", ["gtr-0", "gtr-1", "co2", "f10", "nm2", "co4", "co6", "ho4", "gtr-1/2", "gtr-alpha"])
def test_every_interval_is_the_measured_limit(name):
    from thermonet.stability import stability_interval

    options = IMPLICIT.get(name, {})
    c = stability_interval(tn.get_integrator(name, **{k: v for k, v in options.items() if k == "alpha"}))
    assert np.isfinite(c)
    assert linear_spring_energy_growth(name, 0.99 * c, **options) < 1.5
    grown = linear_spring_energy_growth(name, 1.01 * c, **options)
    assert not np.isfinite(grown) or grown > 10.0


def test_ho4_interval_matches_the_closed_form_of_its_step_matrix():
    """HO4 on ẍ = −x (m = ω = 1): the linear equations (58a), (57a), (58b) give a 2×2 step
    matrix of determinant 1; its trace reaches −2 at hω = 2√2."""
    from thermonet.stability import MEASURED_INTERVALS

    def trace(h):
        A = np.array([[8 / (3 * h), -1 / (3 * h)], [-8 / h**2 + 1, 4 / h**2]])
        cols = []
        for x0, p0 in ((1.0, 0.0), (0.0, 1.0)):
            xh, x1 = np.linalg.solve(A, [p0 + 7 * x0 / (3 * h) - h / 6 * x0, -4 * x0 / h**2])
            cols.append([x1, (x0 - 8 * xh + 7 * x1) / (3 * h) - h / 6 * x1])
        return np.trace(np.array(cols).T)

    c = MEASURED_INTERVALS["ho4"]
    assert c == pytest.approx(2 * np.sqrt(2), abs=1e-4)
    assert abs(trace(0.999 * c)) < 2 < abs(trace(1.001 * c))


# ---------------------------------------------------------------------------------------------
# the policy in `thermonet run`

STIFF_SCENE = """
[net]
generator = "lattice"
[net.lattice]
shape = [3, 3, 3]
[materials.all]
c = 1e6
[integrator]
h = 0.01
steps = 5
"""


@pytest.mark.parametrize("extra, rc, words", [
    ([], 2, ["stiff.toml:9: integrator.h: h = 0.01 is 9.2", "× the stability limit", "--allow-unstable-step"]),
    (["--allow-unstable-step"], 0, ["warning: h = 0.01"]),
    (["--set", "integrator.check_step=false"], 0, ["warning: h = 0.01"]),
    (["--h", "0.0014"], 0, ["warning: h = 0.0014 is 1.29×", "safety fraction 0.9"]),
    (["--h", "0.0005"], 0, []),
])
def test_run_applies_the_policy(tmp_path, capsys, extra, rc, words):
    from thermonet.cli.main import main

    scene = tmp_path / "stiff.toml"
    scene.write_text(STIFF_SCENE)
    out = tmp_path / "out"
    assert main(["run", str(scene), "--out", str(out)] + extra) == rc
    err = capsys.readouterr().err
    for w in words:
        assert w in err
    assert ("warning" in err) == (len(words) > 0 and rc == 0)
    assert (out / "summary.json").exists() == (rc == 0)
