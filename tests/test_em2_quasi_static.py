"""EM2 where it is meant to be used: a part heated and loaded slowly, far above the explicit
limit. Its temperature field and displacement against CO2 at a fine step
(benchmarks/em2_accuracy.py; docs/robustness.md, "EM2 above the explicit limit"), and the time
that heat flow reads inside the loads' splitting around an implicit step."""

import importlib.util
import os
import sys

import numpy as np

import thermonet as tn
from thermonet.heat import Bath
from thermonet.loads import Force

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _benchmark(name):
    sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
    spec = importlib.util.spec_from_file_location(name, os.path.join(ROOT, "benchmarks", f"{name}.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def heated_pulled_bar(h, conduction_every=1):
    """A 2 × 2 × 5 jittered 18-neighbour bar (285 springs): its x = 0 face a bath ramping
    300 → 400 over t = 2, its x = 4 face pushed by a force ramping in over the same time; EM2."""
    net = tn.lattice((5, 2, 2), neighbours=18, jitter=0.1, seed=3)
    x = net.positions[:, 0]
    net = tn.Net(net.positions, net.edges, net.masses, node_groups={"hot": np.flatnonzero(x < 0.5),
                                                                     "end": np.flatnonzero(x > x.max() - 0.5)})
    return tn.Simulation(net, model="hencky", parameters=dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0, g=0.5),
                         temperatures=300.0, integrator="em2", h=h, stability_guard="off", energy_tolerance=None,
                         conduction_every=conduction_every,
                         baths={"hot": Bath("hot", {"start": 300.0, "end": 400.0, "duration": 2.0})},
                         loads={"push": Force("end", {"start": 0.0, "end": 0.5, "duration": 2.0}, direction=[1, 0, 0],
                                              total=True)})


def test_heat_flow_inside_the_loads_splitting_reads_each_steps_time():
    """Around an implicit step, the loads' splitting runs the step (with its conduction) one at a
    time: each must see its own step and time. A run of 20 steps in one call and one of 20
    calls of a step give the same bits, and the bath has heated the bar. (Before, the steps of
    one call all read the call's start: the bath stayed at its start temperature, 300, until
    the next call.)"""
    one = heated_pulled_bar(0.1)
    one.run(steps=20, diagnostics_every=20)
    single = heated_pulled_bar(0.1)
    for _ in range(20):
        single.run(steps=1, diagnostics_every=1)
    assert one.step == single.step == 20
    for name in ("positions", "momenta", "entropy"):
        assert np.array_equal(getattr(one.state, name), getattr(single.state, name)), name
    assert one.temperatures().max() > 310.0  # (measured 317: the bath reached 400 at t = 2; 300 before the fix)


def test_resumed_runs_with_auto_conduction_cycles_follow_the_calls_cadences(tmp_path):
    """With conduction_every = "auto" each call's length and output cadences are among the
    numbers the cycle k must divide (an output inside a cycle is only first order), so calls
    cut differently may conduct differently. The bar at h = 0.1 (λ h = 0.02: "auto" allows up
    to k = 10): 20 steps in one call and 10 + a checkpoint + 10 resumed, all with diagnostics
    every 10, take k = 10 and give the same bits; two calls of 10 with diagnostics every 5 take
    k = 5, other bits, and exactly those of one call of 20 with k = 5: the cycle is the whole
    difference. (So do 4 + 4 steps of benchmarks/em2_paths.py's steel part at 100× against 8:
    k = 4 against 8, 3e-12 m apart; with the cadences or k the same, the same bits.)"""
    from thermonet.io.checkpoint import load_checkpoint, save_checkpoint

    one = heated_pulled_bar(0.1, "auto")
    one.run(steps=20, diagnostics_every=10)
    first = heated_pulled_bar(0.1, "auto")
    first.run(steps=10, diagnostics_every=10)
    save_checkpoint(tmp_path / "c.npz", first.state, {})
    state, _ = load_checkpoint(tmp_path / "c.npz")
    resumed = heated_pulled_bar(0.1, "auto")
    resumed.load_state(state)
    resumed.run(steps=10, diagnostics_every=10)
    halves = heated_pulled_bar(0.1, "auto")
    for _ in range(2):
        halves.run(steps=10, diagnostics_every=5)
    fixed = heated_pulled_bar(0.1, 5)
    fixed.run(steps=20, diagnostics_every=10)
    assert one.conduction_cycle[0] == first.conduction_cycle[0] == resumed.conduction_cycle[0] == 10
    assert halves.conduction_cycle[0] == fixed.conduction_cycle[0] == 5
    assert one.step == resumed.step == halves.step == fixed.step == 20
    for name in ("positions", "momenta", "entropy"):
        assert np.array_equal(getattr(one.state, name), getattr(resumed.state, name)), name
        assert np.array_equal(getattr(halves.state, name), getattr(fixed.state, name)), name
    assert not np.array_equal(one.state.entropy, halves.state.entropy)


def test_a_slowly_heated_and_loaded_part_at_100x_the_explicit_limit_is_within_1_percent():
    """The steel part of benchmarks/em2_accuracy.py --quick (837 springs, ramps over 0.02 s,
    about 50 periods of its slowest mode): EM2 at 100× CO2's stable step (270 steps) against CO2
    at 0.9× it (30 000 steps): the temperature field within 1 % of the largest rise and the
    loaded face's displacement within 1 % (measured 0.03 % and 0.3 %). At 1000× the
    displacement is off by more (measured 1.6 %): the study tells the steps apart."""
    study = _benchmark("em2_accuracy")
    rows = study.main(["--quick"])
    em2 = {round(r["factor"], -1): r for r in rows if r["integrator"] == "em2"}
    fine, coarse = em2[100], em2[1000]
    assert fine["theta_error"] < 0.01 and fine["ux_error"] < 0.01, fine
    assert coarse["ux_error"] > fine["ux_error"], (fine, coarse)


def test_a_carried_factorization_is_rebuilt_on_resume_bit_for_bit(tmp_path, monkeypatch):
    """Factorizations carried from step to step (here on every net: the worth threshold set to
    0) leave their point in the state: the thermal shock at 10× (scenes/thermal_shock.toml), 12 steps
    in one run against 6 + a checkpoint + 6 resumed in a new simulation, the same bits, with
    fewer factorizations than steps (so a carried one was used)."""
    import thermonet.solvers.direct as direct
    from thermonet.io.checkpoint import load_checkpoint, save_checkpoint

    monkeypatch.setattr(direct, "KEPT_ANYWHERE_WORTH", 0.0)
    paths = _benchmark("em2_paths")
    h_max = None

    def make():
        nonlocal h_max
        if h_max is None:
            from thermonet.stability import stable_step
            h_max = stable_step(paths.scene_simulation("thermal_shock", "co2", 1e-3, 12))["h_max"]
        return paths.scene_simulation("thermal_shock", "em2", 10 * h_max, 12)

    one = make()
    one.run(steps=12, diagnostics_every=6)
    s = one.stepper.summary()
    assert s["factorizations"] < s["steps"] and s["reused_factorizations"] > 0, s
    first = make()
    first.run(steps=6, diagnostics_every=6)
    assert "factorization_point" in first.state.extra
    save_checkpoint(tmp_path / "c.npz", first.state, {})
    state, _ = load_checkpoint(tmp_path / "c.npz")
    resumed = make()
    resumed.load_state(state)
    resumed.run(steps=6, diagnostics_every=6)
    assert one.step == resumed.step == 12
    for name in ("positions", "momenta", "entropy", "thermal_displacement"):
        assert np.array_equal(getattr(one.state, name), getattr(resumed.state, name)), name
