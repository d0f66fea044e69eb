"""``[loads.<name>]`` scene tables: built into the same objects as the API, errors at file:line."""

import numpy as np
import pytest

from thermonet.errors import InputError
from thermonet.scenes.scene import scene_from_text

BASE = """
[net]
generator = "lattice"
[net.lattice]
shape = [3, 1, 0]
[effects]
anchors = ["xmin"]
[integrator]
h = 1e-3
steps = 50
"""


def built(loads: str):
    return scene_from_text(BASE + loads, file="pull.toml").build()


def test_a_scene_drive_and_force_run_like_the_api_objects():
    import thermonet as tn
    from thermonet.loads import Drive, Force

    text = """
[loads.pull]
type = "drive"
group = "xmax"
displacement = { x = { end = 0.1, duration = 0.5 } }
[loads.push]
type = "force"
group = "ymax"
force = { amplitude = 0.5, frequency = 3.0 }
direction = [0, 2, 0]
total = true
"""
    sim = built(text).simulation
    api = tn.Simulation(sim.net, h=1e-3, loads={
        "pull": Drive("xmax", {"x": {"end": 0.1, "duration": 0.5}}),
        "push": Force("ymax", {"amplitude": 0.5, "frequency": 3.0}, direction=[0, 1, 0], total=True)})
    sim.run(steps=50, diagnostics_every=10)
    api.run(steps=50, diagnostics_every=10)
    np.testing.assert_array_equal(sim.state.positions, api.state.positions)
    assert {"pull_Rx", "pull_work", "push_Fy", "work", "energy_balance"} <= set(sim.diagnostics.columns)


@pytest.mark.parametrize("loads, line, message", [
    ('[loads.pull]\ntype = "drive"\ngroup = "xmin"\nvelocity = [1, 0, 0]\n', 13, r"loads\.pull\.group: node 0 is anchored"),
    ('[loads.pull]\ntype = "drive"\ngroup = "xmax"\n\ndisplacement = { x = { table = [[0, 0], [1, 1], [0.5, 2]] } }\n',
     15, r"loads\.pull\.displacement\.x\.table: times must increase strictly"),
    ('[loads.push]\ntype = "force"\ngroup = "nowhere"\nforce = 1.0\ndirection = [1, 0, 0]\n', 13,
     r"loads\.push\.group: no node group 'nowhere'"),
    ('[loads.pull]\ntype = "drive"\ngroup = []\nvelocity = [1, 0, 0]\n', 13, r"loads\.pull\.group: the group has no nodes"),
    ('[loads.pull]\ntype = "drive"\ngroup = "xmax"\nvelocity = [1, 0, 0]\ntotal = true\n', 15,
     r"loads\.pull\.total: total belongs to a force"),
    ('[loads.pull]\ntype = "push"\ngroup = "xmax"\n', 12, r"loads\.pull\.type: must be one of drive, force"),
])
def test_bad_scene_loads_name_the_file_line_and_key(loads, line, message):
    with pytest.raises(InputError, match=rf"pull\.toml:{line}: {message}"):
        built(loads)


def test_info_lists_the_loads(tmp_path, capsys):
    from thermonet.cli.main import main

    scene = tmp_path / "pull.toml"
    scene.write_text(BASE + '[loads.pull]\ntype = "drive"\ngroup = "xmax"\nvelocity = [0.1, 0, 0]\nfree = true\n'
                     '[loads.push]\ntype = "force"\ngroup = [5]\nforce = { y = 2.0 }\n')
    assert main(["info", str(scene)]) == 0
    out = capsys.readouterr().out
    assert "loads (2):" in out
    assert "pull: drive on 2 nodes" in out and "other axes free" in out
    assert "push: force (per node) on 1 nodes; f = {y: 2}" in out and "<" not in out
