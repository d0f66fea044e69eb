"""The one GPU check: on a machine with an NVIDIA GPU, run the ``gpu`` tests, the explicit
throughput at 1e5/1e6/1e7 springs, what conduction costs per step, and the default, thermal-shock
and tensile scenes on the GPU, then print one table.

    python benchmarks/gpu_check.py [--base DIR] [--sizes 1e5,1e6,1e7] [--heat-sizes 3e6] [--out DIR]
    NUMBA_ENABLE_CUDASIM=1 python benchmarks/gpu_check.py --quick   # a smoke run (tests/test_benchmarks.py)

Each part runs as its own process (a part that fails is reported and the others still run), in
this order: ``pytest -m gpu`` on the CUDA test files (``-n`` workers when pytest-xdist is there);
``gpu_throughput.py`` (CO2, 6-neighbour lattices, fused and two launches per stage, against the
copy bandwidth measured in the same run); ``gpu_heat_cost.py`` (conduction every step and every
k steps against the adiabatic step); with ``--base DIR``, each benchmark also from another
checkout (e.g. a copy of the main branch) right after this one's on the same card, so that a
change is measured against a baseline of the same call; ``thermonet run`` of the three scenes with
``--set integrator.backend=cuda``. docs/gpu.md says how to carry the wheels to a GPU machine
without the package index. About 5 minutes on one H100 or H200 (6.2 on an H200 with ``--base`` and
``--heat-sizes 3e5,3e6``).

``--quick`` runs the two benchmarks' own quick modes (tiny nets; Numba's CUDA simulator allowed)
and skips the tests and the scenes: it checks that this script and its parts run, its timings
mean nothing.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
CUDA_TESTS = ("tests/test_cuda_sim.py", "tests/test_cuda_heat_sim.py", "tests/test_loads_cuda.py")
SCENES = ("default", "thermal_shock", "tensile")


def part(name: str, command: list[str], cwd: str, timeout: float, env=None) -> dict:
    """Run one part; its wall time, exit code and output (also echoed, so a log keeps it)."""
    print(f"\n=== {name}: {' '.join(command)}", flush=True)
    t0 = time.perf_counter()
    try:
        done = subprocess.run(command, cwd=cwd, capture_output=True, text=True, timeout=timeout,
                              env=dict(os.environ, PYTHONPATH=os.pathsep.join(
                                  p for p in (cwd, os.environ.get("PYTHONPATH", "")) if p), **(env or {})))
        rc, out = done.returncode, done.stdout + done.stderr
    except subprocess.TimeoutExpired as exc:
        rc, out = 124, f"{exc.stdout or ''}{exc.stderr or ''}\n(timed out after {timeout:.0f} s)"
        out = out if isinstance(out, str) else out.decode(errors="replace")
    print(out[-6000:], flush=True)
    return dict(name=name, rc=rc, seconds=time.perf_counter() - t0, out=out)


def throughput_rows(path: str) -> list[dict]:
    try:
        with open(path) as f:
            return json.load(f)["rows"]
    except (OSError, ValueError, KeyError):
        return []


def heat_rows(out: str) -> list[tuple]:
    """(springs, launch, run, ratio) of gpu_heat_cost's table."""
    rows = []
    for line in out.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 6 and cells[0].replace(",", "").isdigit():
            rows.append((cells[0], cells[1], cells[2], cells[4]))
    return rows


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--base", help="another checkout whose gpu_throughput.py runs right after this one's")
    ap.add_argument("--sizes", default="1e5,1e6,1e7", help="throughput net sizes (springs)")
    ap.add_argument("--heat-sizes", default="3e6", help="conduction cost net sizes (springs)")
    ap.add_argument("--seconds", type=float, default=0.5, help="length of each timed run")
    ap.add_argument("--workers", type=int, default=8, help="pytest-xdist workers for the tests")
    ap.add_argument("--out", help="folder for the JSON and the log (default: a temporary folder)")
    ap.add_argument("--quick", action="store_true", help="the benchmarks' quick modes only; simulator allowed")
    args = ap.parse_args(argv)
    out_dir = args.out or tempfile.mkdtemp(prefix="gpu_check_")
    os.makedirs(out_dir, exist_ok=True)
    py = sys.executable
    parts, trees = [], [("this tree", ROOT)] + ([("base", os.path.abspath(args.base))] if args.base else [])
    if not args.quick:
        try:
            import xdist  # noqa: F401

            workers = ["-n", str(args.workers)]
        except ImportError:
            workers = []
        parts.append(part("gpu tests", [py, "-m", "pytest", "-q", "-m", "gpu", "-p", "no:cacheprovider", *workers,
                                        *CUDA_TESTS], ROOT, 300))
    for label, tree in trees:
        json_path = os.path.join(out_dir, f"throughput_{'base' if tree != ROOT else 'this'}.json")
        command = [py, os.path.join(tree, "benchmarks", "gpu_throughput.py"), "--json", json_path]
        command += ["--quick"] if args.quick else ["--sizes", args.sizes, "--seconds", str(args.seconds),
                                                   "--cpu-max", "0"]
        result = part(f"throughput ({label})", command, tree, 400)
        result["rows"] = throughput_rows(json_path)
        parts.append(result)
    for label, tree in trees:
        heat = [py, os.path.join(tree, "benchmarks", "gpu_heat_cost.py")]
        heat += ["--quick"] if args.quick else ["--sizes", args.heat_sizes, "--seconds", str(args.seconds)]
        result = part(f"conduction cost ({label})", heat, tree, 400)
        result["rows"] = heat_rows(result["out"])
        parts.append(result)
    if not args.quick:
        for scene in SCENES:
            folder = os.path.join(out_dir, f"scene_{scene}")
            parts.append(part(f"scene {scene}", [py, "-m", "thermonet", "run", f"scenes/{scene}.toml", "--quiet",
                                                 "--overwrite", "--out", folder, "--set", 'integrator.backend="cuda"'],
                              ROOT, 300))
    report(parts)
    with open(os.path.join(out_dir, "gpu_check.json"), "w") as f:
        json.dump([{k: v for k, v in p.items() if k != "out"} for p in parts], f, indent=1, default=str)
    return parts


def report(parts: list[dict]) -> None:
    """The one table: each part's outcome, then the figures."""
    print("\n## GPU check\n\n| part | exit | seconds | result |\n|---|---:|---:|---|")
    for p in parts:
        summary = ""
        if p["name"] == "gpu tests":
            found = re.findall(r"(\d+ (?:passed|failed|skipped|error)\w*)", p["out"])
            summary = ", ".join(found[-4:])
        elif p["name"].startswith("throughput"):
            summary = "; ".join(f"{r['springs']:,}: {r['gpu_rate_fused'] / 1e9:.2f} fused / "
                                f"{r['gpu_rate_two_launch'] / 1e9:.2f} two launches G/s, "
                                f"{r['bandwidth_fraction']:.0%} of copy" for r in p.get("rows", []))
        elif p["name"].startswith("conduction cost"):
            summary = "; ".join(f"{s} {launch} {run}: {ratio}" for s, launch, run, ratio in p.get("rows", [])
                                if run != "adiabatic")
        elif p["rc"] != 0:
            summary = p["out"].strip().splitlines()[-1][:200] if p["out"].strip() else ""
        else:
            summary = "ran"
        print(f"| {p['name']} | {p['rc']} | {p['seconds']:.0f} | {summary} |")


if __name__ == "__main__":
    parts = main()
    sys.exit(0 if all(p["rc"] == 0 for p in parts) else 1)
