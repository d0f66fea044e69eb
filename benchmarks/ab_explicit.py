"""Explicit step cost of two versions of thermonet in one process, interleaved: a change's speed
against the code before it, measured in the same period on the same machine.

    python benchmarks/ab_explicit.py --old /path/to/old/checkout [--cells 32,70]
                                     [--integrators co2] [--repeats 8] [--steps 100]

The old checkout's ``thermonet`` package is copied to a temporary folder as ``thermonet_old``
(its imports are relative) and imported beside this checkout's. For each net (a 6-neighbour
lattice of cells³ cells: 32 about 1e5 springs, 70 about 1e6; jitter 0.1, hencky, random
temperatures 250–350, a diagnostics row every ``--diagnostics-every`` steps, default 10) both simulations are built and warmed
up (kernels compiled or loaded), then timed alternately, ``--steps`` steps per call. Prints a
markdown table of the median time per step and the ratio new/old of medians, with the range of
the paired ratios: on a shared machine a range straddling 1 is noise. Each version runs as two
simulations, one built before and one after the other version's (the order of allocation alone
moved a version's time by 8 % at 1e5 springs). Set NUMBA_NUM_THREADS to
compare at a thread count.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time

import numpy as np


def load_old(checkout: str):
    """The old checkout's package, imported as ``thermonet_old`` from a temporary copy."""
    folder = tempfile.mkdtemp(prefix="thermonet-old-")
    shutil.copytree(os.path.join(checkout, "thermonet"), os.path.join(folder, "thermonet_old"),
                    ignore=shutil.ignore_patterns("__pycache__"))
    sys.path.insert(0, folder)
    import thermonet_old

    return thermonet_old


def simulation(tn, cells: int, integrator: str):
    net = tn.lattice((cells, cells, cells), neighbours=6, jitter=0.1, seed=1)
    rng = np.random.default_rng(1)
    # the stepping alone: run-time guards off where a version has them (effects_cost.py prices them)
    guards = dict(stability_guard="off", energy_tolerance=None) if "stability_guard" in getattr(
        tn.Simulation.__init__, "__code__").co_varnames else {}
    sim = tn.Simulation(net, temperatures=250 + 100 * rng.random(net.n_springs),
                        velocities=rng.normal(0, 0.01, (net.n_nodes, 3)), integrator=integrator, h=1e-3, **guards)
    sim.run(steps=20, diagnostics_every=10)
    return sim


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", required=True, help="checkout of the code before the change")
    ap.add_argument("--cells", default="32,70", help="lattice cells per axis (32: ~1e5 springs, 70: ~1e6)")
    ap.add_argument("--integrators", default="co2")
    ap.add_argument("--repeats", type=int, default=8)
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--diagnostics-every", type=int, default=10,
                    help="diagnostics cadence of the timed runs (above --steps: one row per call)")
    args = ap.parse_args(argv)
    import thermonet as new

    old = load_old(args.old)
    print(f"threads: {os.environ.get('NUMBA_NUM_THREADS', 'all')}; load average at start: {os.getloadavg()[0]:.2f}")
    print("| integrator | springs | old (ms/step) | new (ms/step) | new/old (paired range) |")
    print("|---|---|---|---|---|")
    for integrator in args.integrators.split(","):
        for cells in (int(c) for c in args.cells.split(",")):
            # two of each, built in the orders old-new and new-old: which of two simulations is
            # built second measurably changes its speed (memory placement: 8 % at 1e5 springs)
            sims = [("old", simulation(old, cells, integrator)), ("new", simulation(new, cells, integrator)),
                    ("new", simulation(new, cells, integrator)), ("old", simulation(old, cells, integrator))]
            times: dict[str, list] = {"old": [], "new": []}
            for r in range(args.repeats):
                for which, sim in (sims if r % 2 == 0 else sims[::-1]):
                    t = time.perf_counter()
                    sim.run(steps=args.steps, diagnostics_every=args.diagnostics_every)
                    times[which].append((time.perf_counter() - t) / args.steps)
            o, n = np.array(times["old"]), np.array(times["new"])
            paired = n / o
            springs = sims[0][1].net.n_springs
            sims.clear()
            print(f"| {integrator} | {springs} | {np.median(o) * 1e3:.2f} | {np.median(n) * 1e3:.2f} | "
                  f"{np.median(n) / np.median(o):.3f} ({paired.min():.2f}–{paired.max():.2f}) |", flush=True)
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
