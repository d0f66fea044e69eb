"""What a new user hits on first use: a previous run deleted before its replacement was checked,
a wheel without its default scene, the quick start run twice, runs that are not reproducible.

Each test reproduces the failure as it was met and asserts the wanted behaviour: exit codes,
one-line messages naming the file, key or step, and the files left on disk.
"""

import os
import re

import numpy as np
import pytest

from thermonet.cli.main import main

from cli_helpers import one_error_line, snapshot

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MESHES = os.path.join(ROOT, "meshes")
#: the thermal shock scene, small: conduction, a bath, a few steps
SHOCK = f"""name = "shock"
[net]
mesh = "{MESHES}/thermal_bar.msh"
cells = ["tetra"]
[materials.bar]
c = 100.0
beta = 0.002
C0 = 1.0
theta0 = 300.0
g = 4.0
[effects]
conduction = true
anchors = []
[baths.hot]
group = "hot_end"
temperature = 900.0
[integrator]
name = "co2"
h = 0.01
steps = 12
[output]
frames_every = 4
diagnostics_every = 2
checkpoint_every = 6
"""


# ----------------------------------------------------------------------------------------------
# --overwrite deletes nothing until the new run is built and checked

BROKEN = {
    "missing mesh": (SHOCK.replace("thermal_bar.msh", "no_such_mesh.msh"), "does not exist"),
    "bath group typo": (SHOCK.replace('group = "hot_end"', 'group = "hot_edn"'), "hot_edn"),
    "infinite bath temperature": (SHOCK.replace("temperature = 900.0", "temperature = inf"), "baths.hot.temperature"),
    "integrator option typo": (SHOCK.replace('name = "co2"', 'name = "co2"\noptions = { tolerence = 1e-10 }'),
                               "tolerence"),
    "step above the stability limit": (SHOCK.replace("h = 0.01", "h = 5.0"), "integrator.h"),
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_overwrite_keeps_the_previous_run_when_the_new_scene_fails_its_checks(tmp_path, capsys, case):
    good = tmp_path / "good.toml"
    good.write_text(SHOCK)
    out = tmp_path / "keep"
    assert main(["run", str(good), "--out", str(out), "--quiet"]) == 0
    before = snapshot(out)
    assert len(before) >= 6
    capsys.readouterr()
    text, named = BROKEN[case]
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    assert main(["run", str(bad), "--out", str(out), "--overwrite", "--quiet"]) == 2
    assert named in one_error_line(capsys.readouterr().err)
    assert snapshot(out) == before


# ----------------------------------------------------------------------------------------------
# a wheel carries the default scene and its mesh


def test_the_packaged_default_scene_is_the_source_tree_s_default_scene():
    from thermonet.scenes import DEFAULT_SCENE

    packaged = open(DEFAULT_SCENE).read().splitlines()
    source = open(os.path.join(ROOT, "scenes", "default.toml")).read().splitlines()
    keys = lambda lines: [re.sub(r"\s*#.*", "", l) for l in lines if l.strip() and not l.startswith("#")]  # noqa: E731
    assert [l for l in keys(packaged) if not l.startswith("mesh")] == [l for l in keys(source) if not l.startswith("mesh")]
    assert 'mesh = "truss_block.msh"' in keys(packaged)
    with open(os.path.join(os.path.dirname(DEFAULT_SCENE), "truss_block.msh"), "rb") as a, \
            open(os.path.join(MESHES, "truss_block.msh"), "rb") as b:
        assert a.read() == b.read()


def test_a_built_wheel_installed_in_a_fresh_venv_runs_the_default_scene_from_another_folder(tmp_path):
    import shutil
    import subprocess
    import sys
    import venv

    src = tmp_path / "src"
    shutil.copytree(os.path.join(ROOT, "thermonet"), src / "thermonet",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(os.path.join(ROOT, name), src / name)
    dist = tmp_path / "dist"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), str(src)],
                   check=True, capture_output=True, cwd=tmp_path)
    (wheel,) = dist.glob("thermonet-*.whl")
    # numpy, numba, ... from this interpreter's site packages; thermonet only from the wheel
    venv.create(tmp_path / "venv", system_site_packages=True, with_pip=False)
    python = str(tmp_path / "venv" / "bin" / "python")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    subprocess.run([sys.executable, "-m", "pip", "--python", python, "install", "-q", "--no-index", "--no-deps",
                    "--ignore-installed", str(wheel)], check=True, capture_output=True, env=env)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    where = subprocess.run([python, "-c", "import thermonet; print(thermonet.__file__)"], cwd=elsewhere, env=env,
                           check=True, capture_output=True, text=True).stdout
    assert where.startswith(str(tmp_path / "venv")), where
    done = subprocess.run([python, "-m", "thermonet.cli.main", "run", "--set", "integrator.steps=10"],
                          cwd=elsewhere, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    out = elsewhere / "thermonet-out" / "truss_block"
    assert {"truss_block.pvd", "diagnostics.csv", "summary.json"} <= set(os.listdir(out))


# ----------------------------------------------------------------------------------------------
# the quick start run twice: the second run goes to a fresh folder and says where


def test_a_run_without_out_goes_to_a_fresh_numbered_folder_and_says_where(tmp_path, monkeypatch, capsys):
    scene = tmp_path / "shock.toml"
    scene.write_text(SHOCK)
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    assert main(["run", str(scene)]) == 0
    first = snapshot(work / "thermonet-out" / "shock")
    assert "shock.pvd" in first and "diagnostics written to thermonet-out/shock\n" in capsys.readouterr().out
    assert main(["run", str(scene)]) == 0
    captured = capsys.readouterr()
    assert ("thermonet: thermonet-out/shock holds a previous run: writing to thermonet-out/shock-2"
            in captured.err)
    assert "diagnostics written to thermonet-out/shock-2\n" in captured.out
    assert snapshot(work / "thermonet-out" / "shock") == first
    assert "summary.json" in os.listdir(work / "thermonet-out" / "shock-2")
    (work / "thermonet-out" / "shock-3").write_text("a file, not a folder")
    assert main(["run", str(scene), "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    assert "summary.json" in os.listdir(work / "thermonet-out" / "shock-4")
    # --out is the user's choice: a previous run there is refused, not sidestepped
    assert main(["run", str(scene), "--out", "thermonet-out/shock"]) == 2
    assert "holds the output of a previous run" in one_error_line(capsys.readouterr().err)


# ----------------------------------------------------------------------------------------------
# reproducibility: the stable step and a whole run, twice


def test_stable_step_of_two_identical_simulations_is_the_same_number():
    import thermonet as tn
    from thermonet.stability import stable_step

    def simulation():
        net = tn.lattice((5, 5, 5), jitter=0.05, seed=3)  # 648 free coordinates: the Lanczos path
        return tn.Simulation(net, model="hencky", parameters=dict(c=100.0, beta=0.1, C0=1.0, theta0=300.0),
                             temperatures=300.0, integrator="co2", h=0.001)

    estimates = [stable_step(simulation()) for _ in range(4)]
    assert "Lanczos" in estimates[0]["method"]
    assert len({(e["h_max"], e["omega_max"]) for e in estimates}) == 1, [e["h_max"] for e in estimates]


def test_a_scene_run_twice_gives_byte_identical_frames_and_diagnostics(tmp_path):
    scene = os.path.join(ROOT, "scenes", "spinning_lattice.toml")
    args = ["--quiet", "--set", "integrator.steps=60", "--set", "output.frames_every=20",
            "--set", "output.diagnostics_every=5", "--set", "output.checkpoint_every=30"]
    for name in ("a", "b"):
        assert main(["run", scene, "--out", str(tmp_path / name), *args]) == 0
    a, b = snapshot(tmp_path / "a"), snapshot(tmp_path / "b")
    assert sorted(a) == sorted(b)
    compared = [n for n in a if n.endswith((".vtu", ".pvd", ".csv"))]
    assert len(compared) >= 5
    for name in compared:
        assert a[name] == b[name], name


# ----------------------------------------------------------------------------------------------
# Ctrl-C and SIGTERM checkpoint the step they stopped at


@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_a_signal_checkpoints_the_step_the_run_stopped_at_and_resume_is_bit_for_bit(tmp_path, monkeypatch, capsys,
                                                                                  signame):
    import signal

    from thermonet.io import load_checkpoint, series

    scene = os.path.join(ROOT, "scenes", "spinning_lattice.toml")
    args = ["--quiet", "--set", "integrator.steps=120", "--set", "output.frames_every=20",
            "--set", "output.diagnostics_every=10", "--set", "output.checkpoint_every=80"]
    assert main(["run", scene, "--out", str(tmp_path / "whole"), *args]) == 0
    real = series.RunOutput.write_frame

    def signalled_at_step_60(self, sim):
        real(self, sim)
        if sim.step == 60:
            os.kill(os.getpid(), getattr(signal, signame))

    monkeypatch.setattr(series.RunOutput, "write_frame", signalled_at_step_60)
    previous = signal.getsignal(signal.SIGTERM)
    out = tmp_path / "cut"
    assert main(["run", scene, "--out", str(out), *args[1:]]) == 130
    assert signal.getsignal(signal.SIGTERM) is previous  # the run's handlers are gone
    err = capsys.readouterr().err
    assert (f"thermonet: interrupted at step 60; the last checkpoint is of step 60: continue from there with: "
            f"thermonet run --resume {out}/spinning_lattice.checkpoint.npz") in err
    assert load_checkpoint(out / "spinning_lattice.checkpoint.npz")[0].step == 60
    monkeypatch.setattr(series.RunOutput, "write_frame", real)
    assert main(["run", "--resume", str(out), "--quiet"]) == 0
    a, b = snapshot(tmp_path / "whole"), snapshot(out)
    for name in ("diagnostics.csv", "spinning_lattice_000006.vtu", "spinning_lattice.pvd"):
        assert a[name] == b[name], name
    end_whole = load_checkpoint(tmp_path / "whole" / "spinning_lattice.checkpoint.npz")[0]
    end_cut = load_checkpoint(out / "spinning_lattice.checkpoint.npz")[0]
    assert end_cut.step == end_whole.step == 120
    assert (end_cut.positions == end_whole.positions).all() and (end_cut.momenta == end_whole.momenta).all()


# ----------------------------------------------------------------------------------------------
# resume: free keys may change, a refused change is named


def test_resume_allows_what_keeps_the_trajectory_and_names_what_changes_it(tmp_path, capsys):
    from thermonet.io import load_checkpoint

    scene = os.path.join(ROOT, "scenes", "spinning_lattice.toml")
    out = tmp_path / "out"
    assert main(["run", scene, "--out", str(out), "--quiet", "--set", "integrator.steps=40",
                 "--set", "output.checkpoint_every=20", "--set", "output.frames_every=20"]) == 0
    assert main(["run", "--resume", str(out), "--quiet", "--set", "materials.all.c=21.0",
                 "--set", 'initial.velocity.random.seed=12']) == 2
    err = one_error_line(capsys.readouterr().err)
    assert "written by a different scene: initial.velocity.random.seed: 11 → 12 (and 1 more: materials.all.c: " \
           "20.0 → 21.0)" in err and "free to change on resume: the outputs, integrator.t_end" in err
    # the end, the thread count, the guards and the outputs are not the trajectory
    assert main(["run", "--resume", str(out), "--quiet", "--set", "integrator.steps=60", "--set", "integrator.threads=1",
                 "--set", "integrator.check_step=false", "--set", "output.frames_every=10"]) == 0, \
        capsys.readouterr().err
    assert load_checkpoint(out / "spinning_lattice.checkpoint.npz")[0].step == 60


# ----------------------------------------------------------------------------------------------
# the API: anchors=, the frames' fields in to_meshio, a quoted step


def test_simulation_takes_anchors_and_refuses_a_quoted_step_and_to_meshio_has_the_frame_fields():
    import numpy as np

    import thermonet as tn
    from thermonet.errors import InputError

    net = tn.read_mesh(os.path.join(MESHES, "thermal_bar.msh"), cell_types=["tetra"])
    params = dict(c=100.0, beta=0.002, C0=1.0, theta0=300.0, g=4.0)
    sim = tn.Simulation(net, parameters=params, temperatures=300.0, h=0.01, anchors=["far_end", 0],
                        baths={"hot": tn.heat.Bath("hot_end", 900.0)})
    held = np.zeros(net.n_nodes, dtype=bool)
    held[net.node_groups["far_end"]] = True
    held[0] = True
    assert (sim.net.anchored == held).all() and not net.anchored.any()
    start = sim.state.positions[held].copy()
    sim.run(steps=5)
    assert (sim.state.positions[held] == start).all()
    mesh = sim.to_meshio()
    assert mesh.point_data["node_temperature"].shape == (net.n_nodes,)
    assert mesh.cell_data["heat_rate"][0].shape == (net.n_springs,)
    assert mesh.point_data["node_temperature"][net.node_groups["hot_end"]] == pytest.approx(900.0)
    assert np.abs(mesh.cell_data["heat_rate"][0]).max() > 0
    with pytest.raises(InputError, match="anchors: no node group 'far_edn' in the net; node groups: .*far_end"):
        tn.Simulation(net, parameters=params, h=0.01, anchors=["far_edn"])
    with pytest.raises(InputError, match="anchors: node index 99999 is out of range"):
        tn.Simulation(net, parameters=params, h=0.01, anchors=[99999])
    with pytest.raises(InputError, match="time step h must be a number, got str '0.01'"):
        tn.Simulation(net, parameters=params, h="0.01")


# ----------------------------------------------------------------------------------------------
# messages


def test_a_misspelt_integrator_option_is_named_at_its_line_with_what_was_meant(tmp_path, capsys):
    import thermonet as tn
    from thermonet.errors import InputError

    scene = tmp_path / "em2.toml"
    scene.write_text('[net]\ngenerator = "chain"\n[integrator]\nname = "em2"\nh = 0.01\nsteps = 2\n'
                     'options = { tolerence = 1e-10 }\n')
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert one_error_line(capsys.readouterr().err) == (
        f"thermonet: error: {scene}:7: integrator.options.tolerence: unknown option 'tolerence' (did you mean "
        "'tolerance'?); options: tolerance, max_iterations, retry, linear_solver, rtol, atol, newton_path "
        "(implicit integrators), alpha (gtr-alpha)")
    with pytest.raises(InputError, match=r"integrator 'co2': unknown option 'aplha' \(did you mean 'alpha'\?\)"):
        tn.Simulation(tn.chain(), integrator="co2", h=0.01, integrator_options={"aplha": 0.5})


def test_info_labels_the_mass_it_shows(capsys):
    assert main(["info", os.path.join(ROOT, "scenes", "bracket.toml")]) == 0
    out = capsys.readouterr().out
    net_line = next(line for line in out.splitlines() if line.startswith("  net: "))
    assert "mass 0.0674102 on the 554 free nodes (0.068688 with the anchored ones)" in net_line
    assert "    mass 0.068688 (ρ V = 0.068688)" in out


# ----------------------------------------------------------------------------------------------
# each output folder: the scene as run and a log of what was printed


def test_the_output_folder_holds_the_scene_as_run_and_a_log_and_summary_says_where(tmp_path, capsys):
    import json

    from thermonet.scenes import load_scene

    scene = tmp_path / "shock.toml"
    scene.write_text(SHOCK.replace(f"{MESHES}/thermal_bar.msh", os.path.relpath(MESHES, tmp_path) + "/thermal_bar.msh"))
    out = tmp_path / "first"
    assert main(["run", str(scene), "--out", str(out), "--set", "baths.hot.temperature=700.0",
                 "--set", "integrator.steps=8"]) == 0
    printed = capsys.readouterr()
    files = json.loads((out / "summary.json").read_text())["files"]
    assert files == {"scene_as_run": "scene-as-run.toml", "log": "run.log"}
    log = (out / "run.log").read_text()
    assert log.startswith("# ") and printed.out in log
    assert log.splitlines()[0].endswith(f": thermonet run {scene} --out {out} --set baths.hot.temperature=700.0 "
                                        "--set integrator.steps=8")
    # the copy is the scene with its overrides, and runs the same from another folder
    copy = load_scene(out / "scene-as-run.toml")
    assert copy["baths"]["hot"]["temperature"] == 700.0 and copy["integrator"]["steps"] == 8
    assert copy.mesh_path() == os.path.join(MESHES, "thermal_bar.msh")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    os.replace(out / "scene-as-run.toml", elsewhere / "again.toml")
    assert main(["run", str(elsewhere / "again.toml"), "--out", str(tmp_path / "again"), "--quiet"]) == 0
    for name in ("diagnostics.csv", "shock_000002.vtu"):
        assert (out / name).read_bytes() == (tmp_path / "again" / name).read_bytes()
    # resume appends to the log and writes the scene it continues with
    assert main(["run", "--resume", str(out), "--set", "integrator.steps=12"]) == 0
    resumed = capsys.readouterr()
    log = (out / "run.log").read_text()
    assert log.count("# ") == 2 and log.endswith(resumed.out)
    assert load_scene(out / "scene-as-run.toml")["integrator"]["steps"] == 12


def test_scene_messages_name_the_typo_the_value_and_the_line(tmp_path, capsys):
    bracket = f'[net]\nmesh = "{MESHES}/bracket.msh"\n[materials.bracket]\nyoungs_modulis = 70e9\n' \
              'density = 2700.0\nheat_capacity = 900.0\n[integrator]\nh = 1e-7\nsteps = 2\n'
    chain = '[net]\ngenerator = "chain"\n[materials.all]\nc = 3.0\n[integrator]\nh = 0.01\nsteps = 2\n'
    for text, expected in [
        (bracket, ":4: materials.bracket.youngs_modulis: model 'hencky' has no parameter 'youngs_modulis' "
                  "(did you mean 'youngs_modulus'?)"),
        (chain.replace("c = 3.0", "c = nan"), ":4: materials.all.c: must be a finite number, got nan"),
        (chain.replace("[materials.all]", "[material.all]"), ":3: material: unknown key (did you mean 'materials'?)"),
        (SHOCK.replace("temperature = 900.0", "temperature = inf"), ":16: baths.hot.temperature: must be finite, got inf"),
    ]:
        scene = tmp_path / "s.toml"
        scene.write_text(text)
        assert main(["run", str(scene), "--out", str(tmp_path / "out")]) == 2
        line = one_error_line(capsys.readouterr().err)
        assert line.startswith(f"thermonet: error: {scene}{expected}"), line
        assert "<" not in line


def test_nothing_is_said_about_compiling_before_a_scene_fails_its_checks(tmp_path):
    import subprocess
    import sys

    scene = tmp_path / "stiff.toml"
    scene.write_text('[net]\ngenerator = "chain"\n[materials.all]\nc = 1e6\n[integrator]\nh = 0.5\nsteps = 2\n')
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cold-cache"), PYTHONPATH=ROOT)
    done = subprocess.run([sys.executable, "-m", "thermonet.cli.main", "run", str(scene), "--out", str(tmp_path / "o")],
                          env=env, capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr.splitlines() == [one_error_line(done.stderr)] and "integrator.h: h = 0.5" in done.stderr


def test_the_progress_line_shows_steps_per_second_with_three_significant_digits():
    from thermonet.cli.progress import ProgressBar

    bar = ProgressBar()
    assert "1,230,000 steps/s" in bar.line(1234567, 10**7, 1.0)
    assert "45.7 steps/s" in bar.line(457, 1000, 10.0)
    assert "? steps/s" in bar.line(0, 1000, 0.0)


# ----------------------------------------------------------------------------------------------
# two volumes not fused: pieces no spring joins


def _two_unfused_tetrahedra(path) -> None:
    """Two tetrahedra meeting at a face whose nodes are duplicated (volumes not fused), the face
    of the first one a node group "clamp"."""
    import meshio
    import numpy as np

    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float)
    cells = [("triangle", np.array([[0, 1, 2]])), ("tetra", np.array([[0, 1, 2, 3], [4, 5, 6, 7]]))]
    meshio.Mesh(pts, cells, cell_data={"gmsh:physical": [np.array([2]), np.array([1, 1])],
                                       "gmsh:geometrical": [np.array([1]), np.array([1, 2])]},
                field_data={"clamp": np.array([2, 2]), "part": np.array([1, 3])}).write(
        str(path), file_format="gmsh22", binary=False)


def test_pieces_no_spring_joins_are_said_in_info_warned_in_run_and_named_for_continuum(tmp_path, capsys):
    _two_unfused_tetrahedra(tmp_path / "two.msh")
    scene = tmp_path / "two.toml"
    base = '[net]\nmesh = "two.msh"\ncells = ["tetra"]\n[effects]\nanchors = ["clamp"]\n[integrator]\nh = 0.01\nsteps = 3\n'
    scene.write_text(base + "[materials.part]\nc = 10.0\n[initial.mass]\nuniform = 1.0\n")
    note = "the net is 2 pieces that no spring joins (4, 4 nodes; a mesh of volumes that were not fused"
    assert main(["info", str(tmp_path / "two.msh")]) == 0
    assert note in capsys.readouterr().out
    assert main(["info", str(scene)]) == 0
    assert f"{note}" in capsys.readouterr().out
    assert main(["run", str(scene), "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert f"thermonet: warning: {note}" in err and "1 of them holds no anchored node and moves freely" in err
    scene.write_text(base + "[materials.part]\nyoungs_modulus = 1e3\ndensity = 1.0\nheat_capacity = 1.0\n")
    assert main(["run", str(scene), "--out", str(tmp_path / "out2")]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert "is 2 pieces that no spring joins" in line and "continuum materials need one rigid net" in line
    assert "tetrahedra (triangles in 2D)" not in line


# ----------------------------------------------------------------------------------------------
# plots and pictures


def test_plots_carry_units_and_the_energy_plot_shows_the_heat_that_came_in(tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from thermonet.cli.plot import plot_run

    scene = tmp_path / "shock.toml"
    scene.write_text(SHOCK)
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    seen = {}
    real = Figure.savefig

    def remember(self, path, *a, **k):
        seen[os.path.basename(path)] = [(ax.get_xlabel(), ax.get_ylabel(), [l.get_label() for l in ax.get_lines()])
                                        for ax in self.axes]
        return real(self, path, *a, **k)

    monkeypatch.setattr(Figure, "savefig", remember)
    plot_run(str(tmp_path / "out"))
    top, balance = seen["energy.png"]
    assert top[1] == "energy (model units)" and "heat in (baths, sources)" in top[2] and "energy" in top[2]
    assert balance == ("time (model units)", "H − H(0) − ΣQ (model units)", balance[2])
    assert all(x.endswith("(model units)") for axes in seen.values() for x, _, _ in axes if x)


def test_render_keeps_vtk_noise_out_and_labels_its_colour_bar_readably(tmp_path, capfd):
    pytest.importorskip("pyvista")
    from thermonet.cli.render import bar_labels

    scene = tmp_path / "shock.toml"
    scene.write_text(SHOCK)
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    capfd.readouterr()
    assert main(["render", str(tmp_path / "out"), "--png", str(tmp_path / "frame.png"), "--size", "300x200"]) == 0
    out, err = capfd.readouterr()
    assert "X server" not in err and "WARN" not in err and err == "", err
    assert os.path.getsize(tmp_path / "frame.png") > 1000
    assert bar_labels([300.0, 900.0]) == {"n_labels": 5, "fmt": "%.0f"}
    assert bar_labels([299.99, 300.01]) == {"n_labels": 5, "fmt": "%.4f"}
    assert bar_labels([300.0, 300.0]) == {"n_labels": 2, "fmt": "%.6g"}
    assert bar_labels([0.0, 2e7])["fmt"].endswith("e")


def test_a_bath_names_when_its_temperature_reaches_zero_and_a_group_of_points_no_spring_joins(tmp_path, capsys):
    import meshio
    import numpy as np

    for temperature, expected in [
        ("{ start = 300.0, rate = -1e308 }", "a bath temperature must stay > 0, but 300 − 1e+308·t reaches 0 at t = 3e-306"),
        ("{ start = 300.0, end = -300.0, duration = 2.0 }",
         "a bath temperature must stay > 0, but 300 → -300 over t ∈ [0, 2] reaches 0 at t = 1"),
        ("-5.0", "a bath temperature must be > 0, got -5 at t = 0"),
    ]:
        scene = tmp_path / "s.toml"
        scene.write_text(SHOCK.replace("temperature = 900.0", f"temperature = {temperature}"))
        assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 2
        assert one_error_line(capsys.readouterr().err).endswith(f":16: baths.hot.temperature: {expected}")
    # a node group whose only point touches no spring
    _two_unfused_tetrahedra(tmp_path / "two.msh")
    mesh = meshio.read(tmp_path / "two.msh")
    points = np.vstack([mesh.points, [[5.0, 5.0, 5.0]]])
    cells = [("vertex", np.array([[8]]))] + [(b.type, b.data) for b in mesh.cells]
    meshio.Mesh(points, cells, cell_data={"gmsh:physical": [np.array([4])] + list(mesh.cell_data["gmsh:physical"]),
                                          "gmsh:geometrical": [np.array([9])] + list(mesh.cell_data["gmsh:geometrical"])},
                field_data={**mesh.field_data, "lonely": np.array([4, 0])}).write(
        str(tmp_path / "lonely.msh"), file_format="gmsh22", binary=False)
    scene = tmp_path / "lonely.toml"
    scene.write_text('[net]\nmesh = "lonely.msh"\ncells = ["tetra"]\n[materials.part]\nc = 10.0\nbeta = 0.1\nC0 = 1.0\n'
                     'theta0 = 300.0\ng = 1.0\n[initial.mass]\nuniform = 1.0\n[effects]\nconduction = true\n'
                     '[baths.warm]\ngroup = "lonely"\ntemperature = 400.0\n[integrator]\nh = 0.01\nsteps = 2\n')
    assert main(["run", str(scene), "--out", str(tmp_path / "out2"), "--quiet"]) == 2
    assert one_error_line(capsys.readouterr().err).endswith(
        ":15: baths.warm.group: node group 'lonely' holds no node of the net: its mesh points touch no spring "
        "(only points that springs join become nodes)")


def test_the_first_time_a_time_function_reaches_a_level():
    from thermonet.timefunctions import TimeFunction

    assert TimeFunction.constant(5.0).first_at_or_below(0.0) is None
    assert TimeFunction.linear(-2.0, start=10.0).first_at_or_below(0.0) == pytest.approx(5.0)
    assert TimeFunction.ramp(-100.0, 4.0, start=300.0).first_at_or_below(0.0) == pytest.approx(3.0)
    assert TimeFunction.sine(400.0, 0.25, 0.0, 300.0).first_at_or_below(0.0) == pytest.approx(
        (np.pi + np.arcsin(0.75)) / (2 * np.pi * 0.25), abs=1e-4)
    assert TimeFunction.sine(100.0, 0.25, 0.0, 300.0).first_at_or_below(0.0) is None
    assert TimeFunction.table([[0.0, 300.0], [1.0, 100.0], [2.0, -100.0]]).first_at_or_below(0.0) == pytest.approx(1.5)
