"""Throughput of the explicit CO2 integrator: thermonet's fused kernel against a NumPy step.

    python benchmarks/explicit_throughput.py [--sizes 1e3,1e4,1e5,1e6] [--repeats 5] [--quick]

For 6-neighbour lattice nets (jitter 0.1, "hencky" springs, random temperatures 250–350 and small
random velocities) of about each requested number of springs, prints a markdown table:

- thermonet spring-steps per second (springs × steps / wall time) through ``Simulation.run``,
  on 1 thread (serial kernel) and on all threads (parallel kernel), after JIT warm-up; the
  median over repeats, each repeat long enough (``--seconds``) to make call overheads small;
- the same for a NumPy implementation of the same CO2 step (one force evaluation per step,
  vectorized per-spring arithmetic, ``np.bincount`` scatter, same node numbering), and the ratio
  of thermonet's rate with the engine's default kernel choice to it; before timing, both run a
  few steps from one state and their agreement is reported (round-off: ~1e-15);
- the bytes per spring-step the kernel moves and the fraction of the bandwidth bound reached:
  the bound is (STREAM triad bandwidth measured in this run) / (bytes per spring-step). Bytes
  are *compulsory traffic*: every array a pass reads counts its full size once per pass, every
  array it writes once more (Φ and p are read and written), writes without write-allocate, as
  STREAM counts; gathered reads (x of the other end, T/l of incident springs) count as if each
  element came from memory once per pass. This is what a perfect cache would move, so the
  fraction is a lower bound on the real fraction;
- bytes of memory per spring: every array the Simulation holds in its internal numbering
  (System, Layout, State, the stepper's scratch), divided by the number of springs.

On a shared machine rates are medians of interleaved repeats, and the load average is printed:
another CPU-bound job on one of two cores slows the parallel kernel by 2–4× (every pass waits for
its slowest thread) and small nets' parallel runs far more; compare runs only at low load.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import numpy as np

import numba
from numba import njit, prange

import thermonet as tn

H = 1e-3
NEIGHBOURS = 6


# ---------------------------------------------------------------------------------------------
# the NumPy step


class NumpyCO2:
    """CO2 (kick–drift–kick) for "hencky" springs in NumPy, one force evaluation per step.

    x, p: (n, 3); eta, phi, l0: (m,); edges: (m, 2); P: dict of (m,) or scalar parameters c,
    beta, C0, theta0; masses: (n,); anchored: (n,) bool. Arrays are copied; state is advanced
    in place in ``self``. Like the kernel, the force at the end of a step is kept for the first
    kick of the next one.
    """

    def __init__(self, x, p, phi, eta, l0, edges, P, masses, anchored):
        self.x, self.p, self.phi = x.copy(), p.copy(), phi.copy()
        self.eta, self.l0 = eta, l0
        self.a = np.ascontiguousarray(edges[:, 0], dtype=np.intp)
        self.b = np.ascontiguousarray(edges[:, 1], dtype=np.intp)
        self.c, self.beta, self.C0, self.theta0 = (P[k] for k in ("c", "beta", "C0", "theta0"))
        self.inv_mass = np.where(anchored, 0.0, 1.0 / masses)[:, None]
        self.free = ~anchored
        self.n = len(x)
        self.f, self.theta = self.forces(self.x)

    def forces(self, x):
        d = x[self.b]
        d -= x[self.a]
        l = np.sqrt(np.einsum("ij,ij->i", d, d))
        L = np.log(l / self.l0)
        theta = self.theta0 * np.exp((self.eta - self.beta * L) / self.C0)
        s = (self.c * L - self.beta * (theta - self.theta0)) / l
        s /= l
        d *= s[:, None]
        f = np.empty((self.n, 3))
        for k in range(3):
            f[:, k] = np.bincount(self.a, d[:, k], minlength=self.n)
            f[:, k] -= np.bincount(self.b, d[:, k], minlength=self.n)
        f *= self.free[:, None]
        return f, theta

    def run(self, n_steps: int, h: float):
        half = 0.5 * h
        for _ in range(n_steps):
            self.p += half * self.f
            self.phi += half * self.theta
            self.x += h * self.inv_mass * self.p
            self.f, self.theta = self.forces(self.x)
            self.p += half * self.f
            self.phi += half * self.theta


# ---------------------------------------------------------------------------------------------
# memory bandwidth


@njit(parallel=True)  # not cached: the tests load this script under a module name Numba's cache cannot re-import
def _triad(a, b, c, scalar):
    for i in prange(a.shape[0]):
        a[i] = b[i] + scalar * c[i]


def triad_bandwidth(n: int = 20_000_000, repeats: int = 10) -> float:
    """STREAM triad a = b + s c, bytes/s counted as STREAM does (24 per element: two reads, one
    write); the best of ``repeats``, as STREAM reports, on all threads or on one thread, whichever
    is higher (with another job on one core, the all-thread triad waits for its slow thread and
    understates the machine). The table uses the best over one such measurement before every size."""
    a, b, c = np.zeros(n), np.ones(n), np.full(n, 2.0)
    threads = numba.get_num_threads()
    best = np.inf
    try:
        for t in sorted({1, threads}):
            numba.set_num_threads(t)
            _triad(a, b, c, 3.0)
            for _ in range(repeats):
                t0 = time.perf_counter()
                _triad(a, b, c, 3.0)
                best = min(best, time.perf_counter() - t0)
    finally:
        numba.set_num_threads(threads)
    return 24.0 * n / best


# ---------------------------------------------------------------------------------------------
# the nets and what the kernel touches


def lattice_cells(target_springs: float) -> int:
    """k such that the k×k×k-cell 6-neighbour lattice (3 k (k+1)² springs) is closest to target."""
    k = max(1, int(round((target_springs / 3.0) ** (1.0 / 3.0))))
    return min(range(max(1, k - 2), k + 3), key=lambda j: abs(3 * j * (j + 1) ** 2 - target_springs))


def make_simulation(k: int, parallel: bool | None, threads: int | None, varied: bool) -> tn.Simulation:
    net = tn.lattice((k, k, k), neighbours=NEIGHBOURS, jitter=0.1, seed=1)
    rng = np.random.default_rng(2)
    m = net.n_springs
    params = dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0)
    if varied:
        params = {key: value * rng.uniform(0.9, 1.1, m) for key, value in params.items()}
    return tn.Simulation(net, model="hencky", parameters=params, temperatures=rng.uniform(250.0, 350.0, m),
                         velocities=rng.normal(0.0, 0.01, (net.n_nodes, 3)), integrator="co2", h=H,
                         parallel=parallel, threads=threads, stability_guard="off", energy_tolerance=None)


def kernel_traffic(sim) -> dict:
    """Compulsory bytes one CO2 step (one force evaluation: spring pass + node pass) moves, by
    pass and array: {(pass, array): bytes}. Each array a pass reads counts its full size once,
    an array it writes once more (Φ and p are read and written; T/l and the new positions only
    written by the pass that makes them); gathered arrays (x at the other end, T/l of incident
    springs) count once, as if a perfect cache served every repeat. With thermal coupling off,
    Φ and η are not there and count 0."""
    st = sim.stepper
    topo, springs, nodes, s_buf = st._topology, st._springs, st._nodes, st._scratch.s
    s = sim._state

    def nb(a):
        return 0 if a is None else a.nbytes

    x, p, phi, eta = s.positions, s.momenta, s.thermal_displacement, s.entropy
    return {
        ("spring", "edges (2 × uint32)"): topo.edges.nbytes,
        ("spring", "x (gathered)"): x.nbytes,
        ("spring", "η"): nb(eta),
        ("spring", "rest length"): springs.rest.nbytes,
        ("spring", "parameters"): springs.P.nbytes,
        ("spring", "T/l (written)"): s_buf.nbytes,
        ("spring", "Φ (read, written)"): 2 * nb(phi),
        ("node", "inc_ptr (int64)"): topo.inc_ptr.nbytes,
        ("node", "inc_spring (uint32)"): topo.inc_spring.nbytes,
        ("node", "inc_other (uint32)"): topo.inc_other.nbytes,
        ("node", "T/l (gathered)"): s_buf.nbytes,
        ("node", "x (own and gathered)"): x.nbytes,
        ("node", "p (read, written)"): 2 * p.nbytes,
        ("node", "new x (written)"): x.nbytes,
        ("node", "1/m"): nodes.inv_mass.nbytes,
        ("node", "anchor flag"): nodes.anchored.nbytes,
    }


def kernel_bytes_per_step(sim) -> int:
    """The sum of :func:`kernel_traffic`: compulsory bytes of one CO2 step."""
    return sum(kernel_traffic(sim).values())


def traffic_table(sims: dict) -> str:
    """A markdown table of :func:`kernel_traffic` per spring-step, one column per simulation
    (``sims``: label -> Simulation of one net), with the passes' subtotals and the total."""
    labels = list(sims)
    traffic = {label: kernel_traffic(sim) for label, sim in sims.items()}
    m = {label: sim.net.n_springs for label, sim in sims.items()}
    lines = ["| pass | array | " + " | ".join(f"{label} (B/spring-step)" for label in labels) + " |",
             "|---|---|" + "---:|" * len(labels)]
    for pass_ in ("spring", "node"):
        keys = [k for k in traffic[labels[0]] if k[0] == pass_]
        for key in keys:
            lines.append(f"| {pass_} | {key[1]} | "
                         + " | ".join(f"{traffic[label][key] / m[label]:.1f}" for label in labels) + " |")
        lines.append(f"| {pass_} | **pass total** | " + " | ".join(
            f"**{sum(v for k, v in traffic[label].items() if k[0] == pass_) / m[label]:.1f}**" for label in labels)
            + " |")
    lines.append("| both | **step total** | " + " | ".join(
        f"**{sum(traffic[label].values()) / m[label]:.1f}**" for label in labels) + " |")
    return "\n".join(lines)


def resident_bytes(sim) -> int:
    """Bytes of every array the Simulation holds in its internal numbering."""
    seen, total = set(), 0
    objs = [sim.system, sim.system.layout, sim._state, sim.stepper]
    for obj in objs:
        for value in vars(obj).values():
            arrays = value if isinstance(value, tuple) else (value,)
            for arr in arrays:
                if isinstance(arr, np.ndarray) and id(arr) not in seen:
                    base = arr if arr.base is None else arr.base
                    if id(base) in seen:
                        continue
                    seen.update((id(arr), id(base)))
                    total += base.nbytes if isinstance(base, np.ndarray) else arr.nbytes
    return total


# ---------------------------------------------------------------------------------------------
# timing


def steps_for(m: int, seconds: float, rate_guess: float) -> int:
    return max(3, int(seconds * rate_guess / m))


def time_rates(runs: dict, m: int, seconds: float, repeats: int) -> dict:
    """runs: name -> (callable(n_steps), rate guess). Calibrates the step count per run, then
    times interleaved repeats; returns name -> median spring-steps/s."""
    n_steps = {}
    for name, (run, guess) in runs.items():
        n = steps_for(m, 0.2 * seconds, guess)
        t = time.perf_counter()
        run(n)
        rate = m * n / (time.perf_counter() - t)
        n_steps[name] = steps_for(m, seconds, rate)
    rates = {name: [] for name in runs}
    for _ in range(repeats):
        for name, (run, _) in runs.items():
            n = n_steps[name]
            t = time.perf_counter()
            run(n)
            rates[name].append(m * n / (time.perf_counter() - t))
    return {name: float(np.median(r)) for name, r in rates.items()}


def numpy_step_for(sim) -> NumpyCO2:
    """The NumPy step on a copy of ``sim``'s current state, same (internal) numbering."""
    s, sy = sim._state, sim.system
    P = {name: sy.parameters[i] for i, name in enumerate(sim.model.parameters)}
    return NumpyCO2(s.positions, s.momenta, s.thermal_displacement, s.entropy, sy.rest_lengths, sy.layout.edges,
                    P, sy.masses, sy.anchored)


def check_agreement(sim, steps: int = 5) -> float:
    """Run thermonet and the NumPy step ``steps`` steps from one state; the larger of the max
    differences of positions and of momenta, each relative to that array's largest entry."""
    ref = numpy_step_for(sim)
    sim.run(steps=steps, diagnostics_every=10**12)
    ref.run(steps, H)
    s = sim._state
    return max(float(np.abs(ref.x - s.positions).max() / np.abs(ref.x).max()),
               float(np.abs(ref.p - s.momenta).max() / np.abs(ref.p).max()))


def measure_size(target: float, args, threads: int) -> dict:
    """One row of the table. One Simulation (its default kernel choice recorded) runs with a
    serial and a parallel stepper in turn; the NumPy step runs on a copy of its state."""
    sim = make_simulation(lattice_cells(target), None, threads, args.varied)
    default_kind = "parallel" if sim.parallel else "serial"
    steppers = {kind: sim.integrator.make_stepper(sim.system, parallel=(kind == "parallel"))
                for kind in ("serial", "parallel")}
    m, n = sim.net.n_springs, sim.net.n_nodes

    def thermonet_run(kind):
        def run(steps):
            sim.stepper = steppers[kind]
            numba.set_num_threads(1 if kind == "serial" else threads)
            sim.run(steps=steps, diagnostics_every=10**12)
        return run

    for kind in steppers:
        thermonet_run(kind)(2)  # JIT (or load from the disk cache) and touch memory
    agreement = check_agreement(sim)
    runs = {"serial": (thermonet_run("serial"), 5e7), "parallel": (thermonet_run("parallel"), 1e8)}
    if not args.no_numpy:
        ref = numpy_step_for(sim)
        runs["numpy"] = (lambda steps: ref.run(steps, H), 5e6)
    rates = time_rates(runs, m, args.seconds, args.repeats)
    sim.stepper = steppers[default_kind]
    numba.set_num_threads(threads)
    bytes_step = kernel_bytes_per_step(sim)
    best = rates[default_kind]
    numpy_rate = rates.get("numpy", float("nan"))
    return dict(
        springs=m, nodes=n, serial=rates["serial"], parallel=rates["parallel"], default=default_kind,
        numpy=numpy_rate, ratio=best / numpy_rate, bytes_per_spring_step=bytes_step / m,
        achieved_gbs=best * bytes_step / m / 1e9,
        memory_per_spring=resident_bytes(sim) / m, agreement=agreement,
    )


def cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def available_memory() -> float:
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    return float("inf")


def main(argv=None) -> list:
    """Run the benchmark (``argv``: its command line); returns its rows (dicts; a string for a
    size skipped for memory)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1e3,1e4,1e5,1e6",
                    help="comma-separated target numbers of springs (default 1e3,1e4,1e5,1e6; add 1e7 if memory allows)")
    ap.add_argument("--repeats", type=int, default=5, help="timed repeats per size (median reported)")
    ap.add_argument("--seconds", type=float, default=1.0, help="wall time per timed repeat")
    ap.add_argument("--threads", type=int, default=None, help="threads of the parallel kernel (default: all)")
    ap.add_argument("--varied", action="store_true", help="per-spring parameters (±10 %%) instead of shared ones")
    ap.add_argument("--no-numpy", action="store_true", help="skip the NumPy step")
    ap.add_argument("--quick", action="store_true", help="size 1e3, one short repeat (a smoke run)")
    args = ap.parse_args(argv)
    if args.quick:
        args.sizes, args.repeats, args.seconds = "1e3", 1, 0.01
    threads = args.threads or numba.config.NUMBA_NUM_THREADS
    triad_elements = 1_000_000 if args.quick else 20_000_000
    bandwidth = triad_bandwidth(triad_elements)

    load_start = os.getloadavg()[0]
    rows = []
    for token in args.sizes.split(","):
        target = float(token)
        need = 700.0 * target  # net, layout construction, engine, the NumPy step's temporaries
        if need > 0.8 * available_memory():
            rows.append(f"| ~{target:.0e} | skipped: needs about {need / 2**30:.0f} GiB | | | | | | | | | |")
            continue
        bandwidth = max(bandwidth, triad_bandwidth(triad_elements))
        rows.append(measure_size(target, args, threads))
        r = rows[-1]
        print(f"{r['springs']:,} springs: {r['serial'] / 1e6:.1f} / {r['parallel'] / 1e6:.1f} M/s (1 thread / "
              f"parallel), NumPy {r['numpy'] / 1e6:.2f} M/s", file=sys.stderr, flush=True)

    print(f"# CO2 throughput, hencky springs, {NEIGHBOURS}-neighbour jittered lattices"
          f"{', per-spring parameters' if args.varied else ', shared parameters'}")
    print(f"machine: {cpu_name()}, {os.cpu_count()} CPUs, {available_memory() / 2**30:.0f} GiB available; "
          f"numba {numba.__version__} ({numba.threading_layer()}), numpy {np.__version__}; "
          f"parallel kernel on {threads} threads")
    print(f"STREAM triad (24 B/element, best over the run): {bandwidth / 1e9:.1f} GB/s; "
          f"load average (1 min) at start {load_start:.2f}, at end {os.getloadavg()[0]:.2f}\n")
    print("| springs | nodes | thermonet 1 thread (M/s) | thermonet parallel (M/s) | NumPy (M/s) | ratio | "
          "bytes/spring-step | GB/s moved | % of bandwidth bound | bytes/spring | agree |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        if isinstance(r, str):
            print(r)
            continue
        mark = lambda kind: "**" if r["default"] == kind else ""  # noqa: E731
        best = r[r["default"]]
        print(f"| {r['springs']:,} | {r['nodes']:,} | {mark('serial')}{r['serial'] / 1e6:.1f}{mark('serial')} | "
              f"{mark('parallel')}{r['parallel'] / 1e6:.1f}{mark('parallel')} | {r['numpy'] / 1e6:.2f} | "
              f"{r['ratio']:.1f}× | {r['bytes_per_spring_step']:.0f} | {r['achieved_gbs']:.1f} | "
              f"{100 * best * r['bytes_per_spring_step'] / bandwidth:.0f} % | {r['memory_per_spring']:.0f} | "
              f"{r['agreement']:.0e} |")
    print("\nbold: the kernel the Simulation picks by default at that size (used for ratio, GB/s and %); "
          "agree: largest relative difference of x and p between thermonet and NumPy after 5 steps from one "
          "state. Other jobs on the machine slow the parallel kernel most (each pass waits for its slowest "
          "thread): compare the load averages.")
    return rows


if __name__ == "__main__":
    main()
