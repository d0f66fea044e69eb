"""The shipped tensile test (scenes/tensile.toml, meshes/dogbone.msh, examples/tensile_test.py)."""

import importlib.util
import pathlib

import numpy as np

EXAMPLE = pathlib.Path(__file__).resolve().parent.parent / "examples" / "tensile_test.py"


def test_the_tensile_example_pulls_the_gauge_cools_as_the_closed_form_says_and_warms_back_with_conduction(tmp_path):
    spec = importlib.util.spec_from_file_location("example_tensile_test", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    n = module.main(["--smoke", "--out", str(tmp_path)])
    assert abs(n["pull"] - 0.15) < 1e-12 and n["force"] > 0.0
    assert n["gauge_strain"] > 0.0 and n["gauge_theta_drop"] > 0.0
    # the springs along the pull are stretched at constant entropy (no kick, drive or force ever
    # writes η): θ0 exp(−βL/C0) at their current strain, to round-off
    assert n["along_theta_drop"] > 0.5 and n["along_theta_error"] < 1e-9 * n["along_theta_drop"]
    assert n["balance_relative"] < 1e-5
    # with conduction and the grips as baths at 300 K, heat flows in and the gauge cools less
    assert n["heat_in"] > 0.0 and 0.0 < n["conducting_theta_drop"] < 0.9 * n["gauge_theta_drop"]
    assert n["conducting_balance_relative"] < 1e-5
    assert sorted(p.name for p in tmp_path.glob("*.png")) == ["tensile_gauge.png", "tensile_load_displacement.png",
                                                              "tensile_warming.png"]
