"""VTU frames and PVD index: exact round trips through two readers nobody here wrote (meshio and
VTK via PyVista), every frame listed with its time, atomic writes that survive a kill."""

import os
import signal
import subprocess
import sys
import time

import meshio
import numpy as np
import pytest

import thermonet as tn
from thermonet.io import PVDIndex, VTUWriter, load_checkpoint, read_pvd, save_checkpoint
from thermonet.io import atomic as atomic_module
from thermonet.scenes import load_scene
from thermonet.state import State

pv = pytest.importorskip("pyvista")
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _random_net(rng, n=40, m=90):
    pairs = set()
    while len(pairs) < m:
        a, b = rng.integers(0, n, 2)
        if a != b:
            pairs.add((int(a), int(b)))
    return np.array(sorted(pairs), dtype=np.int64)


def _fields(rng, n, m):
    point = {"displacement": rng.normal(size=(n, 3)), "anchored": rng.integers(0, 2, n).astype(np.uint8),
             "node_temperature": rng.uniform(100, 900, n)}
    cell = {"temperature": rng.uniform(100, 900, m), "strain": rng.normal(size=m) * 1e-3,
            "material": rng.integers(-1, 3, m).astype(np.int32), "tiny": rng.normal(size=m) * 1e-300}
    return point, cell


def _check_meshio(path, points, edges, point, cell):
    mesh = meshio.read(path)
    np.testing.assert_array_equal(mesh.points, points)
    assert [b.type for b in mesh.cells] == ["line"]
    np.testing.assert_array_equal(mesh.cells[0].data, edges)
    for k, v in point.items():
        assert mesh.point_data[k].shape == v.shape
        np.testing.assert_array_equal(mesh.point_data[k], v)
    for k, v in cell.items():
        assert mesh.cell_data[k][0].shape == v.shape
        np.testing.assert_array_equal(mesh.cell_data[k][0], v)


def _check_vtk(path, points, edges, point, cell):
    grid = pv.read(path)
    np.testing.assert_array_equal(grid.points, points)
    assert set(np.asarray(grid.celltypes).tolist()) == {pv.CellType.LINE}
    np.testing.assert_array_equal(grid.cells_dict[pv.CellType.LINE], edges)
    for k, v in point.items():
        np.testing.assert_array_equal(np.asarray(grid.point_data[k]), v)
    for k, v in cell.items():
        np.testing.assert_array_equal(np.asarray(grid.cell_data[k]), v)


def test_frames_round_trip_exactly_through_meshio_and_vtk(tmp_path):
    rng = np.random.default_rng(0)
    edges = _random_net(rng)
    n, m = 40, len(edges)
    writer = VTUWriter(edges, n)
    x = rng.normal(size=(n, 3))
    for frame in range(3):
        x = x + 1e-3 * rng.normal(size=(n, 3))  # moving points
        point, cell = _fields(rng, n, m)
        path = str(tmp_path / f"f_{frame}.vtu")
        writer.write(path, x, point, cell)
        _check_meshio(path, x, edges, point, cell)
        _check_vtk(path, x, edges, point, cell)


def _run_scene(tmp_path, overrides=(), background=True, frames_every=20, direct=True):
    from thermonet.io import RunOutput

    scene = load_scene(os.path.join(ROOT, "scenes", "default.toml"),
                       ["integrator.steps=60", "output.frames_every=20", "output.diagnostics_every=10",
                        "output.checkpoint_every=0", *overrides])
    built = scene.build()
    sim = built.simulation
    out = RunOutput(sim, tmp_path, scene.name, fields=scene.output_fields(), frames_every=frames_every,
                    diagnostics_every=10, checkpoint_every=0, material_id=built.material_id, scene=scene.describe(),
                    background=background, direct=direct)
    sim.run(steps=scene.total_steps(), diagnostics_every=10, observers=out.observers())
    return scene, built, sim


def test_frames_are_the_same_files_written_any_way_and_complete_when_run_returns(tmp_path):
    """On the writer thread or in the observer, direct to the device or through the page cache."""
    ways = {(background, direct): tmp_path / f"{background}-{direct}" for background in (True, False)
            for direct in (True, False)}
    for (background, direct), folder in ways.items():
        _run_scene(folder, background=background, direct=direct)  # read back as soon as run returns
    reference = ways[False, False]
    names = sorted(f for f in os.listdir(reference) if f.endswith((".vtu", ".pvd")))
    assert len(names) == 5
    for folder in ways.values():
        assert names == sorted(f for f in os.listdir(folder) if f.endswith((".vtu", ".pvd")))
        assert not [f for f in os.listdir(folder) if ".tmp-" in f]
        for name in names:
            assert (folder / name).read_bytes() == (reference / name).read_bytes(), (folder, name)


def test_an_error_of_the_last_frame_write_is_raised_by_run(tmp_path, monkeypatch):
    from thermonet.io import vtu

    real = vtu.FrameImage.write
    calls = []

    def full_disk_at_the_last_frame(self, path, direct=True):
        calls.append(path)
        if len(calls) == 4:
            raise OSError(28, "No space left on device")
        return real(self, path, direct)

    monkeypatch.setattr(vtu.FrameImage, "write", full_disk_at_the_last_frame)
    with pytest.raises(OSError, match="No space left"):
        _run_scene(tmp_path)
    assert len(read_pvd(tmp_path / "truss_block.pvd")) == 3


def test_run_frames_hold_the_simulation_fields_and_the_pvd_lists_every_frame_with_its_time(tmp_path):
    scene, built, sim = _run_scene(tmp_path)
    frames = read_pvd(tmp_path / f"{scene.name}.pvd")
    rows = {r["step"]: r["time"] for r in sim.diagnostics.rows}
    assert [t for t, _ in frames] == [rows[s] for s in (0, 20, 40, 60)]
    assert [os.path.basename(f) for _, f in frames] == [f"truss_block_{i:06d}.vtu" for i in range(4)]
    net = built.net
    mesh = meshio.read(frames[-1][1])
    grid = pv.read(frames[-1][1])
    state = sim.state
    expected_cell = {"temperature": sim.temperatures(), "entropy": state.entropy, "strain": sim.strains(),
                     "tension": sim.tensions(), "thermal_displacement": state.thermal_displacement,
                     "material": built.material_id}
    expected_point = {"displacement": state.positions - net.positions, "momentum": state.momenta,
                      "velocity": state.momenta / net.masses[:, None], "anchored": net.anchored.astype(np.uint8)}
    for reader in (lambda k: mesh.cell_data[k][0], lambda k: np.asarray(grid.cell_data[k])):
        for k, v in expected_cell.items():
            np.testing.assert_array_equal(reader(k), v)
    for k, v in expected_point.items():
        np.testing.assert_array_equal(mesh.point_data[k], v)
        np.testing.assert_array_equal(np.asarray(grid.point_data[k]), v)
    np.testing.assert_array_equal(mesh.points, state.positions)
    np.testing.assert_array_equal(mesh.cells[0].data, net.edges)
    theta = sim.temperatures()
    a = 0
    incident = np.flatnonzero((net.edges == a).any(axis=1))
    assert mesh.point_data["node_temperature"][a] == pytest.approx(theta[incident].mean(), rel=1e-14)


def test_thermal_off_frames_have_no_thermal_fields(tmp_path):
    text = open(os.path.join(ROOT, "scenes", "default.toml")).read()
    text = text.replace("temperature = { uniform = 300.0, regions = { hot = 900.0 } }\n", "")
    path = tmp_path / "mech.toml"
    path.write_text(text.replace('mesh = "../meshes/', f'mesh = "{ROOT}/meshes/'))
    from thermonet.cli.main import main

    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet", "--set", "effects.thermal=false",
                 "--set", "integrator.steps=40", "--set", "output.frames_every=20"]) == 0
    frames = read_pvd(tmp_path / "out" / "truss_block.pvd")
    mesh = meshio.read(frames[-1][1])
    assert set(mesh.cell_data) == {"strain", "tension", "material"}
    assert set(mesh.point_data) == {"displacement", "velocity", "momentum", "anchored"}
    state, _ = load_checkpoint(tmp_path / "out" / "truss_block.checkpoint.npz")
    assert state.entropy is None and state.thermal_displacement is None
    with np.load(tmp_path / "out" / "truss_block.checkpoint.npz") as z:
        assert "entropy" not in z.files and "thermal_displacement" not in z.files


class _Killed(BaseException):
    pass


@pytest.mark.parametrize("direct", [True, False], ids=["direct", "page-cache"])
def test_a_kill_during_a_frame_write_leaves_only_complete_frames_listed(tmp_path, monkeypatch, direct):
    real_open, real_write_all = open, atomic_module._write_all
    written = {"frames": 0}

    class TornFile:
        """Writes half of what it is given, then the process 'dies'."""

        def __init__(self, f):
            self.f = f

        def write(self, data):
            self.f.write(data[: len(data) // 2])
            raise _Killed()

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

    def faulty_open(path, mode="r", **kw):
        f = real_open(path, mode, **kw)
        if str(path).endswith(".vtu.tmp-%d" % os.getpid()):
            written["frames"] += 1
            if written["frames"] == 3:
                return TornFile(f)
        return f

    def faulty_write_all(fd, data):
        written["frames"] += 1
        if written["frames"] == 3:
            real_write_all(fd, data[: len(data) // 2])
            raise _Killed()
        real_write_all(fd, data)

    if direct:
        monkeypatch.setattr(atomic_module, "_write_all", faulty_write_all)
    else:
        monkeypatch.setattr(atomic_module, "open", faulty_open, raising=False)
    with pytest.raises(_Killed):
        _run_scene(tmp_path, direct=direct)
    assert written["frames"] == 3
    frames = read_pvd(tmp_path / "truss_block.pvd")
    assert len(frames) == 2
    for _, f in frames:
        meshio.read(f)
        pv.read(f)
    assert not (tmp_path / "truss_block_000002.vtu").exists()


def _padded_bytes(size, seed=3):
    padded = atomic_module.aligned_buffer(size)
    assert padded.ctypes.data % atomic_module.DIRECT_ALIGNMENT == 0
    assert len(padded) % atomic_module.DIRECT_ALIGNMENT == 0 and 0 <= len(padded) - size < atomic_module.DIRECT_ALIGNMENT
    padded[:size] = np.random.default_rng(seed).integers(0, 256, size, dtype=np.uint8)
    return padded


@pytest.mark.parametrize("size", [1, 4095, 4096, 4097, 3 * 4096 + 17])
def test_a_direct_write_holds_exactly_the_first_size_bytes(tmp_path, size):
    padded = _padded_bytes(size)
    target = tmp_path / "frame.vtu"
    target.write_bytes(b"an older frame")
    direct = atomic_module.atomic_write_direct(target, padded, size)
    assert direct == atomic_module.direct_writes_possible(tmp_path)
    assert target.read_bytes() == padded[:size].tobytes()
    assert os.listdir(tmp_path) == ["frame.vtu"]


def test_a_direct_write_falls_back_to_the_page_cache_where_it_is_refused(tmp_path, monkeypatch):
    """tmpfs and some network file systems refuse O_DIRECT at open (EINVAL); a write can also be
    refused part-way. Either way the same bytes arrive, written through the page cache."""
    size = 2 * 4096 + 5
    padded = _padded_bytes(size)
    real_open, real_write = os.open, os.write
    flag = getattr(os, "O_DIRECT", 0)

    def refusing_open(path, flags, *args):
        if flags & flag:
            raise OSError(22, "Invalid argument")
        return real_open(path, flags, *args)

    monkeypatch.setattr(atomic_module.os, "open", refusing_open)
    assert not atomic_module.direct_writes_possible(tmp_path)
    assert atomic_module.atomic_write_direct(tmp_path / "a.vtu", padded, size) is False
    monkeypatch.undo()
    assert (tmp_path / "a.vtu").read_bytes() == padded[:size].tobytes()
    if not atomic_module.direct_writes_possible(tmp_path):
        pytest.skip("this file system refuses O_DIRECT: the part-way refusal cannot be reached")
    calls = []

    def refusing_after_one_block(fd, data):
        calls.append(len(data))
        if len(calls) == 2:
            raise OSError(22, "Invalid argument")
        return real_write(fd, data[:4096])

    monkeypatch.setattr(atomic_module.os, "write", refusing_after_one_block)
    assert atomic_module.atomic_write_direct(tmp_path / "b.vtu", padded, size) is False
    monkeypatch.undo()
    assert (tmp_path / "b.vtu").read_bytes() == padded[:size].tobytes()
    assert sorted(os.listdir(tmp_path)) == ["a.vtu", "b.vtu"]


def test_a_failed_direct_write_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    padded = _padded_bytes(10_000)
    target = tmp_path / "frame.vtu"
    target.write_bytes(b"the frame before")

    def full_disk(fd, data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(atomic_module, "_write_all", full_disk)
    monkeypatch.setattr(atomic_module, "open", lambda *a, **k: full_disk(None, None), raising=False)  # fallback
    with pytest.raises(OSError, match="No space left"):
        atomic_module.atomic_write_direct(target, padded, 10_000)
    assert target.read_bytes() == b"the frame before" and os.listdir(tmp_path) == ["frame.vtu"]
    with pytest.raises(ValueError, match="aligned_buffer"):
        atomic_module.atomic_write_direct(target, np.zeros(4096, np.uint8)[1:], 10)


def test_a_kill_during_the_index_rewrite_keeps_the_previous_index(tmp_path, monkeypatch):
    index = PVDIndex(tmp_path / "x.pvd")
    index.add(0, 0.0, "x_000000.vtu")
    index.add(10, 0.5, "x_000001.vtu")
    before = (tmp_path / "x.pvd").read_bytes()

    def dying_replace(src, dst):
        raise _Killed()

    monkeypatch.setattr(atomic_module.os, "replace", dying_replace)
    with pytest.raises(_Killed):
        index.add(20, 1.0, "x_000002.vtu")
    monkeypatch.undo()
    assert (tmp_path / "x.pvd").read_bytes() == before
    assert [t for t, _ in read_pvd(tmp_path / "x.pvd")] == [0.0, 0.5]


def test_a_process_killed_at_a_random_moment_leaves_a_readable_series(tmp_path):
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "thermonet.cli.main", "run", "--out", str(out), "--quiet",
           "--set", "output.frames_every=5", "--set", "integrator.steps=100000", "--set", "output.diagnostics_every=5"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    pvd = out / "truss_block.pvd"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and (not pvd.exists() or len(read_pvd(pvd)) < 8):
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    frames = read_pvd(pvd)
    assert len(frames) >= 8
    for _, f in frames:
        assert meshio.read(f).points.shape[0] == 491
    np.genfromtxt(out / "diagnostics.csv", delimiter=",", names=True)


def test_checkpoints_keep_the_state_exactly(tmp_path):
    rng = np.random.default_rng(1)
    state = State(rng.normal(size=(7, 3)), rng.normal(size=(7, 3)), rng.normal(size=11), rng.normal(size=11),
                  time=0.1 + 0.2, step=3)
    save_checkpoint(tmp_path / "c.npz", state, {"diagnostics": [{"step": 3, "energy": 1 / 3}]})
    back, meta = load_checkpoint(tmp_path / "c.npz")
    for k in ("positions", "momenta", "thermal_displacement", "entropy"):
        np.testing.assert_array_equal(getattr(back, k), getattr(state, k))
    assert back.time == state.time and back.step == 3 and meta["diagnostics"][0]["energy"] == 1 / 3


@pytest.mark.parametrize("int32_limit", [2**31, 10])  # 10: the Int64 topology of very large nets
def test_frame_image_views_are_aligned_and_odd_sizes_round_trip(tmp_path, monkeypatch, int32_limit):
    """Odd node and spring counts make the UInt8/Int32 arrays end off an 8-byte boundary: they
    must go last, every float64 view must stay aligned, and both readers must still agree."""
    from thermonet.io import vtu

    monkeypatch.setattr(vtu, "INT32_LIMIT", int32_limit)
    rng = np.random.default_rng(3)
    n = 37
    edges = _random_net(rng, n=n, m=91)
    m = len(edges)
    point, cell = _fields(rng, n, m)
    point["velocity"] = rng.normal(size=(n, 3))
    writer = VTUWriter(edges, n)
    x = rng.normal(size=(n, 3))
    path = str(tmp_path / "odd.vtu")
    writer.write(path, x, point, cell)
    image = writer.image({k: (v.dtype, v.shape[1] if v.ndim > 1 else 0) for k, v in point.items()},
                         {k: (v.dtype, 0) for k, v in cell.items()})
    assert image.points.flags.aligned and image.points.ctypes.data % 8 == 0
    for view in (*image.point.values(), *image.cell.values()):
        if view.dtype == np.float64:
            assert view.ctypes.data % 8 == 0
    _check_meshio(path, x, edges, point, cell)
    _check_vtk(path, x, edges, point, cell)
    header = open(path, "rb").read(2000)
    index_type = b"Int32" if int32_limit > 2 * m else b"Int64"
    assert b'type="%s" Name="connectivity"' % index_type in header


@pytest.mark.parametrize("parallel", [False, True])
def test_passes_to_user_numbering_equal_the_numpy_expressions(parallel):
    from thermonet.kernels.gather import passes

    gather = passes(parallel)
    from thermonet.layout import build_layout
    from thermonet.net import Net

    rng = np.random.default_rng(4)
    n, m = 57, 131
    node_order = rng.permutation(n)
    node_rank = np.argsort(node_order)  # user u is internal rank[u]
    x, p, X = rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    masses = rng.uniform(0.5, 2.0, n)
    outs = [np.empty((n, 3)) for _ in range(4)]
    gather.node_fields_to_user(*outs, x, p, X, masses, node_order)
    for out, expected in zip(outs, (x[node_rank], x[node_rank] - X, p[node_rank] / masses[:, None], p[node_rank])):
        np.testing.assert_array_equal(out, expected)
    points, none = np.empty((n, 3)), np.empty((0, 3))
    gather.node_fields_to_user(points, none, none, none, x, p, X, masses, node_order)  # only points
    np.testing.assert_array_equal(points, x[node_rank])
    edges = np.unique(np.sort(_random_net(rng, n=n, m=m), axis=1), axis=0)  # no spring twice
    lay = build_layout(Net(positions=rng.normal(size=(n, 3)), edges=edges), renumber=True)
    values = rng.normal(size=len(edges))  # internal numbering
    means = np.empty(n)
    gather.node_means_to_user(means, values, lay.inc_ptr, lay.inc_spring, lay.node_order)
    user_values = values[lay.spring_rank]
    ends = edges.reshape(-1)
    degree = np.bincount(ends, minlength=n)
    expected = np.bincount(ends, weights=np.repeat(user_values, 2), minlength=n) / np.maximum(degree, 1)
    np.testing.assert_allclose(means, expected, rtol=1e-13, atol=1e-15)
    assert np.all(means[degree == 0] == 0.0)


@pytest.mark.parametrize("parallel", [False, True])
@pytest.mark.parametrize("model, thermal", [("hencky", True), ("quadratic", True), ("hencky", False)])
def test_frame_spring_pass_equals_the_public_accessors_bit_for_bit(parallel, model, thermal):
    """The frame's one spring pass (computed and scattered to user order) against
    sim.temperatures(), tensions(), strains() and the state's η and Φ; strains within an ulp of
    NumPy's log."""
    from thermonet.kernels.records import Springs
    from thermonet.kernels.springs import FrameFields, frame_spring_kernel

    net = tn.lattice((4, 3, 3), jitter=0.2, seed=3)
    rng = np.random.default_rng(5)
    m = net.n_springs
    kwargs = dict(temperatures=rng.uniform(250.0, 400.0, m)) if thermal else dict(thermal=False)
    sim = tn.Simulation(net, model=model, momenta=rng.normal(0.0, 0.5, (net.n_nodes, 3)), h=0.01, **kwargs)
    sim.run(steps=7)
    assert not np.array_equal(sim.layout.spring_order, np.arange(m))  # a real permutation
    s, system = sim.internal_state(), sim.system
    out = {k: np.full(m, np.nan) for k in ("temperature", "tension", "strain", "entropy", "phi", "internal")}
    none = np.empty(0)
    eta = s.entropy if thermal else none
    phi = s.thermal_displacement if thermal else none
    kernel = frame_spring_kernel(system.model, thermal, parallel)
    fields = FrameFields(temperature=out["temperature"], tension=out["tension"], strain=out["strain"],
                         entropy=out["entropy"] if thermal else none, thermal_displacement=out["phi"] if thermal else none)
    kernel(s.positions, eta, phi, Springs(system.rest_lengths, system.parameters), system.edges.view(np.uint32),
           np.ascontiguousarray(sim.layout.spring_order, dtype=np.int64), np.empty((4, m)), fields, out["internal"])
    np.testing.assert_array_equal(out["temperature"], sim.temperatures())
    np.testing.assert_array_equal(out["internal"], sim.internal_spring_fields().temperature)
    np.testing.assert_array_equal(out["tension"], sim.tensions())
    np.testing.assert_array_equal(out["strain"], sim.strains())
    np.testing.assert_array_max_ulp(out["strain"], np.log(sim.lengths() / net.rest_lengths), maxulp=1)
    if thermal:
        np.testing.assert_array_equal(out["entropy"], sim.state.entropy)
        np.testing.assert_array_equal(out["phi"], sim.state.thermal_displacement)


def test_by_default_frames_are_written_direct_on_the_writer_thread_where_the_folder_allows(tmp_path):
    from thermonet.io import RunOutput
    from thermonet.io.series import idle_core

    scene = load_scene(os.path.join(ROOT, "scenes", "default.toml"), ["integrator.steps=40"])
    built = scene.build()
    sim = built.simulation
    out = RunOutput(sim, tmp_path, scene.name, fields=scene.output_fields(), frames_every=20, diagnostics_every=10,
                    checkpoint_every=0, material_id=built.material_id, scene=scene.describe())
    direct = atomic_module.direct_writes_possible(tmp_path)
    assert out.direct == direct and out.background == (direct or idle_core(sim))
    sim.run(steps=40, observers=out.observers())
    assert out.direct_writes == (3 if direct else 0) and len(read_pvd(tmp_path / f"{scene.name}.pvd")) == 3


def test_frames_go_to_the_writer_thread_only_where_a_core_is_idle():
    from thermonet.io.series import idle_core

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    net = tn.lattice((3, 3, 3))
    serial = tn.Simulation(net, h=0.01, parallel=False)
    every_core = tn.Simulation(net, h=0.01, parallel=True, threads=cores)
    assert idle_core(serial) == (cores > 1)
    assert not idle_core(every_core)
    if cores > 1:
        assert idle_core(tn.Simulation(net, h=0.01, parallel=True, threads=cores - 1))


def test_the_pvd_is_rewritten_at_an_interval_and_complete_when_run_returns(tmp_path, monkeypatch):
    """Frames every step: the index is not rewritten per frame (that grows with the number of
    frames), yet lists every frame once run returns."""
    writes = []
    real = PVDIndex.write

    def counted(self):
        writes.append(len(self.frames))
        real(self)

    monkeypatch.setattr(PVDIndex, "write", counted)
    scene, built, sim = _run_scene(tmp_path, ["output.frames_every=1"], frames_every=1)
    assert len(read_pvd(tmp_path / "truss_block.pvd")) == 61
    assert 2 <= len(writes) < 10 and writes[0] == 1 and writes[-1] == 61


def test_observers_given_as_a_generator_are_flushed_too(tmp_path):
    from thermonet.io import RunOutput

    scene = load_scene(os.path.join(ROOT, "scenes", "default.toml"), ["integrator.steps=40"])
    built = scene.build()
    sim = built.simulation
    out = RunOutput(sim, tmp_path, scene.name, fields=scene.output_fields(), frames_every=20, diagnostics_every=10,
                    checkpoint_every=0, material_id=built.material_id, scene=scene.describe(), background=True)
    sim.run(steps=40, observers=(pair for pair in out.observers()))
    assert out._pending is None and len(read_pvd(tmp_path / f"{scene.name}.pvd")) == 3
