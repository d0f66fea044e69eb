"""What each effect of a scene costs: steps/s on a ~1e5-spring lattice with
(a) mechanics only, (b) + thermal coupling, (c) + gravity, (d) + a VTU frame every 100 steps,
(e) + a diagnostics row every 10 steps; each as a cost ratio to (a), and the overhead of each
effect over the configuration before it. (d) writes frame files as a run does by default
(direct to the device on a writer thread where the file system allows); the four "(d) …" rows
below it force each way (direct or through the page cache; on the writer thread or in the
frame observer), for comparison.

    python benchmarks/effects_cost.py [--cells 32] [--steps 1000] [--repeats 3]
    python benchmarks/effects_cost.py --quick    # a 3³ lattice, 200 steps, one repeat (a smoke run)

Prints a markdown table. The configurations run interleaved, one run each per repeat, so that
drifts of a shared machine hit all alike; steps/s are medians over the repeats, and an
overhead is the median over the repeats of the ratio of two runs of the same repeat. The frame
columns are the milliseconds per frame the stepping thread spent in the frame observer (filling
the image) and that the file write took (on the writer thread, overlapped with stepping).
Targets: thermal ≤ 1.5× mechanics; output and diagnostics ≤ 10%.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import tempfile
import time

import numba
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

# (name, overrides, frames every, diagnostics every, how frame files are written (RunOutput's
#  background and direct; {}: the default), the configuration whose overhead this adds)
CONFIGS = [
    ("(a) mechanics only", ["effects.thermal=false"], 0, None, {}, None),
    ("(b) + thermal", [], 0, None, {}, "(a) mechanics only"),
    ("(c) + gravity", ["effects.gravity=[0, 0, -1]"], 0, None, {}, "(b) + thermal"),
    ("(d) + VTU every 100 steps", ["effects.gravity=[0, 0, -1]"], 100, None, {}, "(c) + gravity"),
    ("(d) direct, on the writer thread", ["effects.gravity=[0, 0, -1]"], 100, None,
     dict(background=True, direct=True), "(c) + gravity"),
    ("(d) direct, in the observer", ["effects.gravity=[0, 0, -1]"], 100, None,
     dict(background=False, direct=True), "(c) + gravity"),
    ("(d) page cache, on the writer thread", ["effects.gravity=[0, 0, -1]"], 100, None,
     dict(background=True, direct=False), "(c) + gravity"),
    ("(d) page cache, in the observer", ["effects.gravity=[0, 0, -1]"], 100, None,
     dict(background=False, direct=False), "(c) + gravity"),
    ("(e) + diagnostics every 10 steps", ["effects.gravity=[0, 0, -1]"], 100, 10, {}, "(d) + VTU every 100 steps"),
]


def measure(text: str, overrides, frames_every: int, diagnostics_every, folder: str, writes: dict):
    """(steps/s, springs, ms per frame in the observer, ms per frame file write, how the frames
    were written) of one run (diagnostics only at start and end unless ``diagnostics_every``)."""
    scene = scene_from_text(text, overrides)
    built = scene.build()
    sim = built.simulation
    steps = scene.total_steps()
    every = diagnostics_every or steps
    observers = []
    if frames_every:
        out = RunOutput(sim, folder, "bench", fields=scene.output_fields(), frames_every=frames_every,
                        diagnostics_every=every, checkpoint_every=0, material_id=built.material_id,
                        scene={"name": "bench", "hash": scene.hash}, **writes)
        observers = [(k, cb) for k, cb in out.observers() if cb == out.write_frame]
    t0 = time.perf_counter()
    sim.run(steps=steps, diagnostics_every=every, observers=observers)
    rate = steps / (time.perf_counter() - t0)
    if not frames_every:
        return rate, sim.net.n_springs, None, None, None
    frames = len(out.pvd.frames)
    how = ("thread" if out.background else "observer") + (", direct" if out.direct_writes == frames else "")
    return rate, sim.net.n_springs, 1e3 * out.frame_seconds / frames, 1e3 * out.write_seconds / frames, how


def main(argv=None) -> list[dict]:
    """Run the benchmark (``argv``: its command line); returns its rows as dicts (configuration,
    springs, steps/s, cost vs (a), overhead over the configuration before it, and for the
    configurations with frames: frames written, ms per frame in the observer and per write, how
    the frames were written)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=32, help="lattice cells per axis (32: about 1e5 springs)")
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="a 3³ lattice, 200 steps (two frames), one repeat "
                    "(a smoke run)")
    args = ap.parse_args(argv)
    if args.quick:
        args.cells, args.steps, args.repeats = 3, 200, 1
    text = SCENE.format(n=args.cells, steps=args.steps)
    with tempfile.TemporaryDirectory() as folder:
        for _, overrides, frames, diag, writes, _ in CONFIGS:  # compile every kernel first
            measure(SCENE.format(n=2, steps=20), overrides, frames and 10, diag, folder, writes)
        runs = {name: [] for name, *_ in CONFIGS}
        for _ in range(args.repeats):  # interleaved, so drifts of the machine hit all alike
            for name, overrides, frames, diag, writes, _ in CONFIGS:
                # a fresh folder per run, as a new run's output: replacing files of an earlier run
                # costs more (freeing their blocks) and is not what a run normally does
                run_folder = tempfile.mkdtemp(dir=folder)
                runs[name].append(measure(text, overrides, frames, diag, run_folder, writes))
                shutil.rmtree(run_folder)
    m = runs[CONFIGS[0][0]][0][1]
    rate = {name: [r[0] for r in runs[name]] for name in runs}
    base = statistics.median(rate[CONFIGS[0][0]])
    print(f"{m} springs, {args.steps} steps per run, {args.repeats} interleaved repeats, co2, "
          f"{os.cpu_count()} cores, {numba.get_num_threads()} threads\n")
    print("| configuration | steps/s | cost vs (a) | overhead over | ms/frame in observer | ms/frame write |")
    print("|---|---:|---:|---|---:|---:|")
    rows = []
    for name, _, frames, _, _, before in CONFIGS:
        r = statistics.median(rate[name])
        row = {"configuration": name, "springs": m, "rate": r, "cost": base / r, "overhead": None,
               "frame_ms": None, "write_ms": None, "written": None}
        over = "–"
        if before is not None:
            paired = statistics.median(b / a for a, b in zip(rate[name], rate[before]))
            row["overhead"] = paired - 1
            over = f"{100 * (paired - 1):+.1f} % over {before.split()[0]}"
        fill = write = "–"
        if frames:
            row["frame_ms"] = statistics.median(x[2] for x in runs[name])
            row["write_ms"] = statistics.median(x[3] for x in runs[name])
            row["written"] = runs[name][0][4]
            fill, write = f"{row['frame_ms']:.2f}", f"{row['write_ms']:.2f} ({row['written']})"
        print(f"| {name} | {r:,.0f} | {base / r:.2f}× | {over} | {fill} | {write} |")
        rows.append(row)
    return rows


if __name__ == "__main__":
    main()
