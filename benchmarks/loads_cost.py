"""What loads cost: steps/s of CO2 on a ~1e5-spring thermal lattice clamped at x = min and
(a) clamped at x = max too (no loads: the kernels compiled without them), (b) driven at x = max
(a drive: its face's ~1e3 nodes set after each drift, their reaction and work per kick),
(c) (b) + a total force on the z = max face, (d) (c) + a diagnostics row every 10 steps (each
row's reaction needs a spring pass), (e) (a) with a diagnostics row every 10 steps (what (d)
pays for its rows without loads). Each as a cost ratio to (a).

    python benchmarks/loads_cost.py [--cells 32] [--steps 400] [--repeats 5] [--threads N]
    python benchmarks/loads_cost.py --quick      # a 3³ lattice, 20 steps, one repeat (a smoke run)

The configurations run interleaved, one run each per repeat; steps/s are medians over the
repeats and a ratio is the median of the per-repeat ratios.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numba
from thermonet.scenes import scene_from_text

SCENE = """
[net]
generator = "lattice"
lattice = {{ shape = [{n}, {n}, {n}], spacing = 1.0, neighbours = 6, jitter = 0.1, seed = 1 }}
[materials.all]
c = 100.0
[effects]
anchors = {anchors}
{loads}
[initial.velocity]
random = {{ amplitude = 0.01, seed = 2 }}
[integrator]
name = "co2"
h = 0.01
steps = {steps}
energy_tolerance = false
"""
DRIVE = '[loads.pull]\ntype = "drive"\ngroup = "xmax"\nvelocity = [0.01, 0, 0]\n'
FORCE = '[loads.push]\ntype = "force"\ngroup = "zmax"\nforce = {{ z = {{ amplitude = 1.0, frequency = 0.5 }} }}\ntotal = true\n'
CONFIGS = [
    ("(a) both ends clamped, no loads", '["xmin", "xmax"]', "", None),
    ("(b) x = max driven", '["xmin"]', DRIVE, None),
    ("(c) + a total force on z = max", '["xmin"]', DRIVE + FORCE, None),
    ("(d) + diagnostics every 10 steps", '["xmin"]', DRIVE + FORCE, 10),
    ("(e) (a) + diagnostics every 10 steps", '["xmin", "xmax"]', "", 10),
]


def measure(text: str, diagnostics_every):
    """(steps/s, springs, the diagnostics' columns, diagnostics rows) of one timed run."""
    sim = scene_from_text(text).build().simulation
    steps = int(text.split("steps = ")[1].split()[0])
    sim.run(steps=2, diagnostics_every=2)  # compile or load the kernels
    t0 = time.perf_counter()
    sim.run(steps=steps, diagnostics_every=diagnostics_every or steps)
    rate = steps / (time.perf_counter() - t0)
    return rate, sim.net.n_springs, sim.diagnostics.columns, len(sim.diagnostics.rows)


def main(argv=None) -> list[dict]:
    """Run the benchmark (``argv``: its command line); returns its rows as dicts (configuration,
    springs, steps/s, cost vs (a))."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=32)
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--threads", type=int, default=None, help="threads of the kernels (default: all)")
    ap.add_argument("--quick", action="store_true", help="a 3³ lattice, 20 steps, one repeat (a smoke run)")
    args = ap.parse_args(argv)
    if args.quick:
        args.cells, args.steps, args.repeats = 3, 20, 1
    if args.threads:
        numba.set_num_threads(args.threads)
    texts = [SCENE.format(n=args.cells, steps=args.steps, anchors=a, loads=l.replace("{{", "{").replace("}}", "}"))
             for _, a, l, _ in CONFIGS]
    rates = {name: [] for name, *_ in CONFIGS}
    springs, columns = 0, {}
    load0 = os.getloadavg()[0]
    for _ in range(args.repeats):
        for (name, _, _, every), text in zip(CONFIGS, texts):
            rate, springs, *columns[name] = measure(text, every)
            rates[name].append(rate)
    base = rates[CONFIGS[0][0]]
    print(f"{springs} springs, {numba.get_num_threads()} threads, {args.repeats} repeats, "
          f"load average {load0:.2f} at start, {os.getloadavg()[0]:.2f} at end\n")
    print("| configuration | steps/s (median) | cost vs (a) |\n|---|---|---|")
    rows = []
    for name, *_ in CONFIGS:
        ratio = statistics.median(b / r for b, r in zip(base, rates[name]))
        rows.append({"configuration": name, "springs": springs, "rate": statistics.median(rates[name]),
                     "ratio": ratio, "columns": columns[name][0], "diagnostics_rows": columns[name][1]})
        print(f"| {name} | {rows[-1]['rate']:.4g} | {ratio:.3f}× |")
    return rows


if __name__ == "__main__":
    main()
