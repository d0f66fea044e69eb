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


def test_gpu_check_quick_mode_runs_its_benchmarks_under_the_cuda_simulator(monkeypatch, capsys):
    """benchmarks/gpu_check.py --quick: gpu_throughput.py and gpu_heat_cost.py in their quick modes
    (subprocesses under Numba's CUDA simulator), their rows read back into the one table."""
    import importlib.util

    import pytest

    if importlib.util.find_spec("numba_cuda") is None:
        pytest.skip("numba-cuda is not installed (pip install '.[cuda]')")
    monkeypatch.setenv("NUMBA_ENABLE_CUDASIM", "1")
    parts = load("gpu_check").main(["--quick"])
    assert [p["name"] for p in parts] == ["throughput (this tree)", "conduction cost (this tree)"]
    assert all(p["rc"] == 0 for p in parts), [p["out"][-2000:] for p in parts]
    throughput, heat = parts
    (row,) = throughput["rows"]  # the quick mode's one tiny lattice
    assert row["springs"] == 144 and row["nodes"] == 64
    assert row["gpu_rate_fused"] > 0 and row["gpu_rate_two_launch"] > 0
    assert 100 < row["bytes_per_spring_step"] < 150 and row["device_bytes_per_spring"] > 0
    assert "max relative difference 0.00e+00" in throughput["out"]  # the simulator runs the CPU's operations
    # two launch modes × adiabatic, every step, "auto"'s k; conduction's phases per half sweep
    # on the GPU: the lattice's node colours + 3
    table = [line for line in heat["out"].splitlines() if line.startswith("| 54 |")]
    assert len(table) == 6 and len(heat["rows"]) == 6
    assert all(float(r.split("|")[5].strip().rstrip("×")) > 0 for r in table)
    assert all(r.split("|")[6].strip() in ("–", "5") for r in table)
    out = capsys.readouterr().out
    assert "## GPU check" in out and "| throughput (this tree) | 0 |" in out
