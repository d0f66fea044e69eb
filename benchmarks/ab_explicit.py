"""Explicit throughput of two checkouts of thermonet, interleaved: a change's speed against the
code before it, measured in the same period on the same machine.

    python benchmarks/ab_explicit.py --old /path/to/old/checkout [--new .] [--sizes 1e5,1e6]
                                     [--integrators co2] [--repeats 5] [--steps 200]

Each repeat runs one fresh process per checkout (PYTHONPATH set to it), old and new alternating,
and every process times ``Simulation.run`` on the same 6-neighbour lattice (jitter 0.1, hencky,
random temperatures 250–350, a diagnostics row every 10 steps) after a warm-up call that
compiles or loads the kernels. Prints a markdown table of medians (spring-steps per second on
all threads) and the ratio new/old with the range of the per-repeat ratios: on a shared machine
a ratio whose range straddles 1 is noise.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

import numpy as np

WORKER = r"""
import json, sys, time
import numpy as np
import thermonet as tn
cells, integrator, steps = int(sys.argv[1]), sys.argv[2], int(sys.argv[3])
net = tn.lattice((cells, cells, cells), neighbours=6, jitter=0.1, seed=1)
rng = np.random.default_rng(1)
sim = tn.Simulation(net, temperatures=250 + 100 * rng.random(net.n_springs),
                    velocities=rng.normal(0, 0.01, (net.n_nodes, 3)), integrator=integrator, h=1e-3)
sim.run(steps=20, diagnostics_every=10)
t = time.perf_counter()
sim.run(steps=steps, diagnostics_every=10)
dt = time.perf_counter() - t
print(json.dumps({"springs": net.n_springs, "rate": net.n_springs * steps / dt}))
"""


def cells_for(springs: float) -> int:
    """Cells per axis of a 6-neighbour lattice with about that many springs (3 per node)."""
    return max(2, int(round((springs / 3.0) ** (1.0 / 3.0))))


def measure(checkout: str, cells: int, integrator: str, steps: int) -> dict:
    env = dict(os.environ, PYTHONPATH=os.path.abspath(checkout))
    out = subprocess.run([sys.executable, "-c", WORKER, str(cells), integrator, str(steps)], env=env,
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", required=True, help="checkout of the code before the change")
    ap.add_argument("--new", default=".", help="checkout of the change (default: this one)")
    ap.add_argument("--sizes", default="1e5,1e6", help="approximate spring counts")
    ap.add_argument("--integrators", default="co2")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--steps", type=int, default=200)
    args = ap.parse_args(argv)
    print(f"load average at start: {os.getloadavg()[0]:.2f}")
    print("| integrator | springs | old (M spring-steps/s) | new | new/old (range) |")
    print("|---|---|---|---|---|")
    for integrator in args.integrators.split(","):
        for size in (float(s) for s in args.sizes.split(",")):
            cells = cells_for(size)
            steps = max(10, int(args.steps * 1e5 / size))
            rates: dict[str, list] = {"old": [], "new": []}
            springs = 0
            for r in range(args.repeats):
                order = ("old", "new") if r % 2 == 0 else ("new", "old")
                for which in order:
                    got = measure(getattr(args, which), cells, integrator, steps)
                    rates[which].append(got["rate"])
                    springs = got["springs"]
            old, new = np.array(rates["old"]), np.array(rates["new"])
            ratios = new / old
            print(f"| {integrator} | {springs} | {np.median(old) / 1e6:.1f} | {np.median(new) / 1e6:.1f} | "
                  f"{np.median(new) / np.median(old):.3f} ({ratios.min():.2f}–{ratios.max():.2f}) |", flush=True)
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
