"""Probes (per-group mean/min/max series, probe_<name>.csv) and ``thermonet plot``."""

import os

import numpy as np
import pytest

import thermonet as tn
from thermonet.cli.main import main
from thermonet.errors import InputError
from thermonet.loads import Drive
from thermonet.probes import Probe, Probes, read_probe_csv

SCENE = """
[net]
generator = "lattice"
[net.lattice]
shape = [4, 2, 0]
[effects]
anchors = ["xmin"]
[loads.pull]
type = "drive"
group = "xmax"
velocity = [0.2, 0, 0]
[probes.cold]
group = "ymin"
quantity = "temperature"
every = 10
[probes.grip]
group = "xmax"
quantity = "displacement"
[integrator]
h = 1e-3
steps = 60
[output]
frames_every = 0
diagnostics_every = 20
checkpoint_every = 30
"""


def test_a_probe_row_is_the_mean_min_and_max_over_its_group():
    from thermonet.scenes.build import _lattice_faces

    net = tn.lattice((3, 2, 0))
    net.node_groups.update(_lattice_faces(net.positions, 1.0))
    sim = tn.Simulation(net, h=1e-3, loads={"pull": Drive("xmax", velocity=[0.3, 0, 0])})
    probes = Probes(sim, {"t": Probe("ymin", "temperature", every=5), "s": Probe([0, 3, 4], "strain"),
                          "u": Probe("xmax", "displacement")})
    sim.run(steps=20, diagnostics_every=10, observers=probes.observers(10))
    nodes = np.zeros(net.n_nodes, dtype=bool)
    nodes[net.node_groups["ymin"]] = True
    springs = np.flatnonzero(nodes[net.edges].all(axis=1))
    theta = sim.temperatures()[springs]
    assert [r[0] for r in probes.series["t"]] == [0, 5, 10, 15, 20]
    assert probes.series["t"][-1][2:] == (theta.mean(), theta.min(), theta.max())
    assert theta.min() < theta.max() < 300.0  # the pulled net cooled, unevenly
    strain = sim.strains()[[0, 3, 4]]
    assert probes.series["s"][-1][2:] == (strain.mean(), strain.min(), strain.max())
    assert probes.series["u"][-1][2] == pytest.approx(0.3 * 0.02, rel=1e-12)


@pytest.mark.parametrize("probe, message", [
    (Probe("nowhere", "tension"), r"probes\.p\.group: no spring or node group 'nowhere'"),
    (Probe("xmax", "pressure"), r"probes\.p\.quantity: must be one of"),
    (Probe([10_000], "displacement"), r"probes\.p\.group: node index 10000 is out of range"),
])
def test_bad_probes_name_the_key(probe, message):
    sim = tn.Simulation(tn.lattice((2, 2, 0)), h=1e-3)
    with pytest.raises(InputError, match=message):
        Probes(sim, {"p": probe})


def test_run_writes_probe_csvs_resume_keeps_them_and_plot_draws_everything(tmp_path):
    scene = tmp_path / "pull.toml"
    scene.write_text(SCENE)
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    assert main(["run", str(scene), "--quiet", "--out", str(whole)]) == 0
    cold = read_probe_csv(str(whole / "probe_cold.csv"))
    assert list(cold["step"]) == list(range(0, 61, 10)) and np.all(np.diff(cold["mean"]) < 0)
    assert main(["run", str(scene), "--quiet", "--out", str(cut), "--set", "integrator.steps=30"]) == 0
    assert main(["run", "--resume", str(cut), "--quiet", "--set", "integrator.steps=60"]) == 0
    for name in ("probe_cold.csv", "probe_grip.csv"):  # the same rows, bit for bit, and one at the cut's end
        rows = set((cut / name).read_text().splitlines())
        assert set((whole / name).read_text().splitlines()) <= rows
        assert all(r.startswith("30,") for r in rows - set((whole / name).read_text().splitlines()))
    # the loads' work came back from the checkpoint: the last diagnostics row (work, balance) is the same
    assert (whole / "diagnostics.csv").read_text().splitlines()[-1] == (cut / "diagnostics.csv").read_text().splitlines()[-1]
    assert main(["plot", str(whole)]) == 0
    pngs = sorted(os.listdir(whole / "plots"))
    assert pngs == ["energy.png", "entropy.png", "load_pull.png", "momenta.png", "probe_cold.png", "probe_grip.png"]


def test_plot_names_a_folder_without_diagnostics(tmp_path, capsys):
    assert main(["plot", str(tmp_path)]) == 2
    assert "no diagnostics.csv" in capsys.readouterr().err
