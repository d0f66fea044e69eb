"""Accuracy per cost: thermonet's explicit splittings against SciPy's DOP853 and RK45 driving a
Numba-compiled right-hand side, on the study scenes "lattice" (jittered 8³, 1944 hencky springs)
and "chain" (the paper's §5.1).

    python benchmarks/accuracy_cost.py [--scenes lattice,chain] [--repeats 3] [--t-end 10]
                                       [--long-t 1000] [--out DIR] [--quick]

``--quick``: the chain alone (unless ``--scenes``), t_end 1, long runs to 20, 3 halvings, 1 repeat
(a smoke run).

Prints markdown tables:

1. per scene, for each position accuracy 1e-2 … 1e-8 at t = t_end (the paper's norm: root of
   the sum of squares over every component; against DOP853 at ``--reference-rtol`` on the NumPy
   right-hand side, checked against BM6 at h = dt/32): the cheapest thermonet run reaching it and
   the cheapest compiled DOP853 and RK45 runs, and the DOP853/thermonet ratio with both times
   interpolated to the accuracy as in (2) (the fastest thermonet method). Every run (thermonet at h = dt·2⁻ⁱ, SciPy over
   decades of rtol = atol) runs once untimed (warm-up; its errors), then ``--repeats`` rounds
   time each run once, interleaved, single-threaded; medians. The result is a
   :class:`thermonet.studies.CostStudy`, written (plot, CSV, summary) into ``--out``;
2. the 4th- and 6th-order methods at equal accuracy: the time each needs to reach the accuracy,
   interpolated log-log between the two runs that bracket it on its own curve (time against error
   over h = dt·2⁻ⁱ), and the ratios CO4/BM4 and CO6/BM6 in wall time and in force evaluations
   (force evaluations per step × steps, interpolated the same way);
3. long runs to ``--long-t``: the relative energy error max |E(t) − E(0)| / |E(0)| (200 samples)
   and the wall time of one run each, compiled DOP853 at several tolerances against thermonet's
   methods; for each DOP853 run, the thermonet run with the smallest energy error among those
   that took no longer, and the ratio of the energy errors.

Timings on a shared machine are noisy (other jobs change the cost of a force evaluation by
several times within minutes): hence the interleaved rounds, and the ratios in force
evaluations beside those in time. The load average is printed.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import thermonet as tn  # noqa: E402
from thermonet.studies import CostStudy, reference_solution  # noqa: E402
from thermonet.studies.convergence import time_steps  # noqa: E402
from thermonet.studies.ode import hamilton_rhs, solve_hamilton  # noqa: E402
from thermonet.studies.scenes import make_simulation  # noqa: E402
from thermonet.studies.snapshot import QUANTITIES, Snapshot  # noqa: E402
from thermonet.studies.tasks import check_steps  # noqa: E402

ACCURACIES = [10.0**-k for k in range(2, 9)]
METHODS = ["co2", "co4", "co6", "bm4", "bm6", "bm6a"]


def time_at_accuracy(rows, acc, key="time"):
    """Interpolated ``key`` (time or force evaluations) at which one method's curve (rows from
    coarse to fine) reaches error ``acc`` in positions: log-log between the bracketing runs.
    None if no run reaches it; if the coarsest run already does, its value (an upper bound)."""
    pts = [(r["position"], r[key]) for r in rows if math.isfinite(r["time"]) and math.isfinite(r["position"])]
    for i, (e, v) in enumerate(pts):
        if e <= acc:
            if i == 0 or pts[i - 1][0] <= e:
                return v
            e0, v0 = pts[i - 1]
            w = (math.log(acc) - math.log(e0)) / (math.log(e) - math.log(e0))
            return math.exp(math.log(v0) + w * (math.log(v) - math.log(v0)))
    return None


def fmt_time(t):
    if t is None:
        return "–"
    return f"{t * 1e3:.3g} ms" if t < 1 else f"{t:.3g} s"


def describe(r):
    if r is None:
        return "none"
    if r["solver"].startswith("scipy"):
        return f"{r['solver'][6:]} rtol {r['rtol']:.0e}: {fmt_time(r['time'])}"
    return f"{r['solver'].upper()} h {r['h']:g}: {fmt_time(r['time'])}"


def accuracy_tables(study):
    """Print the two tables of ``study``; returns the first's rows: per accuracy, the cheapest
    thermonet, DOP853 and RK45 runs (None where none reaches it) and the interpolated times."""
    curves = dict(study.curves())
    for label, rows in curves.items():
        for r in rows:
            evals = tn.get_integrator(label).force_evaluations if not label.startswith("scipy") else 1
            r["evals"] = float(r["work"]) * evals
    print(f"\n### {study.scene}: error in positions at t = {study.t_end:g}\n")
    print(f"reference: {study.reference.description}\n")
    print("| accuracy | cheapest thermonet run | cheapest compiled DOP853 | DOP853 / thermonet "
          "| cheapest compiled RK45 | RK45 / thermonet | DOP853 / thermonet, interpolated |")
    print("|---|---|---|---|---|---|---|")
    rows = []
    for acc in ACCURACIES:
        tn_best = study.cheapest(acc, scipy=False)
        dop = min((r for r in study.rows if r["solver"] == "scipy-DOP853" and r["position"] <= acc),
                  key=lambda r: r["time"], default=None)
        rk = min((r for r in study.rows if r["solver"] == "scipy-RK45" and r["position"] <= acc),
                 key=lambda r: r["time"], default=None)
        ratio = (lambda o: f"{o['time'] / tn_best['time']:.1f}×" if o and tn_best else "–")
        tn_interp = [t for t in (time_at_accuracy(curves[n], acc) for n in METHODS if n in curves) if t]
        dop_interp = time_at_accuracy(curves.get("scipy-DOP853", []), acc)
        interp = (f"{dop_interp / min(tn_interp):.1f}× ({fmt_time(dop_interp)} / {fmt_time(min(tn_interp))})"
                  if tn_interp and dop_interp else "–")
        rows.append({"accuracy": acc, "thermonet": tn_best, "dop853": dop, "rk45": rk,
                     "thermonet_interpolated": min(tn_interp) if tn_interp else None, "dop853_interpolated": dop_interp})
        print(f"| {acc:.0e} | {describe(tn_best)} | {describe(dop)} | {ratio(dop)} | {describe(rk)} | {ratio(rk)} "
              f"| {interp} |")
    print(f"\n{study.scene}: 4th- and 6th-order methods at equal accuracy (interpolated on each curve)\n")
    print("| accuracy | CO4 | BM4 | CO4/BM4 time | CO4/BM4 evaluations | CO6 | BM6 | CO6/BM6 time "
          "| CO6/BM6 evaluations | BM6A | CO6/BM6A time | CO6/BM6A evaluations |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for acc in ACCURACIES:
        cells = []
        for old, new in (("co4", "bm4"), ("co6", "bm6"), ("co6", "bm6a")):
            t_old, t_new = (time_at_accuracy(curves.get(n, []), acc) for n in (old, new))
            f_old, f_new = (time_at_accuracy(curves.get(n, []), acc, "evals") for n in (old, new))
            cells += ([fmt_time(t_old)] if new != "bm6a" else []) + [
                fmt_time(t_new), f"{t_old / t_new:.2f}" if t_old and t_new else "–",
                f"{f_old / f_new:.2f}" if f_old and f_new else "–"]
        print(f"| {acc:.0e} | " + " | ".join(cells) + " |")
    return rows


def energy_error_thermonet(scene, name, h, t_end, samples=200):
    steps = round(t_end / h)
    every = max(1, steps // samples)
    sim = make_simulation(scene, name, h, threads=1)
    start = time.perf_counter()
    try:
        sim.run(steps=steps, diagnostics_every=every)
    except tn.errors.ThermonetError as exc:  # e.g. past the stability limit
        return float("nan"), float("nan"), f"failed: {exc}"
    wall = time.perf_counter() - start
    E = sim.diagnostics.column("energy")
    return float(np.max(np.abs(E - E[0])) / abs(E[0])), wall, "ok"


def energy_error_scipy(scene, method, rtol, t_end, samples=200):
    from scipy.integrate import solve_ivp

    sim = make_simulation(scene, "co2", 1.0)
    rhs, y0 = hamilton_rhs(sim, compiled=True)
    solve_ivp(rhs, (0.0, 1e-2), y0, method=method, rtol=rtol, atol=rtol)  # warm-up (compiled RHS)
    t_eval = np.linspace(0.0, t_end, samples + 1)
    start = time.perf_counter()
    sol = solve_ivp(rhs, (0.0, t_end), y0, method=method, rtol=rtol, atol=rtol, t_eval=t_eval)
    wall = time.perf_counter() - start
    if not sol.success:
        return float("nan"), wall, sol.message
    E = np.array([rhs.net.energy(*rhs.unpack(y)[:2], rhs.eta) for y in sol.y.T])
    return float(np.max(np.abs(E - E[0])) / abs(E[0])), wall, "ok"


def long_run_table(scene, t_long, scipy_rtols, thermonet_runs):
    """Print the long-run tables; returns (thermonet rows (name, h, energy error, wall, status),
    DOP853 rows (rtol, energy error, wall, status))."""
    print(f"\n### {scene}: long run to t = {t_long:g}, relative energy error max|E(t) − E(0)|/|E(0)|\n")
    tn_rows = []
    for name, h in thermonet_runs:
        make_simulation(scene, name, h, threads=1).run(steps=10, diagnostics_every=10)  # JIT warm-up
        err, wall, status = energy_error_thermonet(scene, name, h, t_long)
        tn_rows.append((name, h, err, wall, status))
    print("| run | energy error | wall time |")
    print("|---|---|---|")
    for name, h, err, wall, status in tn_rows:
        print(f"| {name.upper()} h {h:g} | {err:.2e} | {fmt_time(wall) if status == 'ok' else status} |")
    sp_rows = []
    for rtol in scipy_rtols:
        err, wall, status = energy_error_scipy(scene, "DOP853", rtol, t_long)
        sp_rows.append((rtol, err, wall, status))
        print(f"| compiled DOP853 rtol {rtol:.0e} | {err:.2e} | {fmt_time(wall)} |")
    print("\n| compiled DOP853 run | its energy error, time | best thermonet run in no more time | its energy error, time | DOP853 / thermonet error |")
    print("|---|---|---|---|---|")
    for rtol, err, wall, status in sp_rows:
        ok = [r for r in tn_rows if r[4] == "ok" and r[3] <= wall]
        if not ok:
            print(f"| rtol {rtol:.0e} | {err:.2e}, {fmt_time(wall)} | none | – | – |")
            continue
        best = min(ok, key=lambda r: r[2])
        print(f"| rtol {rtol:.0e} | {err:.2e}, {fmt_time(wall)} | {best[0].upper()} h {best[1]:g} "
              f"| {best[2]:.2e}, {fmt_time(best[3])} | {err / best[2]:.3g}× |")
    return tn_rows, sp_rows


def interleaved_study(scene, t_end, dt, halvings, repeats, rtol, scipy, max_seconds=10.0):
    """A :class:`~thermonet.studies.CostStudy` whose timings are interleaved: every run once
    untimed (JIT warm-up, and its errors: deterministic), then ``repeats`` rounds that time each
    run once, in an order rotated every round; the median per run. Runs slower than
    ``max_seconds`` are timed in the first round only."""
    reference = reference_solution(scene, t_end, rtol, check=("bm6", dt / 32))
    configs = [("thermonet", name, h) for name in METHODS for h in time_steps(dt, halvings)]
    configs += [("scipy", method, tol) for method, tols in scipy.items() for tol in tols]

    def once(kind, name, value):
        if kind == "thermonet":
            steps = check_steps(t_end, value)
            sim = make_simulation(scene, name, value, threads=1)
            start = time.perf_counter()
            try:
                sim.run(steps=steps, diagnostics_every=steps)
            except tn.errors.ThermonetError as exc:
                return float("nan"), None, steps, f"failed: {exc}"
            wall = time.perf_counter() - start
            snap = Snapshot.of(sim)
            ok = all(np.isfinite(a).all() for a in snap.to_dict().values())
            return wall, snap if ok else None, steps, "ok" if ok else "non-finite state"
        res = solve_hamilton(make_simulation(scene, "co2", 1.0), t_end, name, value, value, compiled=True)
        return res.wall_time, res.snapshot, res.nfev, "ok"

    first = {}
    for c in configs:
        if c[0] == "scipy":  # compile (cached) and warm the compiled right-hand side
            solve_hamilton(make_simulation(scene, "co2", 1.0), min(t_end, 1e-2), c[1], c[2], c[2], compiled=True)
        else:
            make_simulation(scene, c[1], c[2], threads=1).run(steps=2, diagnostics_every=2)
        first[c] = once(*c)
    times = {c: [] for c in configs}
    for r in range(repeats):
        order = configs[r % len(configs):] + configs[:r % len(configs)]
        for c in order:
            if first[c][3] != "ok" or (r > 0 and first[c][0] > max_seconds):
                continue
            times[c].append(once(*c)[0])
    study = CostStudy(scene, t_end, reference, repeats=repeats,
                      runner=f"this process, one thread, {repeats} interleaved rounds", scipy_rhs="compiled")
    for c in configs:
        wall, snap, work, status = first[c]
        t = times[c] or [float("nan")]
        errors = snap.errors(reference.snapshot) if snap is not None else {q: float("nan") for q in QUANTITIES}
        study.rows.append({
            "solver": c[1] if c[0] == "thermonet" else f"scipy-{c[1]}",
            "h": c[2] if c[0] == "thermonet" else float("nan"),
            "rtol": c[2] if c[0] == "scipy" else float("nan"), "work": work,
            "time": statistics.median(t), "time_min": min(t), "time_max": max(t), "repeats": len(times[c]),
            "status": status, **errors})
    return study


def main(argv=None) -> list[dict]:
    """Run the benchmark (``argv``: its command line); returns per scene a dict: its cost study,
    the files written, the accuracy table's rows and the long runs' rows."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default=None, help="default: lattice,chain (--quick: chain)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--t-end", type=float, default=10.0)
    ap.add_argument("--long-t", type=float, default=1000.0)
    ap.add_argument("--dt", type=float, default=0.04)
    ap.add_argument("--halvings", type=int, default=6)
    ap.add_argument("--reference-rtol", type=float, default=3e-14)
    ap.add_argument("--out", default="thermonet-out/accuracy-cost")
    ap.add_argument("--quick", action="store_true", help="the chain (unless --scenes), t_end 1, long runs to 20, "
                    "3 halvings, 1 repeat (a smoke run)")
    args = ap.parse_args(argv)
    if args.quick:
        args.t_end, args.long_t, args.repeats, args.halvings = 1.0, 20.0, 1, 3
    args.scenes = args.scenes or ("chain" if args.quick else "lattice,chain")
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.2f}; single-threaded runs")
    scipy = {"DOP853": [10.0**-k for k in range(3, 14)], "RK45": [10.0**-k for k in range(3, 10)]}
    results = []
    for scene in args.scenes.split(","):
        study = interleaved_study(scene, args.t_end, args.dt, args.halvings, args.repeats, args.reference_rtol, scipy)
        files = study.write(os.path.join(args.out, scene), accuracies=ACCURACIES)
        table = accuracy_tables(study)
        print(f"\n(plot and CSV: {', '.join(files)})")
        runs = [("co2", 0.01), ("co2", 0.005), ("bm4", 0.02), ("bm4", 0.01), ("bm6", 0.04), ("bm6", 0.02),
                ("bm6", 0.01)]
        if scene == "chain":  # cheap enough to go down to DOP853's cost at tight tolerances
            runs += [("bm6", 0.005), ("bm6", 0.0025)]
        rtols = [1e-5, 1e-7, 1e-9] if scene == "chain" else [1e-5, 1e-7]
        long_thermonet, long_dop853 = long_run_table(scene, args.long_t, rtols, runs)
        results.append({"scene": scene, "study": study, "files": files, "accuracy": table,
                        "long_thermonet": long_thermonet, "long_dop853": long_dop853})
    print(f"\nload average at the end {os.getloadavg()[0]:.2f}")
    return results


if __name__ == "__main__":
    main()
