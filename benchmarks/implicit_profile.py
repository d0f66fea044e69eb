"""Where an implicit step's time goes on the compiled Newton path: per kernel of the driver
(start, predictor, residual, Jacobi finishing step, linearization, linear solve, damping,
finish), its calls per step and its time in CO2 steps of the same net.

The driver (``implicit/core/compiled_newton.py``) runs whole steps in one compiled call, so Python's
profilers cannot see into it. This script compiles a copy of the driver's template with the
CPU's cycle counter read around each kernel call (LLVM's ``readcyclecounter``), runs it on the
benchmark lattice of ``implicit_cost.py`` interleaved with CO2 (``--rounds`` rounds of a few
steps each), and splits the measured step time by the counted cycles. The copy is made by text
substitution of the template's source: a call the script does not find stops it with an error
naming the line (the template changed; update ``TIMED`` below).

    python benchmarks/implicit_profile.py --method ho4 --cells 32 --threads 1 --rounds 40
    python benchmarks/implicit_profile.py --method em2 --cells 32 --threads 2 --rounds 40
    python benchmarks/implicit_profile.py --method em2 --generic-quotient   # hencky without its energy_quotient
    python benchmarks/implicit_profile.py --quick   # gtr-1/2 (unless --method) on 2³ cells, 2 rounds of 2 steps

``--generic-quotient`` runs "hencky" without its closed-form ``energy_quotient``: EM2 then takes
the generic discrete gradient (implicit/em2/gradient.py), as for a user's model without one.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import os
import statistics
import sys
import textwrap
import time

import numba
import numpy as np
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # implicit_cost, beside this file

import thermonet as tn  # noqa: E402
import thermonet.implicit.core.compiled_newton as nc  # noqa: E402
from implicit_cost import lattice_simulation  # noqa: E402
from thermonet.implicit.core.schemes import OPTIONS  # noqa: E402
from thermonet.kernels.specialize import specialize  # noqa: E402

#: (name, the call's source line in the driver template, or its first line for a call that spans
#: several); each is timed where it stands
TIMED = [
    ("start", "status, bad = scheme_start(step, topo, spring, node, work[0], coef, u)"),
    ("predictor", "scheme_predict(step, topo, spring, node, work, extra, u)"),
    ("residual", "status, bad, rmax, scale = scheme_residual(step, topo, spring, node, work, extra, u, warm, res)"),
    ("local Jacobi step", "done, pending, pending_bad, lmax, lscale, change = scheme_local("),
    ("Jacobi step", "scheme_sweep(topo, node, work, h, du, R, r, True, np.bool_(True))"),
    ("linearization", "scheme_linearize(spring, work, extra, h)"),
    ("linear solve", "contraction = _solve_sweeps(topo, node, work, h, du, R, r,"),
    ("damping", "evaluated, trial_max, trial_scale = scheme_damp(step, topo, spring, node, work, extra, res,"),
    ("finish", "status, bad = scheme_finish(step, topo, spring, node, work, extra, u, phi, new)"),
]


@intrinsic
def cycles(typingctx):
    """The CPU's cycle counter."""
    def codegen(context, builder, signature, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.IntType(64), []),
                                            "llvm.readcyclecounter")
        return builder.call(fn, [])
    return types.int64(), codegen


def timed_template():
    """The driver template with each TIMED call bracketed by cycle counts into ``prof`` (2 ×
    len(TIMED),: cycles, then calls)."""
    lines = textwrap.dedent(inspect.getsource(nc._newton_steps)).split("\n")
    head = "def _newton_steps(state, records, extra, linear, control, out):"
    if lines[0] != head:
        raise SystemExit(f"the driver template's signature changed: {lines[0]!r}")
    lines[0] = "def _newton_steps(state, records, extra, linear, control, out, prof):"
    n = len(TIMED)
    for slot, (name, call) in enumerate(TIMED):
        at = [i for i, ln in enumerate(lines) if ln.strip() == call or (ln.strip().startswith(call) and call[-1] in ",(")]
        if len(at) != 1:
            raise SystemExit(f"{name}: the driver template has {len(at)} lines {call!r} (expected 1)")
        i = at[0]
        indent = lines[i][:len(lines[i]) - len(lines[i].lstrip())]
        end = i
        depth = lines[i].count("(") - lines[i].count(")")
        while depth > 0:  # a call over several lines
            end += 1
            depth += lines[end].count("(") - lines[end].count(")")
        lines[end + 1:end + 1] = [f"{indent}prof[{slot}] += cycles() - _t0", f"{indent}prof[{n + slot}] += 1"]
        lines.insert(i, f"{indent}_t0 = cycles()")
    ns = dict(vars(nc), cycles=cycles)
    exec(compile("\n".join(lines), "<timed driver>", "exec"), ns)
    return ns["_newton_steps"]


def main(argv=None) -> dict:
    """Run the benchmark (``argv``: its command line); returns {method, springs, steps, co2_step and
    step (median seconds per step), kernels: [(name, calls per step, CO2 steps per step)] of the
    kernels called}."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--method", default=None, help="implicit scheme (default ho4; --quick: gtr-1/2)")
    ap.add_argument("--cells", type=int, default=32, help="lattice of cells³ (32: 104 544 springs)")
    ap.add_argument("--threads", type=int, default=1, help="1: serial kernels; more: threaded ones")
    ap.add_argument("--rounds", type=int, default=40, help="interleaved rounds (the lattice heats up as it runs)")
    ap.add_argument("--steps", type=int, default=4, help="implicit steps per round")
    ap.add_argument("--generic-quotient", action="store_true",
                    help="hencky without its energy_quotient (EM2's generic discrete gradient)")
    ap.add_argument("--quick", action="store_true", help="gtr-1/2 (the smallest driver to compile) unless --method, "
                    "2³ cells, one thread, 2 rounds of 2 steps (a smoke run)")
    args = ap.parse_args(argv)
    if args.quick:
        args.cells, args.threads, args.rounds, args.steps = 2, 1, 2, 2
    args.method = args.method or ("gtr-1/2" if args.quick else "ho4")
    numba.set_num_threads(args.threads)
    parallel = args.threads > 1
    model = tn.get_model("hencky")
    if args.generic_quotient:
        model = dataclasses.replace(model, name="hencky_generic", energy_quotient=None)
    sim = lattice_simulation(args.cells, args.method, 0.01, parallel=parallel, model=model, newton_path="compiled")
    co2 = lattice_simulation(args.cells, "co2", 0.01, parallel=parallel)
    for s in (sim, co2):
        s.run(steps=2, diagnostics_every=10**9)
    compiled = sim.stepper.compiled
    driver = compiled.driver
    names = ("SWEEPS", "_solve_sweeps")
    bound = {k: v for k, v in driver.py_func.__globals__.items() if k.startswith("scheme_") or k in names}
    options = {k: v for k, v in OPTIONS.items() if k != "cache"}  # (no source file to cache against)
    timed = specialize(timed_template(), "timed_" + driver.py_func.__qualname__.split("__", 1)[1], bound, **options)
    prof = np.zeros(2 * len(TIMED), dtype=np.int64)
    compiled.driver = lambda *a: timed(*a, prof)
    sim.run(steps=1, diagnostics_every=10**9)  # compile the timed copy
    prof[:] = 0
    co2_steps = max(1, 20 * args.steps)
    co2_times, times = [], []
    for _ in range(args.rounds):
        t = time.perf_counter()
        co2.run(steps=co2_steps, diagnostics_every=10**9)
        co2_times.append((time.perf_counter() - t) / co2_steps)
        t = time.perf_counter()
        sim.run(steps=args.steps, diagnostics_every=10**9)
        times.append((time.perf_counter() - t) / args.steps)
    co2_step = statistics.median(co2_times)
    steps = args.rounds * args.steps
    total = prof[:len(TIMED)].sum()
    print(f"{args.method}, lattice {args.cells}³ ({sim.net.n_springs} springs), {args.threads} thread(s), "
          f"{steps} steps: CO2 {1e6 * co2_step:.0f} µs/step, {args.method} {1e6 * statistics.median(times):.0f} "
          f"µs/step = {statistics.median(times) / co2_step:.1f} CO2 steps (median over rounds)\n")
    print("| kernel | calls/step | CO2 steps per step |")
    print("|---|---:|---:|")
    kernels = []
    for slot, (name, _) in enumerate(TIMED):
        calls = prof[len(TIMED) + slot]
        if calls:
            share = prof[slot] / total * sum(times) * args.steps / steps  # the step time, split by cycles
            kernels.append((name, calls / steps, share / co2_step))
            print(f"| {name} | {calls / steps:.2f} | {share / co2_step:.2f} |")
    return {"method": args.method, "springs": sim.net.n_springs, "steps": steps, "co2_step": co2_step,
            "step": statistics.median(times), "mean_step": statistics.mean(times), "kernels": kernels}


if __name__ == "__main__":
    main()
