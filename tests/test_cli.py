"""The thermonet command: run (default scene, outputs, resume bit for bit), info, render, errors."""

import io
import json
import os

import numpy as np
import pytest

from thermonet.cli.main import main
from thermonet.cli.progress import ProgressBar
from thermonet.io import load_checkpoint, read_pvd

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LATTICE = os.path.join(ROOT, "scenes", "spinning_lattice.toml")
RUN = ["--quiet", "--set", "integrator.steps=300", "--set", "output.frames_every=40",
       "--set", "output.diagnostics_every=10", "--set", "output.checkpoint_every=100"]


def test_run_without_a_scene_runs_the_default_3d_scene(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "--t-end", "0.02", "--set", "output.frames_every=50"]) == 0
    out = tmp_path / "thermonet-out" / "truss_block"
    assert len(read_pvd(out / "truss_block.pvd")) == 3  # steps 0, 50, 100
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 100 and summary["springs"] == 2492 and len(summary["scene_hash"]) == 64
    assert summary["conserved"]["entropy"]["max_deviation"] == 0.0
    assert {"initial", "max_deviation"} <= set(summary["conserved"]["energy"])
    assert summary["steps_per_s"] > 0 and "numpy" in summary["versions"]
    text = capsys.readouterr().out
    assert "energy" in text and "steps/s" in text and "truss_block.pvd (3 frames)" in text


def test_resume_from_a_mid_run_checkpoint_is_bit_for_bit_the_uninterrupted_run(tmp_path, monkeypatch):
    from thermonet.io import series

    whole, cut = tmp_path / "whole", tmp_path / "cut"
    assert main(["run", LATTICE, "--out", str(whole), *RUN]) == 0

    real = series.RunOutput.write_frame

    def dies_at_step_240(self, sim):
        if sim.step == 240:
            raise KeyboardInterrupt
        real(self, sim)

    monkeypatch.setattr(series.RunOutput, "write_frame", dies_at_step_240)
    assert main(["run", LATTICE, "--out", str(cut), *RUN]) == 130
    monkeypatch.undo()
    state, _ = load_checkpoint(cut / "spinning_lattice.checkpoint.npz")
    assert state.step == 200
    assert main(["run", "--resume", str(cut / "spinning_lattice.checkpoint.npz"), "--quiet"]) == 0

    names = sorted(os.listdir(whole))
    assert names == sorted(os.listdir(cut))
    for name in names:
        if name.endswith((".vtu", ".pvd", ".csv")):
            assert (whole / name).read_bytes() == (cut / name).read_bytes(), name
    a, _ = load_checkpoint(whole / "spinning_lattice.checkpoint.npz")
    b, _ = load_checkpoint(cut / "spinning_lattice.checkpoint.npz")
    for k in ("positions", "momenta", "entropy", "thermal_displacement"):
        np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    assert (a.step, a.time) == (b.step, b.time) == (300, a.time)
    assert len(read_pvd(cut / "spinning_lattice.pvd")) == 9  # 0, 40, ..., 280, 300


def test_resume_refuses_a_checkpoint_of_another_scene(tmp_path, capsys):
    assert main(["run", LATTICE, "--out", str(tmp_path), *RUN]) == 0
    code = main(["run", LATTICE, "--resume", str(tmp_path), "--set", "materials.all.c=21.0", "--quiet"])
    assert code == 2
    assert "written by a different scene" in capsys.readouterr().err


def test_a_bad_scene_is_one_line_with_file_and_line(tmp_path, capsys):
    bad = os.path.join(ROOT, "tests", "scenes_bad", "wrong_type.toml")
    assert main(["run", bad, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"thermonet: error: {bad}:5: integrator.h:")
    with pytest.raises(Exception):
        main(["--debug", "run", bad, "--out", str(tmp_path)])
    with pytest.raises(Exception):
        main(["run", bad, "--debug", "--out", str(tmp_path)])


def test_info_describes_meshes_and_scenes(capsys):
    assert main(["info", os.path.join(ROOT, "meshes", "truss_block.msh")]) == 0
    text = capsys.readouterr().out
    assert "491 nodes, 2492 springs" in text and "tetra" in text and "clamp (31)" in text
    assert "memory" in text and "h_max" in text
    assert main(["info", os.path.join(ROOT, "scenes", "default.toml")]) == 0
    text = capsys.readouterr().out
    assert "0: soft" in text and "1: stiff" in text and "h_max" in text and "31 anchored" in text


def test_render_writes_a_picture(tmp_path):
    pytest.importorskip("pyvista")
    assert main(["run", LATTICE, "--out", str(tmp_path), "--quiet", "--set", "integrator.steps=20"]) == 0
    png = tmp_path / "pic.png"
    assert main(["render", str(tmp_path), "--png", str(png), "--size", "320x240"]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_render_without_pyvista_says_how_to_get_it(tmp_path, monkeypatch, capsys):
    import sys

    monkeypatch.setitem(sys.modules, "pyvista", None)
    assert main(["render", str(tmp_path)]) == 2
    assert "pip install 'thermonet[vis]'" in capsys.readouterr().err


def test_progress_bar_shows_rate_and_eta():
    stream = io.StringIO()
    bar = ProgressBar(stream=stream, delay=0.0, interval=0.0)
    bar(250, 1000, 2.0)
    line = stream.getvalue()
    assert "25.0%" in line and "step 250/1000" in line and "125 steps/s" in line and "ETA 0:06" in line


def test_python_dash_m_thermonet_is_the_command():
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "thermonet", "info", "scenes/chain.toml"], capture_output=True,
                          text=True, cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))), timeout=300)
    assert done.returncode == 0, done.stderr
    assert "springs" in done.stdout
