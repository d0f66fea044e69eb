"""EM2's whole run from rest against CO2, as a user runs it: the steel part of em2_paths.py
(heated through its base, pushed on its flange, with conduction) at h = ``--factor`` × CO2's
stable step, ``--steps`` steps in calls of ``--call`` steps, every call timed, the first
factorization and every copy of the kept factors onto their elimination tree included (only
the kernels' compilation is not: a throwaway run loads them first). CO2 at 0.9× its stable step
("auto" conduction, calls of 200 steps) runs in the same process between EM2's calls, so that
a drift of the machine hits both. Prints EM2's ms per step over the run and over windows of it,
CO2's ms per step (the median of its calls), and the ratio of their simulated time per wall time
(> 1: EM2 is the faster way through the run), and what the kept factorizations did.

    python benchmarks/em2_run.py --mesh-size 0.003 --factor 100 --steps 300 --threads 1
    python benchmarks/em2_run.py --mesh-size 0.0012 --factor 100 --steps 150 --threads 2
    python benchmarks/em2_run.py --quick      # the 1 954-spring part, 20 steps (the test's)

To compare two versions of thermonet, run it in turn from each checkout (``PYTHONPATH=<checkout>``)
several times: the whole-run times of one configuration scatter by 10–20 % between runs on a
shared 2-core machine.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
import warnings

import numba
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from em2_paths import CO2_FRACTION  # noqa: E402  (CO2's step: this fraction of its stable step)

#: CO2's steps per call (its "auto" conduction takes a cycle dividing it)
CO2_CALL = 200


def measure(size: float, factor: float, steps: int, call: int, threads: int, co2_every: int = 5) -> dict:
    """The run's figures (see the module docstring): EM2's seconds per call (``call_s``), CO2's
    ms per step, the ratio over the run, and the kept factorizations' counts."""
    import em2_paths as ep

    from thermonet.stability import stable_step

    stable = stable_step(ep.part_simulation(size, "co2", 1.0, threads=threads))["h_max"]
    co2 = ep.part_simulation(size, "co2", CO2_FRACTION * stable, threads=threads)
    co2.stability_guard.active = False  # (its allowance is large next to the calls timed here)
    co2.run(steps=CO2_CALL, diagnostics_every=CO2_CALL)
    h = factor * stable
    warm = ep.part_simulation(size, "em2", h, threads=threads)
    warm.run(steps=2, diagnostics_every=10**9)
    _load_tree_kernels(warm)
    del warm
    sim = ep.part_simulation(size, "em2", h, threads=threads)
    call_s, co2_ms = [], []
    for k in range(0, steps, call):
        t0 = time.perf_counter()
        sim.run(steps=min(call, steps - k), diagnostics_every=10**9)
        call_s.append(time.perf_counter() - t0)
        if (k // call) % co2_every == 0:
            t0 = time.perf_counter()
            co2.run(steps=CO2_CALL, diagnostics_every=CO2_CALL)
            co2_ms.append((time.perf_counter() - t0) / CO2_CALL * 1e3)
    summary = sim.stepper.summary()
    em2_ms = sum(call_s) / steps * 1e3
    co2_step = statistics.median(co2_ms)
    solver = sim.stepper.solver
    return dict(springs=sim.net.n_springs, threads=threads, factor=factor, h=h, steps=steps, call=call,
                call_s=call_s, em2_ms=em2_ms, co2_ms=co2_step,
                ratio=factor / CO2_FRACTION * co2_step / em2_ms,
                corrections=summary.get("iterations", 0) / max(1, steps),
                factorizations=summary.get("factorizations", 0),
                stale=summary.get("stale_refactorizations", 0), tree_solves=summary.get("tree_solves", 0),
                tree_copies=getattr(solver, "tree_copies", 0), tree_layouts=getattr(solver, "tree_layouts", 0))


def _load_tree_kernels(sim) -> None:
    """Compile (or load) the elimination-tree solve on the factors a run kept, so that the timed
    run pays its first copy's work but not Numba's."""
    from thermonet.solvers.tree_solve import tree_factors, tree_solve

    lu = getattr(sim.stepper.solver, "_lu", None)
    if lu is None:
        return
    tree, _ = tree_factors(lu, numba.get_num_threads())
    if tree is not None:
        tree_solve(tree, np.zeros(lu.shape[0]))


def windows(row: dict, count: int = 6) -> list[tuple[int, int, float]]:
    """(first step, last step, ratio to CO2) of ``count`` windows of whole calls over the run."""
    calls = row["call_s"]
    per = max(1, len(calls) // count)
    out = []
    for w in range(0, len(calls) - per + 1, per):
        first, last = w * row["call"] + 1, min((w + per) * row["call"], row["steps"])
        ms = sum(calls[w:w + per]) / (last - first + 1) * 1e3
        out.append((first, last, row["factor"] / CO2_FRACTION * row["co2_ms"] / ms))
    return out


def report(row: dict, out=print) -> None:
    out(f"steel part, {row['springs']:,} springs, {row['threads']} thread(s), EM2 at {row['factor']:g}× CO2's "
        f"stable step (h = {row['h']:.3g} s), {row['steps']} steps from rest in calls of {row['call']}:")
    out(f"  EM2 {row['em2_ms']:.2f} ms/step over the run ({row['corrections']:.2f} corrections a step, "
        f"{row['factorizations']} factorizations, {row['stale']} of them renewals; {row['tree_solves']} solves on "
        f"the elimination tree, {row['tree_copies']} copies onto it, {row['tree_layouts']} of them laid out anew); "
        f"CO2 {row['co2_ms']:.3f} ms/step")
    out(f"  EM2 ÷ CO2 through simulated time, the whole run: {row['ratio']:.2f}×; by windows: "
        + ", ".join(f"steps {a}–{b} {r:.2f}×" for a, b, r in windows(row)))


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mesh-size", nargs="+", type=float, default=[0.003], help="the part's mesh size(s), m")
    ap.add_argument("--factor", nargs="+", type=float, default=[100.0], help="EM2's step(s) in CO2 stable steps")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--call", type=int, default=10, help="EM2's steps per call")
    ap.add_argument("--threads", nargs="+", type=int, default=[1])
    ap.add_argument("--quick", action="store_true", help="the 1 954-spring part, 20 steps at 100×")
    args = ap.parse_args(argv)
    if args.quick:
        args.mesh_size, args.factor, args.steps, args.call, args.threads = [0.006], [100.0], 20, 5, [1]
    rows = []
    for size in args.mesh_size:
        for threads in args.threads:
            numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            for factor in args.factor:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    row = measure(size, factor, args.steps, args.call, threads)
                report(row)
                rows.append(row)
    print(f"load average at end: {os.getloadavg()[0]:.2f}")
    return rows


if __name__ == "__main__":
    main()
