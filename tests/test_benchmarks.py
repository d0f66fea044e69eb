"""Every benchmark with a quick mode runs here, so that none can rot (speed is measured in
benchmarks/, not here: these check that the scripts run and report sane numbers)."""

import importlib.util
import math
import pathlib

ROOT = pathlib.Path(__file__).resolve().parent.parent


def load(name: str):
    spec = importlib.util.spec_from_file_location(f"benchmark_{name}", ROOT / "benchmarks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_heat_cost_quick_mode_runs_and_reports_the_conduction_cycle(capsys):
    rows, parts = load("heat_cost").main(["--quick"])
    assert {r["net"].split()[0] for r in rows} == {"lattice", "gmsh"}
    for r in rows:
        assert all(math.isfinite(r[k]) and r[k] > 0 for k in ("adiabatic", "conduction", "schedule", "sweeps", "auto"))
        assert r["colours"] >= 1 and r["gpu_pair_phases"] > r["gpu_star_phases"] > 0
    steel, shock = parts
    # the steel part at its explicit stable step: heat is slow, conduction runs every many steps
    assert steel["k"] >= 10 and "auto: fastest conduction rate" in steel["why"]
    assert shock["k"] >= 1 and shock["springs"] == 673
    text = capsys.readouterr().out
    assert "| steel bracket" in text and "| scenes/thermal_shock.toml" in text


def test_gpu_heat_cost_quick_mode_runs_under_the_cuda_simulator():
    import importlib.util
    import os
    import subprocess
    import sys

    import pytest

    if importlib.util.find_spec("numba_cuda") is None:
        pytest.skip("numba-cuda is not installed (pip install '.[cuda]')")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "gpu_heat_cost.py"), "--quick"], env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    rows = [line for line in done.stdout.splitlines() if line.startswith("| 54 |")]
    assert len(rows) == 6  # two launch modes × adiabatic, every step, "auto"'s k
    assert all(float(r.split("|")[5].strip().rstrip("×")) > 0 for r in rows)
    # conduction's phases per half sweep on the GPU: the lattice's node colours + 3
    assert all(r.split("|")[6].strip() in ("–", "5") for r in rows)
