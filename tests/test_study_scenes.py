"""Studies of scene files as a user writes them: heat flow and loads in the reference, the
scene's own step and end, messages that add up, and a Dask study from a cold Numba cache."""

import csv
import os
import subprocess
import sys
import warnings

import pytest

from thermonet.cli.main import main

from cli_helpers import one_error_line

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = os.path.join(ROOT, "scenes")
#: a free jittered lattice of 27 nodes, thermal coupling on: Hamilton's equations alone
TINY = """name = "tiny"
[net]
generator = "lattice"
lattice = { shape = [3, 3, 3], spacing = 0.5, neighbours = 18, jitter = 0.05, seed = 3 }
[materials.all]
c = 20.0
beta = 0.1
C0 = 1.0
theta0 = 300.0
[initial.velocity]
random = { amplitude = 0.05, seed = 11 }
[initial.mass]
uniform = 0.1
[integrator]
h = 0.01
t_end = 0.08
"""


def slopes(folder) -> dict:
    with open(os.path.join(folder, "slopes.csv")) as f:
        return {(r["integrator"], r["quantity"]): float(r["slope"]) for r in csv.DictReader(f)}


@pytest.mark.parametrize("scene, argv, named", [
    ("thermal_shock.toml", ["--t-end", "0.4", "--halvings", "3"], "conduction, baths (hot)"),
    ("tensile.toml", ["--t-end", "0.1", "--halvings", "2"], "loads (pull)"),
])
def test_a_convergence_study_of_a_scene_with_heat_flow_or_loads_includes_them_and_finds_order_2(
        tmp_path, capsys, scene, argv, named):
    out = tmp_path / "study"
    assert main(["study", "convergence", os.path.join(SCENES, scene), "--serial", "--integrators", "co2",
                 *argv, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "reference co4 h=" in text and f"(the scene's {named} are not in Hamilton's equations" in text
    assert "DOP853 rtol" not in text and " no position slope" not in text
    assert ("every integrator is second order with it" in text) == ("conduction" in named)
    fitted = slopes(out)
    for quantity in ("position", "momentum", "temperature"):
        assert abs(fitted[("co2", quantity)] - 2.0) < 0.1, (quantity, fitted)


def test_a_study_uses_the_scene_s_own_step_and_end(tmp_path, capsys):
    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY)
    out = tmp_path / "study"
    assert main(["study", "convergence", str(scene), "--serial", "--integrators", "co2", "--halvings", "2",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "time steps 0.01·2^-i, i = 0..2, to t = 0.08; reference checked against co6" in text
    assert "errors at t = 0.08" in text and abs(slopes(out)[("co2", "position")] - 2.0) < 0.1
    # the energy study: the scene's h and t_end too (8 steps)
    assert main(["study", "energy", str(scene), "--serial", "--integrators", "co2", "--out", str(tmp_path / "e")]) == 0
    with open(tmp_path / "e" / "history_co2.csv") as f:
        rows = list(csv.DictReader(f))
    assert float(rows[-1]["time"]) == pytest.approx(0.08) and len({r["time"] for r in rows}) == 9


def test_studies_refuse_in_one_line_what_they_cannot_measure(tmp_path, capsys):
    shock = os.path.join(SCENES, "thermal_shock.toml")
    assert main(["study", "energy", shock, "--serial"]) == 2
    assert "its baths (hot) exchange energy with the outside" in one_error_line(capsys.readouterr().err)
    assert main(["study", "convergence", shock, "--serial", "--check", "none"]) == 2
    assert "--check none: the scene has conduction, baths (hot)" in one_error_line(capsys.readouterr().err)


def test_why_a_slope_is_missing_counts_each_point_once():
    from thermonet.studies.convergence import unfitted_reason
    from thermonet.studies.slopes import asymptotic_slope

    h = [0.1, 0.05, 0.025]
    reason = unfitted_reason(h, [1.0, 0.5, 1e-12], floor=1e-9, scale=2.0)
    assert reason.startswith("0 usable points of 3 (2 needed)")
    assert "1 at or below the reference's floor" in reason and "2 with errors ≥ 0.1" in reason
    # a quantity of size 0 (momenta of a net at rest) has no relative criterion
    assert "size 0" not in unfitted_reason(h, [1e-12, 1e-13, 1e-14], floor=1e-9, scale=0.0)
    assert asymptotic_slope(h, [4e-4, 1e-4, 2.5e-5], floor=1e-9, scale=0.0).slope == pytest.approx(2.0)


def test_the_cost_summary_says_how_much_slower_in_words():
    from thermonet.studies.cost import _slower

    assert _slower(1.02) == "takes about as long" and _slower(83.4) == "is 83 times slower"
    assert _slower(1.4) == "is 1.4 times slower"


def test_a_dask_study_from_a_partly_cold_numba_cache_runs(tmp_path):
    """The console script's main module imports Numba before a Dask worker sets
    NUMBA_NUM_THREADS=1; the first run launched Numba's threads at the core count, and the first
    function compiled after that (here: the SciPy baseline's compiled right-hand side, which the
    run that warmed the cache never needed) made Numba raise. A mechanical scene: the cheapest
    kernel to warm the cache with."""
    if (os.cpu_count() or 1) < 2:
        pytest.skip("with one core Numba's default thread count is already 1")
    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY + "[effects]\nthermal = false\n")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"), PYTHONPATH=ROOT)
    cli = [sys.executable, "-m", "thermonet.cli.main"]
    subprocess.run(cli + ["run", str(scene), "--quiet", "--set", "integrator.steps=2", "--out", str(tmp_path / "run")],
                   env=env, check=True, capture_output=True, cwd=tmp_path)
    done = subprocess.run(cli + ["study", "cost", str(scene), "--integrators", "co2", "--halvings", "0",
                                 "--repeats", "1", "--scipy", "DOP853:1e-6..1e-6", "--check", "none", "--workers", "1",
                                 "--quiet", "--out", str(tmp_path / "study")],
                          env=env, capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr[-3000:]
    with open(tmp_path / "study" / "cost.csv") as f:
        rows = list(csv.DictReader(f))
    assert [(r["solver"], r["status"]) for r in rows] == [("co2", "ok"), ("scipy-DOP853", "ok")]
    # the SciPy run solved the mechanical net's equations (springs held at θ0) to its tolerance
    assert float(rows[1]["error_position"]) < 1e-5 and float(rows[1]["error_temperature"]) == 0.0


def test_a_study_of_a_mechanical_scene_leaves_out_the_implicit_integrators_and_says_why(tmp_path, capsys):
    """Without thermal coupling the default integrators that need it (the implicit ones) are left
    out, named; SciPy's reference solves the mechanical equations (springs at θ0), so CO2's
    positions converge at order 2 and the temperatures, held, have no slope to fit."""
    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY + "[effects]\nthermal = false\n")
    out = tmp_path / "study"
    assert main(["study", "convergence", str(scene), "--serial", "--halvings", "2", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "(left out gtr-1/2, ho4: implicit integrators need thermal coupling, which the scene switches off)" in text
    assert "no temperature slopes: every run's temperature equals the reference's exactly" in text
    assert "no temperature slope for" not in text
    fitted = slopes(out)
    assert {name for name, _ in fitted} == {"gtr-0", "gtr-1", "co2", "co4", "omf4"}
    assert abs(fitted[("co2", "position")] - 2.0) < 0.1 and abs(fitted[("co4", "position")] - 4.0) < 0.2
    # an implicit integrator named on the command line is refused, with the reason
    assert main(["study", "convergence", str(scene), "--serial", "--integrators", "ho4", "--out", str(out)]) == 2
    assert "tiny.toml: integrator ho4 needs thermal coupling" in capsys.readouterr().err
    # the energy study: no entropy to report (a dash, not nan) or to draw (no empty legend)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        assert main(["study", "energy", str(scene), "--serial", "--integrators", "co2", "--out",
                     str(tmp_path / "energy")]) == 0
    (row,) = [line.split() for line in capsys.readouterr().out.splitlines() if line.startswith("  co2 ")]
    # (row[2], the zoom window's range, is nan: 0.08 s of run has no diagnostics row in it)
    assert row[4] == "—" and "nan" not in (row[1], row[3], row[5], row[6])


def test_the_default_study_integrators_include_the_methods_the_readme_recommends():
    import re

    from thermonet.cli.study import DEFAULT_INTEGRATORS

    readme = open(os.path.join(ROOT, "README.md")).read()
    (fourth, sixth), = re.findall(r"\*\*`(\w+)` is the 4th-order and `(\w+)` the 6th-order method to use\*\*", readme)
    assert fourth in DEFAULT_INTEGRATORS["convergence"].split(",")
    assert {fourth, sixth} <= set(DEFAULT_INTEGRATORS["cost"].split(","))


def test_a_cost_study_of_a_scene_with_a_bath_has_no_scipy_baseline_and_says_why(tmp_path, capsys):
    out = tmp_path / "cost"
    assert main(["study", "cost", os.path.join(SCENES, "thermal_shock.toml"), "--serial", "--integrators", "co2",
                 "--halvings", "2", "--repeats", "1", "--t-end", "0.2", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "no SciPy baseline: it solves Hamilton's equations, which leave out the scene's conduction, baths (hot)" in text
    assert "the cheapest is CO2" in text and "SciPy's cheapest" not in text
    with open(out / "cost.csv") as f:
        assert {r["solver"] for r in csv.DictReader(f)} == {"co2"}
