"""Every benchmark with a quick mode runs here, so that none can rot (speed is measured in
benchmarks/, not here: these check that the scripts run and report sane numbers)."""

import importlib.util
import math
import pathlib

ROOT = pathlib.Path(__file__).resolve().parent.parent


def load(name: str):
    spec = importlib.util.spec_from_file_location(f"benchmark_{name}", ROOT / "benchmarks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_heat_cost_quick_mode_runs_and_reports_the_conduction_cycle(capsys):
    rows, parts = load("heat_cost").main(["--quick"])
    assert {r["net"].split()[0] for r in rows} == {"lattice", "gmsh"}
    passes = load("heat_cost").PASSES
    for r in rows:
        assert all(math.isfinite(r[k]) and r[k] > 0 for k in ("adiabatic", "conduction", "schedule", "sweeps", "auto"))
        assert r["colours"] >= 1 and r["gpu_pair_phases"] > r["gpu_star_phases"] > 0
        # each pass of the conducting step timed alone (the quick mode runs one round)
        assert set(r["passes"]) == set(passes) and all(math.isfinite(t) and t > 0 for t in r["passes"].values())
    steel, shock = parts
    # the steel part at its explicit stable step: heat is slow, conduction runs every many steps
    assert steel["k"] >= 10 and "auto: fastest conduction rate" in steel["why"]
    assert shock["k"] >= 1 and shock["springs"] == 673
    text = capsys.readouterr().out
    assert "| steel bracket" in text and "| scenes/thermal_shock.toml" in text
    assert "Each pass of a conducting step alone" in text


def test_gpu_check_quick_mode_runs_its_benchmarks_under_the_cuda_simulator(monkeypatch, capsys):
    """benchmarks/gpu_check.py --quick: gpu_throughput.py and gpu_heat_cost.py in their quick modes
    (subprocesses under Numba's CUDA simulator), their rows read back into the one table."""
    import importlib.util

    import pytest

    if importlib.util.find_spec("numba_cuda") is None:
        pytest.skip("numba-cuda is not installed (pip install '.[cuda]')")
    monkeypatch.setenv("NUMBA_ENABLE_CUDASIM", "1")
    parts = load("gpu_check").main(["--quick"])
    assert [p["name"] for p in parts] == ["throughput (this tree)", "conduction cost (this tree)"]
    assert all(p["rc"] == 0 for p in parts), [p["out"][-2000:] for p in parts]
    throughput, heat = parts
    (row,) = throughput["rows"]  # the quick mode's one tiny lattice
    assert row["springs"] == 144 and row["nodes"] == 64
    assert row["gpu_rate_fused"] > 0 and row["gpu_rate_two_launch"] > 0
    assert 100 < row["bytes_per_spring_step"] < 150 and row["device_bytes_per_spring"] > 0
    assert "max relative difference 0.00e+00" in throughput["out"]  # the simulator runs the CPU's operations
    # two launch modes × adiabatic, every step, "auto"'s k; conduction's phases per step on the
    # GPU: the lattice's two node colours a half sweep, the meeting ones run as one phase
    table = [line for line in heat["out"].splitlines() if line.startswith("| 54 |")]
    assert len(table) == 6 and len(heat["rows"]) == 6
    assert all(float(r.split("|")[5].strip().rstrip("×")) > 0 for r in table)
    assert all(r.split("|")[6].strip() in ("–", "3") for r in table)
    # the launch profile: the temperature pass, θ start, two star colours and the joined one, finish,
    # the whole step
    profile = [line.split("|")[1].strip() for line in heat["out"].splitlines()
               if line.startswith("| ") and line.split("|")[1].strip()[:5] in ("tempe", "phase", "whole")]
    assert profile[0] == "temperature pass" and profile[-1].startswith("whole step"), profile
    assert sum(name.endswith("star colour") for name in profile) == 2 and any("finish" in name for name in profile)
    assert any(name.startswith("phase 2 joined") for name in profile)  # the meeting colours as one phase
    out = capsys.readouterr().out
    assert "## GPU check" in out and "| throughput (this tree) | 0 |" in out


def finite_positive(*values) -> bool:
    return all(v is not None and math.isfinite(v) and v > 0 for v in values)


def test_loads_cost_quick_mode_runs_every_configuration_with_its_loads(capsys):
    module = load("loads_cost")
    rows = module.main(["--quick"])
    assert [r["configuration"] for r in rows] == [c[0] for c in module.CONFIGS]
    assert all(r["springs"] == 144 and finite_positive(r["rate"], r["ratio"]) for r in rows)
    assert rows[0]["ratio"] == 1.0  # (a) against itself
    loads = {r["configuration"][:3]: {c[:-5] for c in r["columns"] if c.endswith("_work") and c != "work"}
             for r in rows}
    # (a) and (e) have no loads; (b) drives x = max, (c) and (d) add the force on z = max
    assert loads == {"(a)": set(), "(b)": {"pull"}, "(c)": {"pull", "push"}, "(d)": {"pull", "push"},
                     "(e)": set()}
    by = {r["configuration"][:3]: r["diagnostics_rows"] for r in rows}
    assert by["(d)"] > by["(c)"] and by["(e)"] > by["(a)"]  # a diagnostics row every 10 steps
    text = capsys.readouterr().out
    assert "144 springs" in text and "| configuration | steps/s (median) | cost vs (a) |" in text


def test_effects_cost_quick_mode_runs_every_configuration_and_writes_frames(capsys):
    module = load("effects_cost")
    rows = module.main(["--quick"])
    assert [r["configuration"] for r in rows] == [c[0] for c in module.CONFIGS]
    assert all(r["springs"] == 144 and finite_positive(r["rate"], r["cost"]) for r in rows)
    assert rows[0]["cost"] == 1.0 and rows[0]["overhead"] is None
    assert all(math.isfinite(r["overhead"]) and r["overhead"] > -1 for r in rows[1:])
    for r, config in zip(rows, module.CONFIGS):
        frames, writes = config[2], config[4]
        if not frames:
            assert r["frame_ms"] is r["write_ms"] is r["written"] is None
            continue
        assert finite_positive(r["frame_ms"], r["write_ms"])
        # where the frames were written: as forced, or (the default) on the writer thread
        assert r["written"].split(",")[0] == ("thread" if writes.get("background", True) else "observer")
        if writes.get("direct") is False:
            assert "direct" not in r["written"]
    text = capsys.readouterr().out
    assert "| configuration | steps/s | cost vs (a) | overhead over | ms/frame in observer | ms/frame write |" in text


def test_ab_explicit_quick_mode_times_this_checkout_against_a_copy_of_itself():
    import os
    import re
    import subprocess
    import sys

    # a script: its workers are spawned processes that import it as __main__
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "ab_explicit.py"), "--quick"],
                          env=dict(os.environ), capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "| integrator | springs | old (ms/step) | new (ms/step) | new/old (paired range) |" in done.stdout
    rows = [line for line in done.stdout.splitlines() if line.startswith("| co2 |")]
    assert len(rows) == 1
    cells = [c.strip() for c in rows[0].strip("|").split("|")]
    assert cells[1] == "144"  # the 3³ lattice's springs, in both workers
    old, new = float(cells[2]), float(cells[3])
    ratio, low, high = map(float, re.fullmatch(r"([\d.]+) \(([\d.]+)–([\d.]+)\)", cells[4]).groups())
    assert finite_positive(old, new, ratio, low) and low <= high
    assert abs(ratio - new / old) <= 0.015 * ratio  # the table's times are rounded to 3 digits (±0.5 % each)
    # two repeats: the ratio of the medians (means of two) lies between the paired ratios
    assert low - 0.005 <= ratio <= high + 0.005


def test_ab_explicit_builds_conducting_nets_for_the_sweeps_a_b():
    """--conduction-every k: the nets A/B'd conduct heat in cycles of k steps (this checkout's
    side; the quick mode above runs both sides adiabatic)."""
    import thermonet as tn

    sim = load("ab_explicit").simulation(tn, 3, "co2", 2)
    assert sim.conduction_cycle.k == 2 and sim.system.heat.conduction
    assert float(sim.diagnostics.entropy_produced[-1]) > 0.0


def test_explicit_throughput_quick_mode_times_both_kernels_and_the_numpy_step(capsys):
    rows = load("explicit_throughput").main(["--quick"])
    assert len(rows) == 1
    r = rows[0]
    assert (r["springs"], r["nodes"]) == (882, 343)  # the 7³-cell lattice closest to 1e3 springs
    assert finite_positive(r["serial"], r["parallel"], r["numpy"], r["ratio"], r["achieved_gbs"])
    assert r["default"] == "serial"  # below 16 384 springs
    assert math.isclose(r["ratio"], r["serial"] / r["numpy"])
    assert r["agreement"] < 1e-13  # the same CO2 step as the kernel's, up to round-off
    # the compulsory traffic of one step (docs: ≈ 118–125 B per spring-step) and the arrays held
    assert 100 < r["bytes_per_spring_step"] < 150 and 100 < r["memory_per_spring"] < 300
    text = capsys.readouterr().out
    assert "| springs | nodes | thermonet 1 thread (M/s) | thermonet parallel (M/s) | NumPy (M/s) | ratio |" in text
    assert "| 882 | 343 | **" in text and "STREAM triad" in text


def test_lammps_compare_quick_mode_runs_thermonets_side_without_lammps(tmp_path, capsys):
    absent = tmp_path / "lmp"  # LAMMPS is optional: its runs are skipped with the reason, thermonet's still run
    rows = load("lammps_compare").main(["--quick", "--passes", "--lmp", str(absent)])
    text = capsys.readouterr().out
    assert f"LAMMPS not found ({absent} does not exist): its runs are skipped." in text
    assert "lattice 6³ cells: 343 nodes, 882 bonds" in text and "(no LAMMPS: thermonet's runs only)" in text
    assert "| run | M bond-steps/s (median) | range over rounds | energy: max relative deviation |" in text
    by = {r["run"]: r for r in rows}
    assert sorted(by) == sorted(f"thermonet {kind}, {t}" for kind in ("mechanics-only", "thermal")
                                for t in ("1 thread", "2 threads"))
    for r in rows:
        assert len(r["rates"]) == 1 and finite_positive(*r["rates"])
        assert 0 < r["drift"] < 1e-2  # velocity Verlet at h = 2e-3 over 20 steps: bounded energy error
        assert float(r["percent"].rstrip(" %")) >= 0  # (a cache-resident net may pass the triad bound)
    for kind in ("mechanics-only", "thermal"):  # same dynamics on 1 and 2 threads (serial kernel at this size)
        assert math.isclose(by[f"thermonet {kind}, 1 thread"]["drift"], by[f"thermonet {kind}, 2 threads"]["drift"],
                            rel_tol=1e-9)
    # thermal coupling adds η and Φ (read, and Φ written) to the compulsory traffic
    assert int(by["thermonet thermal, 1 thread"]["bytes"]) > int(by["thermonet mechanics-only, 1 thread"]["bytes"])
    # ... and only those: 8 B of η and 16 of Φ per spring-step, all in the spring pass
    assert "| spring | η | 0.0 | 8.0 |" in text and "| spring | Φ (read, written) | 0.0 | 16.0 |" in text
    assert "| node | **pass total** | **68.0** | **68.0** |" in text
    assert "| both | **step total** | **101.3** | **125.3** |" in text  # 882 bonds, 343 nodes
    assert "| thermal | node | " in text and "| mechanics-only | spring | " in text  # --passes: each pass alone


def test_accuracy_cost_quick_mode_runs_the_chains_study_and_long_runs(tmp_path, capsys):
    module = load("accuracy_cost")
    results = module.main(["--quick", "--out", str(tmp_path)])
    assert [r["scene"] for r in results] == ["chain"]
    r = results[0]
    assert sorted(pathlib.Path(f).name for f in r["files"]) == ["cost.csv", "cost_position.png", "cost_summary.txt"]
    assert all(pathlib.Path(f).stat().st_size > 0 for f in r["files"])
    rows = r["study"].rows
    count = {s: sum(1 for x in rows if x["solver"] == s) for s in {x["solver"] for x in rows}}
    # every method at h = 0.04 · 2⁻ⁱ, i = 0…3; DOP853 at rtol 1e-3 … 1e-13, RK45 at 1e-3 … 1e-9
    assert count == {**{m: 4 for m in module.METHODS}, "scipy-DOP853": 11, "scipy-RK45": 7}
    assert all(x["status"] == "ok" and finite_positive(x["time"], x["position"]) for x in rows)
    co2 = [x["position"] for x in sorted((x for x in rows if x["solver"] == "co2"), key=lambda x: -x["h"])]
    assert all(a > b for a, b in zip(co2, co2[1:]))
    assert 1.8 < math.log2(co2[-2] / co2[-1]) < 2.2  # second order
    loosest = r["accuracy"][0]  # 1e-2: reached by thermonet and by DOP853, and both interpolated
    assert loosest["accuracy"] == 1e-2 and loosest["thermonet"]["position"] <= 1e-2
    assert loosest["dop853"]["position"] <= 1e-2
    assert finite_positive(loosest["thermonet_interpolated"], loosest["dop853_interpolated"])
    long = {(name, h): (err, wall, status) for name, h, err, wall, status in r["long_thermonet"]}
    assert all(status == "ok" and finite_positive(err, wall) for err, wall, status in long.values())
    # the energy error of a second-order symplectic method over t = 20: ∝ h²
    assert 3.5 < long[("co2", 0.01)][0] / long[("co2", 0.005)][0] < 4.5
    dop = [err for _, err, _, status in r["long_dop853"] if status == "ok"]
    assert len(dop) == 3 and dop[0] > dop[1] > dop[2] > 0  # tighter tolerances, smaller energy error
    text = capsys.readouterr().out
    assert "### chain: error in positions at t = 1" in text and "### chain: long run to t = 20" in text
    assert "| accuracy | cheapest thermonet run | cheapest compiled DOP853 | DOP853 / thermonet " in text


def test_evaluations_to_accuracy_quick_mode_measures_orders_and_evaluations(capsys):
    module = load("evaluations_to_accuracy")
    result = module.main(["--quick"])
    names = module.QUICK["methods"].split(",")
    assert list(result["orders"]) == names and list(result["reach"]) == ["chain"]
    for name, (declared, local, fit) in result["orders"].items():
        assert declared == module.method(name).order
        assert abs(fit - declared) < 0.25, (name, fit)  # each table (registered or typed here) has its order
    for name in names:
        evals = module.method(name).force_evaluations
        rows = result["sweeps"]["chain"][name]
        assert len(rows) >= 4 and all(e == steps * evals <= 2000 for steps, e, _ in rows)
        assert all(a[0] < b[0] for a, b in zip(rows, rows[1:]))
        assert all(math.isfinite(err) and err > 0 for *_, err in rows)
        reach = [v for v in result["reach"]["chain"][name] if v is not None]
        assert reach, name  # 1e-2 at least
        # tighter accuracies take more evaluations, within the sweep's range
        assert all(rows[0][1] <= a <= b <= rows[-1][1] for a, b in zip(reach, reach[1:] + reach[-1:]))
    text = capsys.readouterr().out
    assert "### Measured orders (chain, t = 1" in text and "### chain: force evaluations to reach" in text
    assert "| method | order | evaluations per step | 1e-02 |" in text and "| method | CO4/· 1e-02 |" in text
    assert "| co4 | 1.00 |" in text  # CO4 against itself


def test_implicit_cost_quick_mode_runs_every_part(capsys):
    out = load("implicit_cost").main(["--quick"])
    assert list(out) == ["ratio", "crossover", "scaling", "chain", "study"]
    (row,) = out["ratio"]
    assert (row["net"], row["springs"]) == ("chain", 3) and finite_positive(row["co2"])
    assert sorted(row["ratios"]) == sorted((m, p) for m in ("ho4", "gtr-1/2", "em2") for p in ("compiled", "sparse"))
    assert finite_positive(*row["ratios"].values())
    cross = {(str(r["shape"]), r["method"]): r for r in out["crossover"]}
    assert sorted(cross) == sorted((s, m) for s in ("chain", "(1, 1, 1)") for m in ("gtr-1/2", "ho4"))
    for shape, nodes in (("chain", 3), ("(1, 1, 1)", 8)):  # GTR: x per node; HO4: x and a midpoint
        assert cross[(shape, "gtr-1/2")]["unknowns"] == 3 * nodes and cross[(shape, "ho4")]["unknowns"] == 6 * nodes
        assert all(finite_positive(cross[(shape, m)]["dense"], cross[(shape, m)]["sweeps"]) for m in ("gtr-1/2", "ho4"))
    scaling = out["scaling"]
    assert sorted((r["method"], r["solver"]) for r in scaling) == sorted(
        (m, s) for m in ("gtr-1/2", "ho4", "em2") for s in ("splu", "matfree", "gmres"))
    for r in scaling:
        s = r["summary"]
        assert r["springs"] == 54 and s["steps"] == 3 and s["iterations_mean"] > 0
        assert finite_positive(r["seconds"], r["co2_seconds"]) and all(math.isfinite(v) for v in r["split_ms"].values())
    iterations, errors = out["chain"]
    assert len(iterations) == 9 and all(0 < mean <= top <= 50 for _, _, mean, top in iterations)
    assert all(err is not None and err > 0 for _, _, err, _ in errors)
    # each method's order at its two smallest steps, against DOP853 at 1e-13 (t = 1)
    for method, order in {"gtr-0": 1, "gtr-1": 1, "co2": 2, "co4": 4, "co6": 6, "gtr-1/2": 2, "ho4": 4, "em2": 2}.items():
        (h0, e0), (h1, e1) = [(h, e) for m, h, e, _ in errors if m == method][-2:]
        assert abs(math.log(e0 / e1) / math.log(h0 / h1) - order) < 0.3, method
    study = out["study"]
    assert {r["solver"] for r in study.rows} == {"gtr-0", "gtr-1", "gtr-1/2", "co2", "ho4", "co4", "co6"}
    text = capsys.readouterr().out
    for head in ("| net | springs | CO2 µs/step | ho4 compiled |", "| lattice | springs | method | unknowns | dense |",
                 "| springs | method | solver | ms/step | × CO2 | Newton it./step |", "| method | h | error | wall s |",
                 "| accuracy | cheapest of the paper's five |"):
        assert head in text


def test_implicit_profile_quick_mode_times_the_drivers_kernels(capsys):
    import numba

    module = load("implicit_profile")
    threads = numba.get_num_threads()
    try:  # (the script sets the thread count of this process)
        out = module.main(["--quick"])
    finally:
        numba.set_num_threads(threads)
    assert (out["method"], out["springs"], out["steps"]) == ("gtr-1/2", 54, 4)
    assert finite_positive(out["co2_step"], out["step"], out["mean_step"])
    names = [name for name, _ in module.TIMED]
    calls = {name: per_step for name, per_step, _ in out["kernels"]}
    assert list(calls) == [n for n in names if n in calls]  # in the driver's order
    # one start, predictor and finish per step; at least one residual
    assert calls["start"] == calls["predictor"] == calls["finish"] == 1.0 and calls["residual"] >= 1.0
    assert all(math.isfinite(share) and share >= 0 for *_, share in out["kernels"])
    # the counted cycles split the measured step time: the shares add up to it (in CO2 steps)
    assert math.isclose(sum(share for *_, share in out["kernels"]), out["mean_step"] / out["co2_step"], rel_tol=1e-9)
    text = capsys.readouterr().out
    assert "gtr-1/2, lattice 2³ (54 springs), 1 thread(s), 4 steps" in text
    assert "| kernel | calls/step | CO2 steps per step |" in text


def test_em2_run_quick_mode_times_a_whole_run_from_rest(capsys):
    """benchmarks/em2_run.py --quick: the small steel part at 100×, every call timed, the ratio
    to CO2 over the run and by windows."""
    (row,) = load("em2_run").main(["--quick"])
    assert row["springs"] == 1954 and row["steps"] == 20 and len(row["call_s"]) == 4
    assert all(t > 0 for t in row["call_s"]) and row["co2_ms"] > 0 and row["ratio"] > 0
    assert row["factorizations"] >= 1 and 1.0 <= row["corrections"] <= 10.0
    text = capsys.readouterr().out
    assert "the whole run:" in text and "steps 1–5" in text
