"""What each effect of a scene costs: steps/s on a ~1e5-spring lattice with
(a) mechanics only, (b) + thermal coupling, (c) + gravity, (d) + a VTU frame every 100 steps,
(e) + a diagnostics row every 10 steps; each as a cost ratio to (a).

    python benchmarks/effects_cost.py [--cells 32] [--steps 1000] [--repeats 3]

Prints a markdown table (medians over the repeats, all configurations measured side by side in
one process). Targets (issue 4): thermal ≤ 1.5× mechanics; output and diagnostics ≤ 10%.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time

from thermonet.io import RunOutput
from thermonet.scenes import scene_from_text

SCENE = """
name = "bench"
[net]
generator = "lattice"
lattice = {{ shape = [{n}, {n}, {n}], spacing = 1.0, neighbours = 6, jitter = 0.1, seed = 1 }}
[materials.all]
c = 100.0
[initial.velocity]
random = {{ amplitude = 0.01, seed = 2 }}
[integrator]
name = "co2"
h = 0.01
steps = {steps}
"""

CONFIGS = [
    ("(a) mechanics only", ["effects.thermal=false"], 0, None),
    ("(b) + thermal", [], 0, None),
    ("(c) + gravity", ["effects.gravity=[0, 0, -1]"], 0, None),
    ("(d) + VTU every 100 steps", ["effects.gravity=[0, 0, -1]"], 100, None),
    ("(e) + diagnostics every 10 steps", ["effects.gravity=[0, 0, -1]"], 100, 10),
]


def measure(text: str, overrides, frames_every: int, diagnostics_every, folder: str) -> tuple[float, int]:
    """Steps/s of one run (diagnostics only at start and end unless ``diagnostics_every``)."""
    scene = scene_from_text(text, overrides)
    built = scene.build()
    sim = built.simulation
    steps = scene.total_steps()
    every = diagnostics_every or steps
    observers = []
    if frames_every:
        out = RunOutput(sim, folder, "bench", fields=scene.output_fields(), frames_every=frames_every,
                        diagnostics_every=every, checkpoint_every=0, material_id=built.material_id,
                        scene={"name": "bench", "hash": scene.hash})
        observers = [(k, cb) for k, cb in out.observers() if cb == out.write_frame]
    t0 = time.perf_counter()
    sim.run(steps=steps, diagnostics_every=every, observers=observers)
    return steps / (time.perf_counter() - t0), sim.net.n_springs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=32, help="lattice cells per axis (32: about 1e5 springs)")
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    text = SCENE.format(n=args.cells, steps=args.steps)
    with tempfile.TemporaryDirectory() as folder:
        for _, overrides, frames, diag in CONFIGS:  # compile every kernel first
            measure(SCENE.format(n=2, steps=20), overrides, frames and 10, diag, folder)
        rates = {name: [] for name, *_ in CONFIGS}
        for _ in range(args.repeats):  # interleaved, so drifts of the machine hit all alike
            for name, overrides, frames, diag in CONFIGS:
                rate, m = measure(text, overrides, frames, diag, os.path.join(folder, "frames"))
                rates[name].append(rate)
    base = statistics.median(rates[CONFIGS[0][0]])
    print(f"{m} springs, {args.steps} steps per run, median of {args.repeats}, co2, "
          f"{os.cpu_count()} cores\n")
    print("| configuration | steps/s | spring-steps/s | cost vs (a) |")
    print("|---|---:|---:|---:|")
    for name, *_ in CONFIGS:
        r = statistics.median(rates[name])
        print(f"| {name} | {r:,.0f} | {r * m:.3g} | {base / r:.2f}× |")


if __name__ == "__main__":
    main()
