"""Strong scaling of the explicit step over MPI processes, and the model for more of them.

    python benchmarks/mpi_scaling.py [--springs 1e6] [--steps 200] [--repeats 3] [--quick]

Runs the same net (a 6-neighbour lattice of about ``--springs`` springs, jitter 0.1, "hencky"
springs, random temperatures and velocities; ``--quick``: the built-in default scene, fifty
steps) in one process on one thread, in one process on two threads (the threaded
kernel's own scaling, the reference) and over two MPI processes of one thread each
(``mpiexec -n 2``), and prints a markdown table: wall time per step (the median of the repeats,
after a warm-up call that loads or compiles the kernels), speed-up over one thread (the median of
the rounds' ratios), the halo
each process sends per step (messages, bytes), the peak resident memory of each process, and
whether the two-process state and last diagnostics row are bit for bit the one-process ones.
The three runs are built once and kept waiting, and their repeats interleaved: in each round every
run times one repeat in turn while the others wait idle, so that a machine whose speed drifts
(a shared host, a virtual machine) slows all three alike. Each repeat times a call of ``--steps``
steps with one diagnostics row (at its end), then one of as
many steps with a row every fifth of them: s/step is the first's time per step; their difference
is what each further diagnostics stop costs (the row, and the call cut there), and the first's
time less one stop is a step alone. Memory per process: the
arrays the stepping works on (a process's share, or the whole net in one process), the resident
memory after the run and its peak (which includes compiling, where a kernel was compiled).

The model for P processes on a cluster: t_P = t_1 / P + stages × (messages × latency + bytes /
bandwidth), from the measured halo of the two-process run scaled by the surface of a cube's
share ((1/P)^(2/3) of the whole net's cross-section per neighbour, six neighbours in 3D), for a
network of ``--latency`` seconds (default 2 µs) at 10 Gb/s and 100 Gb/s.

The workers are this script with ``--worker``, started by ``mpiexec``, each told by a line on its
standard input to time a repeat or to finish (over processes rank 0 reads it and passes it on; the
others wait for it asleep, not polling a core); the machine's load average is printed with the
table (on a shared machine ratios measured side by side are what counts).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_SCENE = os.path.join(ROOT, "scenes", "default.toml")


def make_simulation(springs: float, quick: bool, threads: int):
    """The benchmark's Simulation (in every process of a run alike)."""
    import thermonet as tn

    if quick:
        from thermonet.scenes import load_scene

        sim = load_scene(DEFAULT_SCENE).build().simulation
        sim.threads = threads
        return sim
    k = max(1, int(round((springs / 3.0) ** (1.0 / 3.0))))
    net = tn.lattice((k, k, k), jitter=0.1, seed=1)
    rng = np.random.default_rng(2)
    return tn.Simulation(net, model="hencky", parameters=dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0),
                         temperatures=rng.uniform(250.0, 350.0, net.n_springs),
                         velocities=rng.normal(0.0, 0.01, (net.n_nodes, 3)), h=1e-3, threads=threads,
                         parallel=threads > 1 or net.n_springs >= 16384, stability_guard="off",
                         energy_tolerance=None)


def _command(comm) -> str:
    """The next line of rank 0's standard input ("repeat" or "finish"), on every process; the
    processes other than rank 0 wait for it asleep (a blocking broadcast would poll a core)."""
    if comm is None:
        return sys.stdin.readline().strip()
    buf = np.zeros(1, dtype=np.int64)
    if comm.Get_rank() == 0:
        buf[0] = 1 if sys.stdin.readline().strip() == "repeat" else 0
    request = comm.Ibcast(buf, root=0)
    while not request.Test():
        time.sleep(0.002)
    return "repeat" if buf[0] == 1 else "finish"


def worker(args) -> None:
    """One process of a measurement: warm up, say "ready", then time a repeat each time rank 0
    reads "repeat" (rank 0 prints it as a JSON line); at "finish" rank 0 prints one JSON line of
    the whole run."""
    sim = make_simulation(args.springs, args.quick, args.threads)
    sim.run(steps=2, diagnostics_every=2)  # kernels loaded or compiled, not timed
    comm = sim.comm
    root = comm is None or comm.Get_rank() == 0
    if root:
        print("ready", flush=True)
    every = max(1, args.steps // 5)
    rows = sim.diagnostics.rows
    while _command(comm) == "repeat":
        before = len(rows)
        t0 = time.perf_counter()
        sim.run(steps=args.steps, diagnostics_every=args.steps)
        t1 = time.perf_counter()
        first = len(rows)
        sim.run(steps=args.steps, diagnostics_every=every)
        t2 = time.perf_counter()
        extra = (len(rows) - first) - (first - before)  # the second call's stops besides the first's
        stop = ((t2 - t1) - (t1 - t0)) / extra if extra > 0 else float("nan")
        if root:
            print(json.dumps({"seconds_per_step": (t1 - t0) / args.steps, "stop_seconds": stop,
                              "step_seconds": ((t1 - t0) - stop) / args.steps}), flush=True)
    halo = getattr(sim.stepper, "halo", None)
    stages = sum(1 for d in sim.integrator.drifts if d != 0.0)
    mine = {"rss_mb": resident_mb(), "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
            "stepping_mb": stepping_bytes(sim) / 2**20,
            "messages": 0 if halo is None else len(halo._send) * stages,
            "bytes": 0 if halo is None else halo.bytes_per_exchange * stages,
            "ghosts": 0 if halo is None else sim.stepper.share.ghosts}
    every = [mine] if comm is None else comm.gather(mine, root=0)
    s = sim.state  # (over processes, a step every process takes: the whole state put together)
    if not root:
        return
    row = sim.diagnostics.rows[-1]
    np.save(args.worker, np.concatenate([s.positions.ravel(), s.momenta.ravel(), [row[k] for k in sorted(row)]]))
    print(json.dumps({"springs": sim.net.n_springs, "nodes": sim.net.n_nodes, "stages": stages, "ranks": every}),
          flush=True)


def resident_mb() -> float:
    """This process's resident memory now (MB; after the run: compilation's peak left out)."""
    try:
        with open("/proc/self/status") as f:
            return next(int(line.split()[1]) for line in f if line.startswith("VmRSS:")) / 1024.0
    except (OSError, StopIteration):
        return float("nan")


def stepping_bytes(sim) -> int:
    """Bytes of the arrays the stepping works on: the stepper's own (a distributed stepper's share:
    its state, buffers, incidence lists, parameters) and, in one process, the state's."""
    seen, total = set(), 0

    def add(value):
        nonlocal total
        if isinstance(value, np.ndarray):
            base = value if value.base is None else value.base
            if id(base) not in seen and isinstance(base, np.ndarray):
                seen.add(id(base))
                total += base.nbytes
        elif isinstance(value, (tuple, list)):
            for v in value:
                add(v)

    for value in vars(sim.stepper).values():
        add(value)
    if sim.comm is None:
        s = sim._state
        add((s.positions, s.momenta, s.thermal_displacement, s.entropy))
    return total


class Run:
    """A worker run over ``ranks`` processes of ``threads`` threads, kept waiting for commands."""

    def __init__(self, args, ranks: int, threads: int, out: str):
        command = [sys.executable, os.path.abspath(__file__), "--worker", out, "--springs", str(args.springs),
                   "--steps", str(args.steps), "--threads", str(threads)]
        command += ["--quick"] if args.quick else []
        env = dict(os.environ, NUMBA_NUM_THREADS=str(max(threads, 1)), OMP_NUM_THREADS="1")
        if ranks > 1:
            command = [shutil.which("mpiexec") or "mpiexec", "-n", str(ranks)] + command
        self.ranks = ranks
        self.errors = open(out + ".stderr", "w+")  # (a file: a full pipe nobody reads would stall the worker)
        self.process = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                        stderr=self.errors, text=True, env=env)
        self.repeats: list = []
        if self._line() != "ready":
            self._failed()

    def _line(self) -> str:
        line = self.process.stdout.readline()
        if not line:
            self._failed()
        return line.strip()

    def _failed(self):
        self.process.kill()
        self.process.wait()
        self.errors.seek(0)
        raise SystemExit(f"mpi_scaling: the run over {self.ranks} process(es) failed:\n{self.errors.read()[-3000:]}")

    def repeat(self) -> dict:
        """One timed repeat (this run alone on the machine while it lasts)."""
        self.process.stdin.write("repeat\n")
        self.process.stdin.flush()
        self.repeats.append(json.loads(self._line()))
        return self.repeats[-1]

    def finish(self) -> dict:
        """The run's JSON line, with the medians of its repeats."""
        self.process.stdin.write("finish\n")
        self.process.stdin.flush()
        out = json.loads(self._line())
        self.process.wait(timeout=600)
        self.errors.close()
        for key in ("seconds_per_step", "step_seconds", "stop_seconds"):
            out[key] = float(np.median([r[key] for r in self.repeats]))
        return out


def model_rows(one: dict, two: dict, latency: float, bandwidths, counts=(2, 4, 8, 16, 64)) -> list:
    """Predicted seconds per step on P processes (see the module docstring)."""
    t1 = one["seconds_per_step"]
    halo = max(r["bytes"] for r in two["ranks"])  # one cut at two processes
    stages = two["stages"]
    rows = []
    for p in counts:
        neighbours = min(6, p - 1)
        bytes_p = neighbours * halo * (1.0 / p) ** (2.0 / 3.0) * 2 ** (2.0 / 3.0)  # each face shrinks with the share
        rows.append((p, [t1 / p + stages * neighbours * latency + bytes_p / b for b in bandwidths]))
    return rows


def main(argv=None) -> list:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--springs", type=float, default=1e6)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--latency", type=float, default=2e-6)
    parser.add_argument("--quick", action="store_true", help="the default scene, 50 steps, once")
    parser.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.quick:
        args.steps, args.repeats = min(args.steps, 50), 1
    if args.worker:
        worker(args)
        return []
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        runs = [("1 process, 1 thread", 1, 1), ("1 process, 2 threads", 1, 2), ("2 processes × 1 thread", 2, 1)]
        if args.quick:
            runs = [runs[0], runs[2]]
        started, rows, states = [], [], []
        try:
            for label, ranks, threads in runs:  # (built one after the other, then kept waiting)
                started.append(Run(args, ranks, threads, os.path.join(tmp, f"{ranks}_{threads}.npy")))
            for _ in range(args.repeats):  # interleaved rounds
                for run in started:
                    run.repeat()
            for (label, ranks, threads), run in zip(runs, started):
                rows.append(dict(run.finish(), label=label, processes=ranks, threads=threads))
                states.append(np.load(os.path.join(tmp, f"{ranks}_{threads}.npy")))
        finally:
            for run in started:
                if run.process.poll() is None:
                    run.process.kill()
    base = rows[0]
    for row, run, state in zip(rows, started, states):
        row["speedup"] = float(np.median([b["seconds_per_step"] / r["seconds_per_step"]
                                          for b, r in zip(started[0].repeats, run.repeats)]))
        row["identical"] = bool(np.array_equal(state, states[0]))
    print(f"\n{base['springs']} springs, {base['nodes']} nodes; load average {os.getloadavg()[0]:.2f} "
          f"on {os.cpu_count()} cores\n")
    print("| run | s/step | speed-up | a step alone (s) | a diagnostics stop (s) | halo msgs/step/process "
          "| halo bytes/step/process | ghosts/process | stepping arrays MB/process | resident MB/process (peak) "
          "| same bits as 1 process |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        ranks = row["ranks"]

        def each(key, form="%.0f"):
            return " / ".join(form % r[key] for r in ranks)

        print(f"| {row['label']} | {row['seconds_per_step']:.3e} | {row['speedup']:.2f} | "
              f"{row['step_seconds']:.3e} | {row['stop_seconds']:.4f} | {max(r['messages'] for r in ranks)} | {max(r['bytes'] for r in ranks)} | {each('ghosts', '%d')} | "
              f"{each('stepping_mb', '%.1f')} | {each('rss_mb')} ({each('peak_mb')}) | "
              f"{'yes' if row['identical'] else 'NO'} |")
    bandwidths = (10e9 / 8, 100e9 / 8)
    print(f"\nModel, t_P = t_1/P + halo (latency {args.latency:.0e} s; 10 and 100 Gb/s):\n")
    print("| processes | s/step at 10 Gb/s | s/step at 100 Gb/s |")
    print("|---|---|---|")
    for p, (t10, t100) in model_rows(rows[0], rows[-1], args.latency, bandwidths):
        print(f"| {p} | {t10:.3e} | {t100:.3e} |")
    return rows


if __name__ == "__main__":
    main()
