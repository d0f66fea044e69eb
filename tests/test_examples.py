"""Each example in its smoke mode, with one key number pinned."""

import importlib.util
import pathlib

import numpy as np
import pytest

EXAMPLES = pathlib.Path(__file__).resolve().parent.parent / "examples"


def load(name):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def pngs(folder):
    return sorted(p.name for p in pathlib.Path(folder).glob("*.png"))


def test_paper_chain_smoke(tmp_path):
    numbers = load("paper_chain").main(["--smoke", "--out", str(tmp_path)])
    assert numbers["initial_energy"] == pytest.approx(7983.333333333333, abs=1e-9)
    assert abs(numbers["slopes"]["co2/position"] - 2.0) < 0.15
    assert numbers["energy"]["co2"]["entropy_change"] == 0.0
    for fig in ("fig06", "fig07", "fig08", "fig09", "fig10", "fig11", "fig12", "fig13", "fig14", "fig15a", "fig15b", "fig15c"):
        assert any(name.startswith(fig) for name in pngs(tmp_path)), fig


def test_paper_net_smoke(tmp_path):
    numbers = load("paper_net").main(["--smoke", "--out", str(tmp_path)])
    assert numbers["py"] == 5.0 and numbers["py_change"] < 1e-12        # the paper's e2 momentum
    assert numbers["entropy_change"] == 0.0
    assert 965.0 < numbers["temperature_range"][0] < 975.0 and numbers["temperature_range"][1] < 1001.0
    assert len(pngs(tmp_path)) == 3


def test_pendulum_smoke_matches_the_polar_ode(tmp_path):
    numbers = load("pendulum").main(["--smoke", "--out", str(tmp_path)])
    assert numbers["theta_range"][1] == pytest.approx(308.237, abs=1e-3)
    assert numbers["co2"]["r"] < 1e-3 and numbers["co4"]["r"] < 3e-5
    assert len(pngs(tmp_path)) == 3


def test_large_net_smoke(tmp_path):
    pytest.importorskip("gmsh")
    numbers = load("large_net").main(["--smoke", "--out", str(tmp_path)])
    summary = numbers["summary"]
    assert numbers["n_springs"] > 1000
    assert summary["entropy"]["max_deviation"] == 0.0
    assert summary["energy"]["relative"] < 1e-4
    assert np.isfinite(numbers["theta_range"]).all()
    assert len(pngs(tmp_path)) == 2


def test_steel_bracket_smoke(tmp_path):
    """The steel part with EM2 at ~2 500× CO2's stable step: its run, ParaView series and plot;
    whole steps on the factorized path, the energy balance at round-off."""
    numbers = load("steel_bracket").main(["--smoke", "--out", str(tmp_path)])
    assert numbers["steps"] == 20 and numbers["springs"] == 2738
    assert numbers["newton"]["linear_solver"] == "splu-reuse" and numbers["newton"]["substep_fraction"] == 0.0
    assert 293.15 < numbers["theta_max"] < 294.0 and numbers["heat"] > 0.0   # the bath ramps up 2 K in 20 ms
    assert numbers["energy_balance"] < 1e-9 * numbers["heat"]                # measured 1.8e-12 J of 0.27 J
    assert (tmp_path / "run" / "steel_bracket.pvd").exists() and pngs(tmp_path) == ["steel_bracket.png"]
