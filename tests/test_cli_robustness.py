"""What a new user hits: silent garbage, overwritten runs, file-system faults,
unreadable meshes, t_end off the step grid, misleading messages, compile time in the ETA.

Each test reproduces the failure as it was reported and asserts the wanted behaviour: exit
codes, one-line messages naming the file, key or step, and the files left on disk.
"""

import os
import subprocess

import meshio
import numpy as np
import pytest

import thermonet as tn
from thermonet.cli.main import main
from thermonet.io import load_checkpoint, read_pvd

from cli_helpers import one_error_line, snapshot

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LATTICE2D = os.path.join(ROOT, "scenes", "lattice2d.toml")
SPINNING = os.path.join(ROOT, "scenes", "spinning_lattice.toml")
#: the reported case on a shipped scene: thermal stress far above the elastic one (β = 1, a region
#: at 10 θ0), h = 0.01 at 0.57 of the initial stability limit (0.0175), which collapses to 0.0013
#: two steps later as the hot region expands
HOT_SCENE = ["materials.soft.beta=1.0", "materials.stiff.beta=1.0", "initial.temperature.regions.soft=3000.0",
             "integrator.h=0.01", "integrator.t_end=2.0"]
HOT = [a for key in HOT_SCENE for a in ("--set", key)] + [
    "--set", "output.frames_every=1", "--set", "output.checkpoint_every=1"]
SMALL = ["--quiet", "--set", "integrator.steps=120", "--set", "output.frames_every=20",
         "--set", "output.diagnostics_every=10", "--set", "output.checkpoint_every=40"]


def assert_valid_output(folder, name):
    """The checkpoint loads and the PVD lists only complete frames meshio reads."""
    state, meta = load_checkpoint(os.path.join(folder, f"{name}.checkpoint.npz"))
    frames = read_pvd(os.path.join(folder, f"{name}.pvd"))
    assert frames
    for _, path in frames:
        assert meshio.read(path).points.shape[0] > 0
    return state, frames


# ----------------------------------------------------------------------------------------------
# 1. a run that left its stability limit, or conservation, does not end with exit 0


def test_a_step_above_the_limit_re_estimated_while_running_stops_the_run(tmp_path, capsys):
    assert main(["run", LATTICE2D, "--out", str(tmp_path), *HOT]) == 3
    err = one_error_line(capsys.readouterr().err)
    assert "at step 2 (t = 0.02) the stability limit of co2 is h_max ≈ 0.001289" in err
    assert "h = 0.01 is 7.76× it" in err and "rewound to step 1" in err
    state, frames = assert_valid_output(tmp_path, "lattice2d")
    assert state.step == 1 and [t for t, _ in frames] == [0.0, 0.01]
    assert not (tmp_path / "summary.json").exists()


def test_with_the_guards_off_a_garbage_run_still_exits_non_zero_and_says_why(tmp_path, capsys):
    code = main(["run", LATTICE2D, "--out", str(tmp_path), *HOT, "--allow-unstable-step",
                 "--set", "integrator.energy_tolerance=false", "--set", "output.frames_every=50"])
    assert code == 3
    captured = capsys.readouterr()
    assert "thermonet: warning: at step 2 (t = 0.02) the stability limit" in captured.err
    err = one_error_line(captured.err)
    assert "broken conservation: energy departed from its initial value by 0.292" in err
    import json

    summary = json.loads((tmp_path / "summary.json").read_text())  # the files are kept
    assert summary["steps"] == 200 and summary["broken_conservation"][0].startswith("energy departed")


def test_the_default_energy_guard_stops_a_run_whose_energy_departs(tmp_path):
    from thermonet.run_guards import DEFAULT_ENERGY_TOLERANCE, broken_conservation
    from thermonet.scenes import load_scene

    scene = load_scene(LATTICE2D, HOT_SCENE)
    assert scene["integrator"]["energy_tolerance"] == DEFAULT_ENERGY_TOLERANCE == 0.1
    sim = scene.build().simulation
    sim.stability_guard.mode = "warn"
    from thermonet.step_policy import StepWarning

    with pytest.warns(StepWarning, match="stability limit"), \
            pytest.raises(tn.SimulationError, match=r"energy departed .* by 0\.285 \(relative; tolerance 0\.1\) at step 3"):
        sim.run(steps=200, diagnostics_every=1)
    assert sim.step == 2  # rewound to the previous stop
    # API: energy_tolerance=None switches the guard off; the run's conservation is then judged at its end
    sim = scene.build().simulation
    sim.energy_tolerance, sim.stability_guard.mode = None, "off"
    sim.run(steps=200, diagnostics_every=1)
    assert broken_conservation(sim) == ["energy departed from its initial value by 0.292 (relative; at most 0.1 expected)"]


def test_the_guard_warns_between_0_9_and_1_5_h_max_and_stops_above():
    from thermonet.run_guards import StabilityLimitExceeded
    from thermonet.step_policy import StepWarning

    def linear_spring(ratio, **kw):  # constant stiffness: ω² = 50 at every state, h_max = 2/ω for co2
        net = tn.Net([[0, 0, 0], [1, 0, 0]], [[0, 1]], masses=[1.0, 2.0], anchored=[0], rest_lengths=[1.0])
        return tn.Simulation(net, model="quadratic", parameters=dict(E=100.0, beta=0.0), momenta=[[0, 0, 0], [1e-3, 0, 0]],
                             h=ratio * 2.0 / np.sqrt(50.0), energy_tolerance=None, **kw)

    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", StepWarning)  # below 0.9 h_max: silent
        linear_spring(0.85).run(steps=40, diagnostics_every=4)
    with pytest.warns(StepWarning, match=r"h = 0.268701 is 0.95× it") as caught:
        linear_spring(0.95).run(steps=40, diagnostics_every=4)
    assert len(caught) == 1  # once per run
    sim = linear_spring(1.6)
    with pytest.raises(StabilityLimitExceeded, match=r"at step 4 .* h = 0.452548 is 1.6× it: the run is no longer stable"):
        sim.run(steps=40, diagnostics_every=4)
    assert sim.step == 0  # rewound to the previous stop
    with pytest.warns(StepWarning, match="1.60× it"):
        linear_spring(1.6, stability_guard="warn").run(steps=8, diagnostics_every=4)


def test_the_guards_time_budget_is_a_share_of_the_running_time(monkeypatch):
    """The stable-step guard keeps to GUARD_TIME_BUDGET of the time the simulation has spent
    running: a program that runs it in short calls between other work (here: sleeps ten
    thousand times as long as a call) does not give it that work's time too, so it skips the
    stops beyond its budget instead of re-estimating at every one."""
    import time

    import thermonet.run_guards as guards

    monkeypatch.setattr(guards, "GUARD_TIME_ALLOWANCE", 0.0)
    net = tn.lattice((3, 3, 2), neighbours=18, jitter=0.3, seed=1)
    sim = tn.Simulation(net, parameters=dict(c=50.0, beta=1.0), temperatures=400.0, h=1e-3, energy_tolerance=None)
    sim.run(steps=2, diagnostics_every=2)  # (compiles)
    check = sim.stability_guard._check
    # a check as costly as on a large net (10 ms), next to calls of a few steps of a small one
    monkeypatch.setattr(sim.stability_guard, "_check", lambda s: (time.sleep(0.01), check(s)))
    checked = sim.stability_guard.checked
    for _ in range(10):
        time.sleep(0.05)
        sim.run(steps=2, diagnostics_every=2)
    guard = sim.stability_guard
    assert guard.skipped >= 9 and guard.checked <= checked + 1
    assert guard.seconds <= guards.GUARD_TIME_BUDGET * sim.runner.seconds_running() + 0.05


def test_the_cheap_frequency_bound_is_an_upper_bound_of_the_largest_frequency():
    from thermonet.run_guards import frequency_bound
    from thermonet.stability import max_frequency

    rng = np.random.default_rng(5)
    for seed in range(4):
        net = tn.lattice((3, 3, 2), neighbours=18, jitter=0.3, seed=seed)
        temps = rng.uniform(100.0, 3000.0, net.n_springs)
        sim = tn.Simulation(net, parameters=dict(c=50.0, beta=1.0), temperatures=temps, h=1e-3,
                            velocities=rng.normal(size=(net.n_nodes, 3)))
        for _ in range(3):
            s = sim.internal_state()
            exact = max_frequency(sim.system, s.positions, s.entropy).omega_max
            bound = frequency_bound(sim.system, s.positions, s.entropy)
            assert exact <= bound <= 4.0 * exact, (seed, exact, bound)
            sim.run(steps=20)


# ----------------------------------------------------------------------------------------------
# 3. an existing output folder is refused, --overwrite replaces it, --resume cleans up


def test_a_previous_run_is_never_overwritten_silently(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", SPINNING, "--out", str(out), *SMALL]) == 0
    (out / "notes.txt").write_text("mine")
    before = snapshot(out)
    assert main(["run", SPINNING, "--out", str(out), *SMALL, "--set", "output.frames_every=60"]) == 2
    err = one_error_line(capsys.readouterr().err)
    assert f"--out {out}: holds the output of a previous run" in err and "--overwrite" in err and "--resume" in err
    assert snapshot(out) == before
    # --overwrite removes the old run's files (its extra frames too), and only those
    assert main(["run", SPINNING, "--out", str(out), *SMALL, "--set", "output.frames_every=60", "--overwrite"]) == 0
    names = sorted(os.listdir(out))
    assert names == ["diagnostics.csv", "notes.txt", "run.log", "scene-as-run.toml", "spinning_lattice.checkpoint.npz",
                     "spinning_lattice.pvd", "spinning_lattice_000000.vtu", "spinning_lattice_000001.vtu",
                     "spinning_lattice_000002.vtu", "summary.json"]
    assert (out / "run.log").read_text().count("\n# ") == 0  # the old run's log went with its files
    assert (out / "notes.txt").read_text() == "mine"


def test_resume_removes_a_killed_runs_temporary_files_and_refuses_overwrite(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", SPINNING, "--out", str(out), *SMALL, "--set", "integrator.steps=80"]) == 0
    for stale in ("spinning_lattice_000004.vtu.tmp-99999", "spinning_lattice.pvd.tmp-4242", "diagnostics.csv.tmp"):
        (out / stale).write_bytes(b"half a file")
    assert main(["run", "--resume", str(out), "--overwrite", "--quiet"]) == 2
    assert "give one of them" in one_error_line(capsys.readouterr().err)
    assert main(["run", "--resume", str(out), "--quiet", "--set", "integrator.steps=120"]) == 0
    assert not [n for n in os.listdir(out) if ".tmp" in n]
    assert load_checkpoint(out / "spinning_lattice.checkpoint.npz")[0].step == 120


# ----------------------------------------------------------------------------------------------
# 4. file-system failures are clear errors; what was written stays valid


def test_out_naming_an_existing_file_is_refused(tmp_path, capsys):
    target = tmp_path / "results"
    target.write_text("not a folder")
    assert main(["run", SPINNING, "--out", str(target), *SMALL]) == 2
    assert f"--out {target}: exists and is not a folder" in one_error_line(capsys.readouterr().err)
    assert target.read_text() == "not a folder"


def _mount_tmpfs(folder, options: str) -> None:
    os.makedirs(folder, exist_ok=True)
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)], capture_output=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here (needs root): {done.stderr.decode().strip()}")


@pytest.fixture
def mounts():
    made = []
    yield made
    for folder in made:
        subprocess.run(["umount", str(folder)], capture_output=True)


def test_a_read_only_output_folder_is_a_clear_error(tmp_path, mounts, capsys):
    out = tmp_path / "ro"
    _mount_tmpfs(out, "ro,size=1m")
    mounts.append(out)
    assert main(["run", SPINNING, "--out", str(out), *SMALL]) == 4
    err = one_error_line(capsys.readouterr().err)
    assert err.endswith(f"--out {out}: cannot write the output folder: Read-only file system")


def test_a_full_disk_part_way_stops_with_a_valid_checkpoint_and_pvd(tmp_path, mounts, capsys):
    out = tmp_path / "small"
    _mount_tmpfs(out, "size=160k")
    mounts.append(out)
    code = main(["run", LATTICE2D, "--out", str(out), "--set", "integrator.steps=2000", "--set", "output.frames_every=10",
                 "--set", "output.checkpoint_every=50", "--set", "output.diagnostics_every=10"])
    assert code == 4
    err = capsys.readouterr().err
    line = one_error_line(err)
    assert "writing the output failed at step" in line and "No space left on device" in line
    assert f"{out}/" in line  # names the file
    assert "the last checkpoint is of step" in err
    state, frames = assert_valid_output(out, "lattice2d")
    assert 0 < state.step < 2000 and not (out / "summary.json").exists()
    assert not [n for n in os.listdir(out) if ".tmp" in n]


def test_a_corrupt_or_truncated_checkpoint_is_refused_on_resume(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", SPINNING, "--out", str(out), *SMALL]) == 0
    ckpt = out / "spinning_lattice.checkpoint.npz"
    data = ckpt.read_bytes()
    for broken in (data[: len(data) // 2], b"garbage" * 10, data[:100]):
        ckpt.write_bytes(broken)
        assert main(["run", "--resume", str(out), "--quiet"]) == 2
        err = one_error_line(capsys.readouterr().err)
        assert f"{ckpt}: not a readable thermonet checkpoint" in err


# ----------------------------------------------------------------------------------------------
# 5. an unreadable mesh is a MeshError naming it, in the CLI as in the API


@pytest.mark.parametrize("content", [b"garbage\n", "truncated"])
def test_an_unreadable_mesh_is_one_error_line_in_run_and_info(tmp_path, capsys, content):
    mesh = tmp_path / "plate.msh"
    if content == "truncated":
        content = open(os.path.join(ROOT, "meshes", "lattice2d.msh"), "rb").read()[:1500]
    mesh.write_bytes(content)
    scene = tmp_path / "plate.toml"
    scene.write_text('[net]\nmesh = "plate.msh"\n[integrator]\nh = 0.001\nsteps = 10\n')
    assert main(["info", str(mesh)]) == 2
    assert one_error_line(capsys.readouterr().err).startswith(f"thermonet: error: {mesh}: meshio cannot read it: ")
    assert main(["run", str(scene), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    captured = capsys.readouterr()
    assert f"{scene}:2: net.mesh: {mesh}: meshio cannot read it" in one_error_line(captured.err)
    assert captured.out == "" and "Couldn't read" not in captured.err.replace(one_error_line(captured.err), "")
    with pytest.raises(tn.MeshError, match="meshio cannot read it"):
        tn.read_mesh(mesh)


# ----------------------------------------------------------------------------------------------
# 6. one rule for t_end: a whole number of steps, everywhere


def test_t_end_off_the_step_grid_is_refused_everywhere_with_what_would_do(tmp_path, capsys):
    sim = tn.Simulation(tn.chain(), h=0.3)
    with pytest.raises(tn.InputError, match=r"t_end = 1 is not a whole number of steps of h = 0.3 .* give t_end = 0.9 or 1.2"):
        sim.run(t_end=1.0)
    assert sim.step == 0
    assert main(["run", SPINNING, "--out", str(tmp_path / "o"), "--quiet", "--t-end", "0.005"]) == 2
    err = one_error_line(capsys.readouterr().err)
    assert "integrator.t_end: t_end = 0.005 is not a whole number of steps of h = 0.002" in err
    assert "give t_end = 0.004 or 0.006" in err
    from thermonet.studies.tasks import check_steps

    with pytest.raises(tn.InputError, match="not a whole number of steps"):
        check_steps(1.0, 0.3)
    assert tn.Simulation(tn.chain(), h=0.1).run(t_end=0.3).rows[-1]["step"] == 3  # 0.3/0.1 rounds to 3


# ----------------------------------------------------------------------------------------------
# 7. messages that say what is wrong, once


def test_a_folder_given_as_scene_or_mesh_says_so(tmp_path, capsys):
    assert main(["run", str(tmp_path)]) == 2
    assert one_error_line(capsys.readouterr().err) == f"thermonet: error: {tmp_path}: is a folder, not a scene file (.toml)"
    assert main(["info", str(tmp_path)]) == 2
    assert "is a folder" in one_error_line(capsys.readouterr().err)
    (tmp_path / "m.msh").mkdir()
    with pytest.raises(tn.MeshError, match="is a folder, not a mesh file"):
        tn.read_mesh(tmp_path / "m.msh")


def test_a_group_typo_names_each_file_once(tmp_path, capsys):
    assert main(["run", LATTICE2D, "--out", str(tmp_path), "--set", "materials.sof.c=3.0"]) == 2
    err = one_error_line(capsys.readouterr().err)
    assert err == ("thermonet: error: --set materials.sof.c: materials.sof: no spring group 'sof' in the mesh "
                   "lattice2d.msh; spring groups: all, soft, stiff")


def test_after_ctrl_c_the_message_names_the_step_resume_starts_from(tmp_path, monkeypatch, capsys):
    from thermonet.io import series

    real = series.RunOutput.write_frame

    def interrupted_at_step_100(self, sim):
        if sim.step == 100:
            raise KeyboardInterrupt
        real(self, sim)

    monkeypatch.setattr(series.RunOutput, "write_frame", interrupted_at_step_100)
    assert main(["run", SPINNING, "--out", str(tmp_path), *SMALL[1:]]) == 130
    err = capsys.readouterr().err
    assert (f"thermonet: interrupted at step 100; the last checkpoint is of step 80: continue from there with: "
            f"thermonet run --resume {tmp_path}/spinning_lattice.checkpoint.npz") in err
    assert load_checkpoint(tmp_path / "spinning_lattice.checkpoint.npz")[0].step == 80


# ----------------------------------------------------------------------------------------------
# 8. compiling is announced and kept out of the rate and ETA


def test_compile_time_is_announced_and_kept_out_of_rate_and_eta():
    import io
    import time

    import numba

    from thermonet.cli.progress import ProgressBar

    sim = tn.Simulation(tn.chain(), h=0.01)
    real = sim.stepper.advance
    calls = []

    def advance_compiling_first(state, n, h, **kw):  # a first chunk that compiles a new kernel
        if not calls:
            fresh = numba.njit(lambda x: x * 2.0 + 1.0)
            fresh(1.0)
        calls.append(n)
        return real(state, n, h, **kw)

    sim.stepper.advance = advance_compiling_first
    stream = io.StringIO()
    bar = ProgressBar(stream=stream, delay=0.0, log_interval=0.0)
    seen = []
    t0 = time.perf_counter()
    sim.run(steps=100, diagnostics_every=10, progress=lambda d, t, e: (seen.append(e), bar(d, t, e)))
    wall = time.perf_counter() - t0
    bar.compiling(), bar.compiling()  # said once
    assert sim.compile_time > 0.01
    assert seen[-1] <= wall - sim.compile_time + 1e-3 and sim.wall_time <= wall - sim.compile_time + 1e-3


def test_the_progress_bar_says_once_that_kernels_are_compiling():
    import io

    from thermonet.cli.progress import ProgressBar
    from thermonet.compile_watch import CompileWatch

    import numba

    stream = io.StringIO()
    bar = ProgressBar(stream=stream)
    with CompileWatch(bar.compiling) as watch:
        numba.njit(lambda x: x + 1)(1)
        numba.njit(lambda x: x + 2)(1)
    assert watch.compilations == 2 and watch.seconds > 0
    assert stream.getvalue().count("compiling kernels") == 1


# ----------------------------------------------------------------------------------------------
# 2. thermonet study convergence: defaults from the scene, arguments checked first, reasons


def test_study_arguments_are_checked_before_any_cluster_starts(monkeypatch, capsys):
    import thermonet.studies as studies

    class NoCluster:
        def __init__(self, *a, **k):
            raise AssertionError("a Runner was started before the arguments were checked")

    monkeypatch.setattr(studies, "Runner", NoCluster)
    for argv, message in [
        (["--dt", "0.3"], "--dt and --t-end: t_end = 1 is not a whole number of steps h = 0.3"),
        (["--check", "co6:0.3"], "--check: t_end = 1 is not a whole number of steps h = 0.3"),
        (["--check", "nope:1e-3"], "unknown integrator 'nope'"),
        (["--halvings", "-1"], "--halvings must be in 0..30, got -1"),
        (["--integrators", "co2,nope"], "unknown integrator 'nope'"),
        (["--t-end", "-1"], "--t-end must be finite and > 0, got -1"),
    ]:
        assert main(["study", "convergence", "chain", *argv]) == 2
        assert message in one_error_line(capsys.readouterr().err), argv
    assert main(["study", "convergence", "no-such-scene.toml"]) == 2
    assert "neither a built-in scene" in one_error_line(capsys.readouterr().err)


def test_study_defaults_come_from_the_scene_and_every_missing_slope_says_why(tmp_path, capsys):
    from thermonet.studies.convergence import default_check, default_time_step

    # the scene's own h (0.002), inside its stability limit (0.046): not the paper's 0.1
    assert default_time_step(LATTICE2D, ["co2", "co4"], 1.0) == 0.002
    assert default_time_step("chain", ["co2"], 1.0) == 0.09090909090909091  # 0.9 h_max = 0.0937 -> 1/11
    assert default_check(LATTICE2D, 1.0) == ("co6", 5e-4)
    # a step the user forces above the limit: the failed runs leave too few points, and the
    # summary says so instead of a bare dash
    code = main(["study", "convergence", LATTICE2D, "--serial", "--integrators", "co2", "--dt", "0.1",
                 "--halvings", "1", "--t-end", "0.2", "--out", str(tmp_path)])
    assert code == 0
    out = capsys.readouterr().out
    assert "\n\n" not in out and not out.startswith("\n")
    assert "time steps 0.1·2^-i, i = 0..1, to t = 0.2; reference checked against co6 h=0.0005" in out
    reasons = [line for line in out.splitlines() if line.startswith("  no ")]
    assert reasons and all("usable point" in line and "(2 needed)" in line for line in reasons)
    assert any("1 failed or non-finite run" in line for line in reasons)
    assert "co2 h=0.1: failed: the energy departed" in out


# ----------------------------------------------------------------------------------------------
# 9. the API: short reprs, frames from a script, meshio and PyVista, citations users can follow


def test_reprs_are_one_short_line():
    net = tn.lattice((6, 6, 6), neighbours=18)
    sim = tn.Simulation(net, h=1e-3)
    diag = sim.run(steps=20, diagnostics_every=5)
    for obj, start in ((net, "<Net 343 nodes (0 anchored), 2"), (diag, "<Diagnostics 5 rows, steps 0..20"),
                       (sim.state, "<State step 20, t = 0.02: 343 nodes (x, p), 2"), (sim.system, "<System 343 nodes"),
                       (sim, "<Simulation 343 nodes")):
        text = repr(obj)
        assert text.startswith(start) and "\n" not in text and "array" not in text and len(text) < 400, text
        assert str(obj) == text


def test_frames_written_from_a_script_are_the_cli_s_files(tmp_path):
    from thermonet.io import RunOutput

    sim = tn.chain_simulation("co2", h=0.01)
    out = RunOutput.for_simulation(sim, tmp_path / "mine", frames_every=25)
    sim.run(t_end=1.0, diagnostics_every=out.diagnostics_every, observers=out.observers())
    out.write_summary(sim)
    frames = read_pvd(tmp_path / "mine" / "run.pvd")
    assert [t for t, _ in frames] == pytest.approx([0.0, 0.25, 0.5, 0.75, 1.0])
    last = meshio.read(frames[-1][1])
    np.testing.assert_array_equal(last.points, sim.state.positions)
    np.testing.assert_array_equal(last.cell_data["temperature"][0], sim.temperatures())
    assert sorted(os.listdir(tmp_path / "mine"))[:3] == ["diagnostics.csv", "run.pvd", "run_000000.vtu"]
    # a second run into the same folder is refused, unless asked to overwrite it
    with pytest.raises(tn.InputError, match="holds the output of a previous run"):
        RunOutput.for_simulation(sim, tmp_path / "mine", frames_every=25)
    RunOutput.for_simulation(sim, tmp_path / "mine", frames_every=25, overwrite=True)
    assert os.listdir(tmp_path / "mine") == []


def test_nets_and_states_convert_to_meshio_and_pyvista_and_read_back(tmp_path):
    pv = pytest.importorskip("pyvista")
    net = tn.read_mesh(os.path.join(ROOT, "meshes", "lattice2d.msh"), anchors="clamp")
    mesh = net.to_meshio()
    mesh.write(tmp_path / "net.vtu")
    back = meshio.read(tmp_path / "net.vtu")
    np.testing.assert_array_equal(back.points, net.positions)
    np.testing.assert_array_equal(back.cells_dict["line"], net.edges)
    np.testing.assert_array_equal(back.point_data["anchored"], net.anchored)
    np.testing.assert_array_equal(back.cell_data["rest_length"][0], net.rest_lengths)
    grid = net.to_pyvista()
    assert isinstance(grid, pv.UnstructuredGrid) and grid.n_cells == net.n_springs
    np.testing.assert_array_equal(grid.point_data["mass"], net.masses)

    sim = tn.Simulation(net, temperatures=400.0, h=1e-3)
    sim.run(steps=30)
    sim.to_meshio().write(tmp_path / "state.vtu")
    grid = pv.read(tmp_path / "state.vtu")
    np.testing.assert_array_equal(np.asarray(grid.points), sim.state.positions)
    np.testing.assert_array_equal(grid.cell_data["temperature"], sim.temperatures())
    np.testing.assert_array_equal(grid.cell_data["strain"], sim.strains())
    np.testing.assert_array_equal(sim.to_pyvista().point_data["momentum"], sim.state.momenta)


def test_the_api_s_docstrings_cite_the_paper_or_the_docs_not_a_private_spec():
    owned = ["simulation.py", "builders.py", "net.py", "system.py", "diagnostics.py", "stability.py",
             "step_policy.py", "run_guards.py", "compile_watch.py", "cli", "io", "scenes"]
    hits = []
    for item in owned:
        path = os.path.join(ROOT, "thermonet", item)
        files = [path] if path.endswith(".py") else [os.path.join(path, f) for f in os.listdir(path) if f.endswith(".py")]
        for f in files:
            text = open(f, encoding="utf-8").read()
            hits += [f for marker in ("spec" + " §", "spec (", "spec" + ".md") if marker in text]
    assert not hits, hits
