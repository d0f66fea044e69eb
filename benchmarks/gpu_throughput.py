"""Throughput of the CUDA backend (CO2, "hencky") on one GPU, against the device's copy bandwidth
and the CPU backend.

    python benchmarks/gpu_throughput.py [--sizes 1e5,1e6,1e7,5e7] [--seconds 2] [--cpu-max 1e7] [--json out.json]
    NUMBA_ENABLE_CUDASIM=1 python benchmarks/gpu_throughput.py --quick   # a smoke run (tests/test_benchmarks.py)

Needs an NVIDIA GPU and numba-cuda (``pip install '.[cuda]'``); refuses to run otherwise, and
under Numba's CUDA simulator (its timings mean nothing). For 6-neighbour lattice nets (jitter
0.1, random temperatures 250–350, small random velocities) of about each requested number of
springs it prints a markdown table:

- GPU spring-steps per second (springs × steps / wall time of ``advance`` with the device
  synchronized), after a warm-up that compiles the kernels; the median of three runs, each about
  ``--seconds`` long; with one cooperative launch per chunk of steps ("fused") and with two
  launches per stage, and the rate of the one the default picks by net size;
- the device-to-device copy bandwidth measured in the same run (a copy kernel over 2 GiB,
  counting bytes read and written), the bytes per spring-step the two kernels move and the
  fraction of that bandwidth reached: (rate × bytes per spring-step) / bandwidth. Bytes are
  compulsory traffic, counted as in ``explicit_throughput.py``: each array a kernel reads counts
  its full size once per launch, each it writes once more; gathered reads (x of the other end,
  T/l of incident springs) count once per launch, as a perfect cache would move them;
- the CPU backend's rate on the same net (all threads; nets up to ``--cpu-max`` springs) and
  the speed-up;
- device memory per spring, and the largest net that would fit in the device's free memory at
  that rate of use (an estimate from the measured bytes per spring, not a run).

Before timing, the GPU and CPU backends run 20 steps from one state on a small net at the same h
and their largest relative difference is printed (round-off: fused multiply-adds on the GPU).

``--quick`` runs a tiny net for a few steps and accepts Numba's CUDA simulator (no copy bandwidth,
no CPU column): it checks that the script runs; its timings mean nothing.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import thermonet as tn  # noqa: E402
from thermonet.explicit.cuda import cuda_problem, simulator_enabled  # noqa: E402

try:
    from numba import cuda
except ImportError:  # main() says what is missing
    cuda = None

H = 1e-3
NEIGHBOURS = 6


def lattice_sim(target_springs: int, backend: str) -> tn.Simulation:
    """A 6-neighbour lattice net of about ``target_springs`` springs on ``backend``."""
    k = max(1, int(round((target_springs / 3.0) ** (1.0 / 3.0))))
    net = tn.lattice((k, k, k), neighbours=NEIGHBOURS, jitter=0.1, seed=1)
    rng = np.random.default_rng(1)
    temps = 250.0 + 100.0 * rng.random(net.n_springs)
    v = rng.normal(0.0, 0.05, (net.n_nodes, 3))
    return tn.Simulation(net, temperatures=temps, velocities=v, integrator="co2", h=H, backend=backend,
                         stability_guard="off", energy_tolerance=None)


def bytes_per_step(n: int, m: int, params_per_spring: int) -> int:
    """Compulsory bytes of one CO2 step (one spring launch, one node launch), thermal, no gravity.

    Spring launch: edges 8m, x 24n, η 8m, l0 8m, Φ read+write 16m, T/l write 8m, per-spring
    parameters 8km (0 when shared). Node launch: x 24n, p read+write 48n, x_new 24n, inc_ptr 8n,
    1/m 8n, anchored 1n, inc_spring + inc_other 8m, T/l 8m.
    """
    spring = 48 * m + 24 * n + 8 * params_per_spring * m
    node = 16 * m + 8 * m + 113 * n
    return spring + node


def device_bytes(stepper) -> int:
    """Bytes of every device array the CUDA stepper holds, directly or in its records (each array
    counted once)."""
    seen, visited = {}, set()

    def walk(value):
        if id(value) in visited:
            return
        visited.add(id(value))
        if hasattr(value, "copy_to_host"):
            seen[id(value)] = value.nbytes
        elif isinstance(value, (tuple, list)):
            for item in value:
                walk(item)
        elif type(value).__module__ == "thermonet.heat.cuda":  # the device heat record's holder
            for item in vars(value).values():
                walk(item)

    for v in vars(stepper).values():
        walk(v)
    return sum(seen.values())


def _copy(src, dst):
    i = cuda.grid(1)
    if i < src.shape[0]:
        dst[i] = src[i]


def copy_bandwidth(cuda, n_bytes: int = 2 << 30, repeats: int = 10) -> float:
    """Device-to-device copy bandwidth in bytes/s (read + write), best of ``repeats``."""

    copy = cuda.jit(_copy)
    n = n_bytes // 8
    src = cuda.device_array(n)
    dst = cuda.device_array(n)
    threads = 256
    blocks = (n + threads - 1) // threads
    copy[blocks, threads](src, dst)
    cuda.synchronize()
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        copy[blocks, threads](src, dst)
        cuda.synchronize()
        best = min(best, time.perf_counter() - t0)
    del src, dst
    return 2 * n * 8 / best


def gpu_rate(sim, cuda, seconds: float, fused: bool, multiple: int = 1, quick: bool = False) -> float:
    """Median spring-steps/s of the CUDA stepper over three runs of about ``seconds``, with one
    cooperative launch per chunk of steps (``fused``) or two launches per stage; every call a
    whole number of ``multiple`` steps (a conduction cycle). quick: one short timed call."""
    stepper, state, m, h = sim.stepper, sim._state, sim.net.n_springs, sim.h
    stepper.fused = fused
    stepper.advance(state, 2 * multiple, h)  # compile and upload
    if quick:
        cuda.synchronize()
        t0 = time.perf_counter()
        stepper.advance(state, multiple, h)
        cuda.synchronize()
        return multiple * m / max(time.perf_counter() - t0, 1e-9)
    cuda.synchronize()
    t0 = time.perf_counter()
    stepper.advance(state, 10 * multiple, h)
    cuda.synchronize()
    per_step = max((time.perf_counter() - t0) / (10 * multiple), 1e-7)
    steps = max(10, int(seconds / per_step)) // multiple * multiple + multiple
    rates = []
    for _ in range(3):
        t0 = time.perf_counter()
        stepper.advance(state, steps, h)
        cuda.synchronize()
        rates.append(steps * m / (time.perf_counter() - t0))
    return float(np.median(rates))


def cpu_rate(target: int, seconds: float) -> float:
    sim = lattice_sim(target, "cpu")
    sim.run(steps=2, diagnostics_every=2)
    t0 = time.perf_counter()
    sim.run(steps=3, diagnostics_every=3)
    per_step = max((time.perf_counter() - t0) / 3, 1e-7)
    steps = max(3, int(seconds / per_step))
    t0 = time.perf_counter()
    sim.run(steps=steps, diagnostics_every=steps)
    return steps * sim.net.n_springs / (time.perf_counter() - t0)


def agreement(springs: int = 3000, steps: int = 20) -> float:
    """Largest relative difference of positions, momenta, Φ after ``steps`` steps at the same h,
    GPU vs CPU."""
    out = []
    for backend in ("cpu", "cuda"):
        sim = lattice_sim(springs, backend)
        sim.run(steps=steps, diagnostics_every=steps)
        s = sim.state
        out.append((s.positions, s.momenta, s.thermal_displacement))
    return max(float(np.max(np.abs(a - b)) / np.max(np.abs(a))) for a, b in zip(*out))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="a tiny net, a few steps; the CUDA simulator allowed")
    ap.add_argument("--sizes", default="1e5,1e6,1e7,5e7", help="comma-separated spring counts")
    ap.add_argument("--seconds", type=float, default=2.0, help="length of each timed run")
    ap.add_argument("--cpu-max", type=float, default=1e7, help="largest net also timed on the CPU backend")
    ap.add_argument("--json", help="also write the rows to this JSON file")
    args = ap.parse_args(argv)
    if args.quick:
        args.sizes, args.cpu_max = "60", 0.0

    problem = "Numba's CUDA simulator is on (NUMBA_ENABLE_CUDASIM): its timings mean nothing" \
        if simulator_enabled() and not args.quick else cuda_problem()
    if problem is not None:
        print(f"gpu_throughput: needs a CUDA GPU: {problem}", file=sys.stderr)
        return 2
    dev = cuda.get_current_device()
    free, total = cuda.current_context().get_memory_info()
    import numba_cuda

    name = getattr(dev, "name", "Numba's CUDA simulator")
    print(f"device: {name.decode() if isinstance(name, bytes) else name}, "
          f"{total / 2**30:.1f} GiB; numba-cuda {numba_cuda.__version__}, numpy {np.__version__}, "
          f"python {platform.python_version()}")
    springs, steps = (60, 3) if args.quick else (3000, 20)
    print(f"GPU vs CPU after {steps} steps ({springs} springs, the same h): max relative difference "
          f"{agreement(springs, steps):.2e}")
    bandwidth = float("nan") if args.quick else copy_bandwidth(cuda)
    print(f"device copy bandwidth (read + write): {bandwidth / 1e12:.2f} TB/s\n")
    print("| springs | nodes | GPU G spring-steps/s | fused launch | two launches per stage | B/spring-step | "
          "of copy bandwidth | CPU G spring-steps/s | speed-up | device B/spring | largest net that fits (est.) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for size in (int(float(s)) for s in args.sizes.split(",")):
        try:
            sim = lattice_sim(size, "cuda")
        except Exception as exc:  # out of device memory: the previous size was the largest that ran
            print(f"| {size:.0e} | – | did not fit: {type(exc).__name__}: {exc} |")
            break
        n, m = sim.net.n_nodes, sim.net.n_springs
        fused = gpu_rate(sim, cuda, args.seconds, fused=True, quick=args.quick)
        two_launch = gpu_rate(sim, cuda, args.seconds, fused=False, quick=args.quick)
        rate = fused if m < sim.stepper.FUSED_MAX_SPRINGS else two_launch  # what the default runs
        P = sim.stepper._springs.P
        b = bytes_per_step(n, m, 0 if P.shape[1] == 1 else P.shape[0]) / m
        per_spring = device_bytes(sim.stepper) / m
        fits = int(free / per_spring) if math.isfinite(free / per_spring) else 0  # (the simulator: no memory)
        del sim
        cpu = cpu_rate(size, args.seconds) if size <= args.cpu_max else float("nan")
        row = dict(springs=m, nodes=n, gpu_rate=rate, gpu_rate_fused=fused, gpu_rate_two_launch=two_launch,
                   bytes_per_spring_step=b, bandwidth=bandwidth,
                   bandwidth_fraction=rate * b / bandwidth, cpu_rate=cpu, speedup=rate / cpu,
                   device_bytes_per_spring=per_spring, largest_fitting_springs=fits)
        rows.append(row)
        print(f"| {m:,} | {n:,} | {rate / 1e9:.2f} | {fused / 1e9:.2f} | {two_launch / 1e9:.2f} | {b:.0f} | "
              f"{row['bandwidth_fraction']:.0%} | {cpu / 1e9:.3f} | {row['speedup']:.0f}× | {per_spring:.0f} | {fits:.2e} |", flush=True)
        if args.json:  # after every row: a run cut short by a time limit keeps what it measured
            with open(args.json, "w") as f:
                json.dump(dict(device=str(name), bandwidth=bandwidth, rows=rows), f, indent=1)
    if args.quick:
        print("(quick: timings mean nothing)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
