import numpy as np

import thermonet as tn


def test_chain_initial_energy_is_the_papers():
    sim = tn.chain_simulation("co2", h=0.01)
    sim.run(steps=0)
    assert abs(sim.diagnostics.energy[0] - 7983.333333333333) < 1e-9


def test_cli_default_runs(tmp_path):
    from thermonet.cli.main import main

    assert main(["run", "--out", str(tmp_path), "--quiet", "--t-end", "0.1"]) == 0
    assert (tmp_path / "diagnostics.csv").exists()
    data = np.genfromtxt(tmp_path / "diagnostics.csv", delimiter=",", names=True)
    assert data["time"][-1] == 0.1 or abs(data["time"][-1] - 0.1) < 1e-12
