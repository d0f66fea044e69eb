"""Explicit step cost of two versions of thermonet, interleaved: a change's speed against the
code before it, measured in the same period on the same machine.

    python benchmarks/ab_explicit.py --old /path/to/old/checkout [--cells 32,70]
                                     [--integrators co2] [--repeats 8] [--steps 100]
                                     [--diagnostics-every 10] [--conduction-every 1]
    python benchmarks/ab_explicit.py --quick   # this checkout against a copy of itself, a 3³ lattice

Each version runs in a worker process of its own (this checkout's ``thermonet``, and the old
checkout's copied to a temporary folder as ``thermonet_old``), driven in turn over a pipe, so the
runs alternate in time but never share a process: two versions in one process share Numba's
dispatcher type cache, which keys record arguments (named tuples) without their class, so the
version that calls second missed it at every call and paid a Python typing of every argument
(it made an unchanged kernel look 7–10 % slower). For each net (a 6-neighbour lattice of cells³
cells: 32 about 1e5 springs, 70 about 1e6; jitter 0.1, hencky, random temperatures 250–350, a
diagnostics row every ``--diagnostics-every`` steps) both simulations are built and warmed up
(kernels compiled or loaded), then timed alternately, ``--steps`` steps per call. Prints a
markdown table of the median time per step and the ratio new/old of medians, with the range of
the paired ratios: on a shared machine a range straddling 1 is noise. Set NUMBA_NUM_THREADS to
compare at a thread count. With ``--conduction-every k`` the nets conduct heat (g = 1, a cycle
of k steps): the conduction sweeps' speed against the code before.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import shutil
import sys
import tempfile
import time

import numpy as np


ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def load_old(checkout: str):
    """(the old checkout's package imported as ``thermonet_old`` from a temporary copy, the copy's
    folder)."""
    folder = tempfile.mkdtemp(prefix="thermonet-old-")
    shutil.copytree(os.path.join(checkout, "thermonet"), os.path.join(folder, "thermonet_old"),
                    ignore=shutil.ignore_patterns("__pycache__"))
    sys.path.insert(0, folder)
    import thermonet_old

    return thermonet_old, folder


def simulation(tn, cells: int, integrator: str, conduction_every: int = 0):
    net = tn.lattice((cells, cells, cells), neighbours=6, jitter=0.1, seed=1)
    rng = np.random.default_rng(1)
    # the stepping alone: run-time guards off where a version has them (effects_cost.py prices them)
    guards = dict(stability_guard="off", energy_tolerance=None) if "stability_guard" in getattr(
        tn.Simulation.__init__, "__code__").co_varnames else {}
    heat = dict(conduction=True, conduction_every=conduction_every, parameters={"g": 1.0}) if conduction_every else {}
    sim = tn.Simulation(net, temperatures=250 + 100 * rng.random(net.n_springs),
                        velocities=rng.normal(0, 0.01, (net.n_nodes, 3)), integrator=integrator, h=1e-3, **guards,
                        **heat)
    sim.run(steps=20, diagnostics_every=10)
    return sim


def worker(old_checkout, conn) -> None:
    """Serve ("build", cells, integrator, conduction_every) -> springs and ("run", steps, every) -> seconds until
    "stop", with the old checkout's package if ``old_checkout`` else this one's."""
    tn, folder = load_old(old_checkout) if old_checkout else (__import__("thermonet"), None)
    sim = None
    try:
        while True:
            msg = conn.recv()
            if msg[0] == "build":
                sim = simulation(tn, *msg[1:])
                conn.send(sim.net.n_springs)
            elif msg[0] == "run":
                t = time.perf_counter()
                sim.run(steps=msg[1], diagnostics_every=msg[2])
                conn.send(time.perf_counter() - t)
            else:
                return
    finally:
        if folder:  # the copy (and the kernels Numba cached in it)
            shutil.rmtree(folder, ignore_errors=True)


def main(argv=None) -> list[dict]:
    """Run the benchmark (``argv``: its command line); returns its rows as dicts (integrator,
    springs, old and new seconds per step (medians), new/old and the paired ratios' range).
    Call it from a script (``python benchmarks/ab_explicit.py``): the workers are spawned and
    import their code from this file as ``__main__``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", default=None, help="checkout of the code before the change (required but with --quick)")
    ap.add_argument("--cells", default="32,70", help="lattice cells per axis (32: ~1e5 springs, 70: ~1e6)")
    ap.add_argument("--integrators", default="co2")
    ap.add_argument("--repeats", type=int, default=8)
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--diagnostics-every", type=int, default=10,
                    help="diagnostics cadence of the timed runs (above --steps: one row per call)")
    ap.add_argument("--conduction-every", type=int, default=0,
                    help="conduct heat (g = 1) in cycles of this many steps (0: adiabatic)")
    ap.add_argument("--quick", action="store_true", help="a 3³ lattice, 10 steps, 2 repeats; without --old, this "
                    "checkout against a copy of itself (a smoke run)")
    args = ap.parse_args(argv)
    if args.quick:
        args.cells, args.steps, args.repeats, args.old = "3", 10, 2, args.old or ROOT
    if args.old is None:
        ap.error("--old is required (the checkout of the code before the change)")
    ctx = mp.get_context("spawn")
    pipes = {}
    procs = []
    for which, checkout in (("old", os.path.abspath(args.old)), ("new", None)):
        parent, child = ctx.Pipe()
        proc = ctx.Process(target=worker, args=(checkout, child), daemon=True)
        proc.start()
        child.close()  # so that a worker's death ends its pipe here (EOFError) rather than hanging
        pipes[which] = parent
        procs.append(proc)
    print(f"threads: {os.environ.get('NUMBA_NUM_THREADS', 'all')}; load average at start: {os.getloadavg()[0]:.2f}")
    print("| integrator | springs | old (ms/step) | new (ms/step) | new/old (paired range) |")
    print("|---|---|---|---|---|")
    rows = []
    try:
        for integrator in args.integrators.split(","):
            for cells in (int(c) for c in args.cells.split(",")):
                for pipe in pipes.values():
                    pipe.send(("build", cells, integrator, args.conduction_every))
                springs = [pipe.recv() for pipe in pipes.values()][-1]
                times: dict[str, list] = {"old": [], "new": []}
                for r in range(args.repeats):
                    for which in (("old", "new") if r % 2 == 0 else ("new", "old")):
                        pipes[which].send(("run", args.steps, args.diagnostics_every))
                        times[which].append(pipes[which].recv() / args.steps)
                o, n = np.array(times["old"]), np.array(times["new"])
                paired = n / o
                rows.append({"integrator": integrator, "springs": springs, "old": float(np.median(o)),
                             "new": float(np.median(n)), "ratio": float(np.median(n) / np.median(o)),
                             "paired": (float(paired.min()), float(paired.max()))})
                print(f"| {integrator} | {springs} | {np.median(o) * 1e3:.3g} | {np.median(n) * 1e3:.3g} | "
                      f"{np.median(n) / np.median(o):.3f} ({paired.min():.2f}–{paired.max():.2f}) |", flush=True)
    finally:
        for pipe in pipes.values():
            try:
                pipe.send(("stop",))
            except OSError:  # that worker died (its error is on stderr)
                pass
        for proc in procs:
            proc.join(timeout=10)
    print(f"load average at end: {os.getloadavg()[0]:.2f}")
    return rows


if __name__ == "__main__":
    main()
