"""A net run over MPI processes (docs/parallel.md) is the run of one process, bit for bit.

The default scene runs in this process (which also fills Numba's disk cache: the processes
started by ``mpiexec`` then load the kernels instead of compiling them) and over 2 processes, cut
in two and resumed on 3 and in one process, and killed and resumed on 2; the tensile scene (a
drive) with a multi-stage splitting (a halo exchange per stage) over 3; the thermal-shock scene
(conduction from a bath, multirate) over 2, resumed on 3; their diagnostics and probe files,
checkpoints (one piece per process, put back together) and frames (ParaView's parallel pieces,
joined back by the node and spring numbers they carry) must be the same bytes. A checkpoint with
a piece missing, foreign or damaged is refused, naming it. Effects the distributed step does not
carry are refused in one line naming them.
"""

import importlib.util
import io
import json
import os
import shutil
import subprocess
import sys
from xml.etree import ElementTree as ET

import meshio
import numpy as np
import pytest

import thermonet as tn
from thermonet.cli.main import main
from thermonet.errors import InputError
from thermonet.io.pvd import read_pvd

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT = os.path.join(ROOT, "scenes", "default.toml")
TENSILE = os.path.join(ROOT, "scenes", "tensile.toml")
SHOCK = os.path.join(ROOT, "scenes", "thermal_shock.toml")
#: 200 steps of the default scene: rows every 20, frames every 100, the checkpoint at the end
RUN = ["--set", "output.frames_every=100", "--set", "output.diagnostics_every=20",
       "--set", "output.checkpoint_every=200", "--quiet"]
SHORT = ["--set", "integrator.t_end=0.04"]


def _mpiexec():
    """The mpiexec beside this Python (the mpich wheel's), else on the PATH; None without one."""
    beside = os.path.join(os.path.dirname(sys.executable), "mpiexec")
    return beside if os.access(beside, os.X_OK) else shutil.which("mpiexec")


MPIEXEC = _mpiexec()
needs_mpi = pytest.mark.skipif(MPIEXEC is None or importlib.util.find_spec("mpi4py") is None,
                               reason="needs mpi4py and mpiexec (pip install 'thermonet[mpi]')")


def mpirun(ranks: int, *args, timeout: int = 300, module: bool = True, ok: bool = True) -> subprocess.CompletedProcess:
    """``mpiexec -n ranks python -m thermonet *args`` (``python *args`` unless ``module``) with
    this checkout on the path; ``ok``: its exit status must be 0."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([ROOT, os.environ.get("PYTHONPATH", "")]),
               NUMBA_NUM_THREADS="1")
    command = [sys.executable, "-m", "thermonet", *args] if module else [sys.executable, *args]
    done = subprocess.run([MPIEXEC, "-n", str(ranks), *command], env=env, capture_output=True, text=True,
                          timeout=timeout)
    assert done.returncode == 0 or not ok, done.stdout + done.stderr
    return done


def checkpoint(folder, name: str = "truss_block") -> dict:
    """The checkpoint's state as the arrays of a one-file checkpoint (a run over processes writes
    a manifest and one piece per process: put together by load_checkpoint)."""
    state, _ = tn.io.load_checkpoint(os.path.join(folder, f"{name}.checkpoint.npz"))
    out = {k: getattr(state, k) for k in ("positions", "momenta", "entropy", "thermal_displacement")
           if getattr(state, k) is not None}
    out.update(time=np.float64(state.time), step=np.int64(state.step))
    out.update({f"heat_{k}": v for k, v in state.extra.pop("heat", {}).items()})
    out.update({f"extra.{k}": v for k, v in state.extra.items()})
    return out


def pieces_of(folder, name: str = "truss_block") -> list:
    """[(format, the pieces' folders, the pieces in the one listed)] of a run's checkpoint."""
    path = os.path.join(folder, f"{name}.checkpoint.npz")
    with np.load(path) as z:
        meta = json.loads(bytes(z["meta"]).decode())
    base = path[:-len(".npz")] + ".pieces"
    listed = os.path.join(folder, meta["pieces"]["folder"]) if "pieces" in meta else None
    return [meta["format"], sorted(os.listdir(base)) if os.path.isdir(base) else [],
            sorted(os.listdir(listed)) if listed else []]


def assert_same_run(one, many, name: str = "truss_block") -> None:
    """Same diagnostics (and probe) bytes, same checkpointed state bits."""
    tables = sorted(f for f in os.listdir(one) if f.endswith(".csv"))
    assert tables == sorted(f for f in os.listdir(many) if f.endswith(".csv"))
    for table in tables:
        with open(os.path.join(one, table), "rb") as a, open(os.path.join(many, table), "rb") as b:
            assert a.read() == b.read(), table
    a, b = checkpoint(one, name), checkpoint(many, name)
    assert a.keys() == b.keys() and {"positions", "momenta", "entropy", "thermal_displacement"} <= set(a)
    for k in a:
        assert np.array_equal(a[k], b[k]), k


_DTYPES = {"Float64": np.float64, "Int64": np.int64, "Int32": np.int32, "UInt8": np.uint8}


def read_vtu(path) -> meshio.Mesh:
    """A frame or piece as thermonet writes it (raw appended arrays, each after its UInt64 byte
    count; line cells). meshio's own reader of raw appended data rewrites the offsets in place
    while it looks them up, and takes the wrong array where a rewritten offset equals one still
    to come (it happens on some pieces)."""
    raw = open(path, "rb").read()
    start = raw.index(b"<AppendedData")
    base = raw.index(b"_", start) + 1
    piece = ET.fromstring(raw[:start] + b"</VTKFile>").find("UnstructuredGrid/Piece")

    def array(tag):
        offset = base + int(tag.get("offset"))
        dtype = np.dtype(_DTYPES[tag.get("type")])
        n = int(np.frombuffer(raw, np.uint64, 1, offset)[0]) // dtype.itemsize
        data = np.frombuffer(raw, dtype, n, offset + 8)
        return data.reshape(-1, int(tag.get("NumberOfComponents"))) if tag.get("NumberOfComponents") else data

    points = array(piece.find("Points/DataArray"))
    cells = array(piece.find("Cells/DataArray[@Name='connectivity']")).reshape(-1, 2).astype(np.int64)
    point_data = {t.get("Name"): array(t) for t in piece.iterfind("PointData/DataArray")}
    cell_data = {t.get("Name"): [array(t)] for t in piece.iterfind("CellData/DataArray")}
    return meshio.Mesh(points, [("line", cells)], point_data=point_data, cell_data=cell_data)


def joined_frame(pvtu: str, ranks: int) -> meshio.Mesh:
    """The pieces a .pvtu lists, read with meshio and put back in the whole net's numbering."""
    sources = [p.get("Source") for p in ET.parse(pvtu).getroot().iter("Piece")]
    assert len(sources) == ranks
    pieces = [read_vtu(os.path.join(os.path.dirname(pvtu), s)) for s in sources]
    nodes = np.concatenate([p.point_data["node_id"] for p in pieces])
    springs = np.concatenate([p.cell_data["spring_id"][0] for p in pieces])
    n, m = nodes.max() + 1, len(springs)
    assert np.array_equal(np.sort(springs), np.arange(m))  # each spring in exactly one piece
    points = np.empty((n, 3))
    cells = np.empty((m, 2), dtype=np.int64)
    point_data = {k: np.empty((n,) + v.shape[1:], v.dtype) for k, v in pieces[0].point_data.items() if k != "node_id"}
    cell_data = {k: np.empty((m,) + v[0].shape[1:], v[0].dtype) for k, v in pieces[0].cell_data.items()
                 if k != "spring_id"}
    for p in pieces:
        ids, sid = p.point_data["node_id"], p.cell_data["spring_id"][0]
        points[ids] = p.points
        cells[sid] = ids[p.cells[0].data]
        for k in point_data:
            point_data[k][ids] = p.point_data[k]
        for k in cell_data:
            cell_data[k][sid] = p.cell_data[k][0]
    return meshio.Mesh(points, [("line", cells)], point_data=point_data,
                       cell_data={k: [v] for k, v in cell_data.items()})


def assert_same_frames(one, many, ranks, name: str = "truss_block") -> list:
    """Every frame of ``many`` (each of ``ranks`` pieces: a count, or the counts allowed) joined
    is that of ``one``; returns the frames' piece counts."""
    counts = []
    serial, parallel = read_pvd(os.path.join(one, f"{name}.pvd")), read_pvd(os.path.join(many, f"{name}.pvd"))
    assert [t for t, _ in serial] == [t for t, _ in parallel] and len(serial) >= 2
    for (_, a), (_, b) in zip(serial, parallel):
        assert b.endswith(".pvtu")
        pieces = len(list(ET.parse(b).getroot().iter("Piece")))
        assert pieces in (ranks if isinstance(ranks, tuple) else (ranks,))
        counts.append(pieces)
        whole, joined = read_vtu(a), joined_frame(b, pieces)
        assert np.array_equal(whole.points, joined.points)
        assert np.array_equal(whole.cells[0].data, joined.cells[0].data)
        assert whole.point_data.keys() == joined.point_data.keys() and whole.cell_data.keys() == joined.cell_data.keys()
        for k in whole.point_data:
            assert np.array_equal(whole.point_data[k], joined.point_data[k]), k
        for k in whole.cell_data:
            assert np.array_equal(whole.cell_data[k][0], joined.cell_data[k][0]), k
    return counts


def compile_here(scene: str) -> None:
    """Compile the distributed step's own functions for ``scene`` in this process (one step over
    ``MPI.COMM_SELF``), so that the processes ``mpiexec`` starts load them from the disk cache
    instead of each compiling them at once on a machine with fewer cores than processes."""
    from mpi4py import MPI

    from thermonet.parallel.stepper import DistributedStepper
    from thermonet.scenes import load_scene

    sim = load_scene(scene).build().simulation
    points = sim.layout.nodes_to_internal(sim.net.positions)
    stepper = DistributedStepper(sim.integrator, sim.system, MPI.COMM_SELF, points, sim.parallel)
    if stepper.loads is not None:
        stepper.loads.time_origin = sim.time_origin
    stepper.advance(sim.internal_state().copy(), 1, sim.h)


@pytest.fixture(scope="module")
def one_process(tmp_path_factory):
    """The default scene's 200 steps in this process (the kernels compiled here, cached on disk)."""
    out = tmp_path_factory.mktemp("one") / "run"
    assert main(["run", DEFAULT, "--out", str(out), *SHORT, *RUN]) == 0
    if MPIEXEC is not None and importlib.util.find_spec("mpi4py") is not None:
        compile_here(DEFAULT)
    return out


@needs_mpi
def test_two_processes_cut_in_two_and_resumed_on_three_are_one_process_bit_for_bit(one_process, tmp_path):
    """A run cut on 2 processes (a checkpoint of two pieces and a manifest) continues on 3 (whose
    checkpoint replaces the two pieces by three) and in one process (whose one-file checkpoint
    replaces the pieces), bit for bit. In the same
    launch of 2 processes, every kind of splitting over them and alone: drift first (F10, BM6A), a
    kick of 0 (GTR-0, GTR-1), no Φ (NM2), a composition (CO4); then CO2 continued at a step that
    blows up (the good steps replayed from the runner's backup of the shares) and at one the
    energy guard stops (the state rewound to the stop before)."""
    out = tmp_path / "run"
    names = ["f10", "gtr-0", "gtr-1", "nm2", "bm6a", "co4", "co2@8e-4", "co2@5e-4"]
    done = mpirun(2, os.path.join(ROOT, "tests", "mpi_integrators.py"), DEFAULT, "20", *names, "--", "run", DEFAULT,
                  "--out", str(out), "--set", "integrator.t_end=0.02", *RUN, module=False)
    assert done.stdout.split() == [w for n in names for w in (n, "same")] + ["share", "only"], done.stdout
    assert checkpoint(out)["step"] == 100
    cut = pieces_of(out)
    assert cut[0] == "thermonet-checkpoint-pieces-1" and len(cut[1]) == 1, cut
    assert cut[2] == ["piece-00000.npz", "piece-00001.npz"]
    alone = tmp_path / "alone"  # (the pieces of 2 processes continued in one)
    shutil.copytree(out, alone)
    mpirun(3, "run", "--resume", str(out), *SHORT, "--quiet")
    assert_same_run(one_process, out)
    resumed = pieces_of(out)  # (the pieces of the checkpoint resumed from removed)
    assert len(resumed[1]) == 1 and resumed[1] != cut[1] and len(resumed[2]) == 3, resumed
    assert main(["run", "--resume", str(alone), *SHORT, "--quiet"]) == 0
    assert_same_run(one_process, alone)
    assert pieces_of(alone) == ["thermonet-checkpoint-1", [], []]
    # frame 0 from two pieces; 100 (rewritten on resume) and 200 from three
    assert assert_same_frames(one_process, out, (2, 3)) == [2, 3, 3]
    from thermonet.io.folder import run_files  # (--overwrite removes them, a new run is refused)

    assert {"truss_block_000000.pvtu", "truss_block_000000_p1.vtu", "truss_block_000002_p2.vtu"} <= set(run_files(out))
    assert not [f for f in os.listdir(out) if f.endswith(".vtu") and "_p" not in f]  # pieces only


@needs_mpi
def test_a_run_on_two_processes_killed_after_a_checkpoint_resumes_bit_for_bit(one_process, tmp_path):
    """The default scene on 2 processes, killed at step 150 by one process's abort (its checkpoint
    of step 100 is then the last), resumed on 2: the one-process run's rows and state."""
    out = tmp_path / "run"
    killed = mpirun(2, os.path.join(ROOT, "tests", "mpi_killed.py"), "150", "run", DEFAULT, "--out", str(out),
                    *SHORT, *RUN, "--set", "output.checkpoint_every=100", module=False, ok=False)
    assert killed.returncode != 0
    assert checkpoint(out)["step"] == 100
    mpirun(2, "run", "--resume", str(out), "--quiet")
    assert_same_run(one_process, out)


@needs_mpi
def test_a_checkpoint_with_a_piece_missing_foreign_or_damaged_is_refused_naming_it(tmp_path):
    """A checkpoint written by 2 processes (a manifest and two pieces) read back whole; then with
    one piece deleted, of another checkpoint, truncated, or holding a node the other holds: each
    refused with an error naming the piece."""
    from thermonet.io import load_checkpoint

    mpirun(2, "run", DEFAULT, "--out", str(tmp_path), "--set", "integrator.t_end=0.004", "--set",
           "output.checkpoint_every=2", "--quiet")
    path = tmp_path / "truss_block.checkpoint.npz"
    whole, _ = load_checkpoint(path)
    assert whole.step == 20 and np.isfinite(whole.positions).all()
    piece = tmp_path / "truss_block.checkpoint.pieces" / pieces_of(tmp_path)[1][0] / "piece-00001.npz"
    kept = piece.read_bytes()
    with np.load(io.BytesIO(kept)) as z:
        arrays = {k: z[k] for k in z.files}

    def rewritten(**changed):
        header = {**json.loads(bytes(arrays["meta"]).decode()), **changed.pop("header", {})}
        meta = np.frombuffer(json.dumps(header).encode(), dtype=np.uint8)
        with open(piece, "wb") as f:
            np.savez(f, **{**arrays, **changed, "meta": meta})

    piece.unlink()
    with pytest.raises(InputError, match=r"piece-00001\.npz: no such checkpoint piece"):
        load_checkpoint(path)
    rewritten(header={"tag": "000000002-00000000"})  # (as the pieces of step 2 were)
    with pytest.raises(InputError, match=r"piece-00001\.npz: a piece of another checkpoint"):
        load_checkpoint(path)
    piece.write_bytes(kept[:len(kept) // 2])
    with pytest.raises(InputError, match=r"piece-00001\.npz: not a readable thermonet checkpoint piece"):
        load_checkpoint(path)
    first = np.load(piece.parent / "piece-00000.npz")["nodes"][0]
    rewritten(nodes=np.concatenate([[first], arrays["nodes"][1:]]))
    with pytest.raises(InputError, match=rf"piece-00001\.npz: node {first} is in another piece too"):
        load_checkpoint(path)
    piece.write_bytes(kept)
    again, _ = load_checkpoint(path)
    assert np.array_equal(again.positions, whole.positions)


@needs_mpi
def test_three_processes_pulling_the_tensile_bar_with_omf4_are_one_process_bit_for_bit(tmp_path):
    """The tensile scene (a drive: its reaction and work summed over the grip's nodes in order;
    probes) with OMF4 (five kicks and four drifts per step, a halo exchange after each drift);
    processes other than rank 0 hold none of the loads' whole-net arrays."""
    args = ["--set", 'integrator.name="omf4"', "--set", "integrator.t_end=0.2", "--set", "output.frames_every=50",
            "--set", "output.diagnostics_every=10", "--set", "output.checkpoint_every=100", "--quiet"]
    assert main(["run", TENSILE, "--out", str(tmp_path / "one"), *args]) == 0
    compile_here(TENSILE)
    # (the run, then what the processes hold with a drive: one launch)
    done = mpirun(3, os.path.join(ROOT, "tests", "mpi_integrators.py"), TENSILE, "20", "--", "run", TENSILE, "--out",
                  str(tmp_path / "three"), *args, module=False)
    assert done.stdout.split() == ["share", "only"], done.stdout
    assert_same_run(tmp_path / "one", tmp_path / "three", "tensile")
    assert "extra.load_work" in checkpoint(tmp_path / "three", "tensile")
    assert_same_frames(tmp_path / "one", tmp_path / "three", 3, "tensile")


@needs_mpi
def test_the_thermal_shock_on_two_processes_resumed_on_three_is_one_process_bit_for_bit(tmp_path):
    """Conduction from a bath (each process sweeping its blocks, temperatures exchanged between
    colours; the kick deferred past the sweeps) every 2 steps: cut on 2 processes, resumed on 3,
    the parts cut between the sweep's blocks (the default); then, on 3 processes with RCB parts
    (blocks cut by the parts), calls of uneven lengths ending inside 3-step cycles with 2
    sub-sweeps (as a replay after a blow-up)."""
    args = ["--set", "effects.conduction_every=2", "--set", "output.frames_every=10", "--set",
            "output.diagnostics_every=2", "--set", "output.checkpoint_every=10", "--quiet"]
    assert main(["run", SHOCK, "--out", str(tmp_path / "one"), "--set", "integrator.t_end=0.2", *args]) == 0
    compile_here(SHOCK)
    mpirun(2, "run", SHOCK, "--out", str(tmp_path / "cut"), "--set", "integrator.t_end=0.1", *args)
    # (the resumed run and the calls in one launch)
    done = mpirun(3, os.path.join(ROOT, "tests", "mpi_conduction.py"), SHOCK, "3,1,4,1", "3x2:rcb", "--",
                  "run", "--resume", str(tmp_path / "cut"), "--set", "integrator.t_end=0.2", "--quiet", module=False)
    assert done.stdout.splitlines() == ["same", "share only"], done.stdout
    assert_same_run(tmp_path / "one", tmp_path / "cut", "thermal_shock")
    assert {"heat_produced", "heat_entry_heat", "heat_theta", "heat_pending_eta"} <= set(
        checkpoint(tmp_path / "cut", "thermal_shock"))
    assert assert_same_frames(tmp_path / "one", tmp_path / "cut", (2, 3), "thermal_shock") == [2, 3, 3]


class TwoProcesses:
    """A stand-in communicator of two processes: the effects are checked before any message."""

    def Get_size(self):
        return 2

    def Get_rank(self):
        return 0

    def send(self, value, dest, tag=0):  # (rank 0 tells the other process of its error)
        pass


def _refused(match: str, **kwargs) -> str:
    parameters = dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0)
    parameters.update(kwargs.pop("extra", {}))
    net = tn.chain()
    net.node_groups["all"] = np.arange(net.n_nodes)
    with pytest.raises(InputError, match=match) as info:
        tn.Simulation(net, parameters=parameters, comm=TwoProcesses(), **kwargs)
    message = str(info.value)
    assert "\n" not in message and "over 2 MPI processes" in message
    return message


def test_effects_the_distributed_step_does_not_carry_are_refused_by_name():
    from push_subflow import push

    from thermonet.loads import Force

    _refused("thermal waves", extra=dict(g=1.0, g_star=1.0))
    _refused("heat conduction together with loads", extra=dict(g=1.0),
             loads={"push": Force("all", [1.0, 0.0, 0.0], total=True)})
    _refused("implicit integrator 'em2'", integrator="em2")
    _refused("extra sub-flows", integrator=tn.get_integrator("co2").with_flow(push([1], [0.1, 0.0, 0.0])))


def test_mpi4py_is_needed_only_under_an_mpi_launcher(monkeypatch):
    from thermonet.parallel import world
    from thermonet.parallel.world import LAUNCHER_VARIABLES

    for name in LAUNCHER_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setitem(sys.modules, "mpi4py", None)  # as if not installed
    assert world() is None  # one process: mpi4py is not imported
    monkeypatch.setenv("PMI_SIZE", "2")
    with pytest.raises(InputError, match=r"mpi4py is not installed: pip install 'thermonet\[mpi\]'"):
        world()


@needs_mpi
def test_mpi_memory_quick_mode_reports_each_process_share():
    lines = mpirun(2, os.path.join(ROOT, "benchmarks", "mpi_memory.py"), "--quick", module=False).stdout.splitlines()
    reports = sorted(line for line in lines if line.startswith("process "))
    assert [r.split(":")[0] for r in reports] == ["process 0", "process 1"]
    assert all("; share: " in r and " MB" in r for r in reports)


@needs_mpi
def test_mpi_scaling_quick_mode_runs_one_and_two_processes_with_the_same_bits(one_process, capsys):
    spec = importlib.util.spec_from_file_location("benchmark_mpi_scaling", os.path.join(ROOT, "benchmarks",
                                                                                          "mpi_scaling.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    rows = module.main(["--quick"])
    assert [r["processes"] for r in rows] == [1, 2]
    assert all(r["identical"] and r["seconds_per_step"] > 0 for r in rows)
    two = rows[1]["ranks"]
    assert len(two) == 2 and all(r["bytes"] > 0 and r["messages"] >= 1 and r["rss_mb"] > 0 for r in two)
    one = rows[0]["ranks"][0]
    assert all(0 < r["stepping_mb"] < one["stepping_mb"] for r in two)  # a share, not the whole net
    assert "| 2 processes × 1 thread |" in capsys.readouterr().out


@pytest.mark.parametrize("method", ["rcb", "metis"])
def test_every_owned_node_sums_its_springs_in_the_whole_nets_order(method):
    """The invariant behind the bits: in its share, each owned node lists the same springs, to the
    same other nodes, in the same order as in the whole net; the halo lists agree pairwise."""
    from thermonet.layout import build_layout
    from thermonet.parallel.domain import decomposition, share
    from thermonet.parallel.partition import partition

    if method == "metis":
        pytest.importorskip("pymetis")
    net = tn.lattice((5, 4, 3), neighbours=18, jitter=0.1)
    layout = build_layout(net)
    edges = layout.edges
    owner = partition(layout.nodes_to_internal(net.positions), edges, 3, method)
    dec = decomposition(owner, edges, 3)
    shares = [share(dec, edges, r) for r in range(3)]
    assert np.array_equal(np.sort(np.concatenate([s.nodes[s.owned] for s in shares])), np.arange(net.n_nodes))
    assert np.array_equal(np.sort(np.concatenate([dec.owned_springs(r) for r in range(3)])), np.arange(net.n_springs))
    for s in shares:
        topo = s.topology
        for a in np.flatnonzero(s.owned):
            g = s.nodes[a]
            lo, hi = topo.inc_ptr[a], topo.inc_ptr[a + 1]
            whole = slice(layout.inc_ptr[g], layout.inc_ptr[g + 1])
            assert np.array_equal(s.springs[topo.inc_spring[lo:hi]], layout.inc_spring[whole])
            assert np.array_equal(s.nodes[topo.inc_other[lo:hi]], layout.inc_other[whole])
        assert np.array_equal(s.nodes[topo.edges.view(np.int32)], edges[s.springs])  # orientation kept
        ghosts = np.flatnonzero(~s.owned)
        assert np.array_equal(np.sort(np.concatenate(list(s.recv.values()))), ghosts)
        for q, idx in s.send.items():
            assert np.array_equal(s.nodes[idx], shares[q].nodes[shares[q].recv[s.rank]])


def test_blocks_parts_keep_every_conduction_block_in_one_process():
    """The default parts with conduction: ranges of the internal numbering cut between the
    sweep's blocks (a block straddling two processes would make its owner hold and exchange the
    other side's temperatures at every colour); balanced to within a block."""
    from thermonet.heat.graph import star_order
    from thermonet.layout import build_layout
    from thermonet.parallel.partition import partition
    from thermonet.parallel.stepper import _block_spans

    net = tn.lattice((9, 4, 3), neighbours=18, jitter=0.1)
    layout = build_layout(net)
    order = star_order(layout, np.ones(net.n_springs), np.ones(net.n_nodes, dtype=bool), 16)
    owner = partition(layout.nodes_to_internal(net.positions), layout.edges, 3, "blocks", _block_spans(order))
    for b in range(order.n_blocks):
        assert len(np.unique(owner[order.node[order.block_ptr[b]:order.block_ptr[b + 1]]])) == 1
    counts = np.bincount(owner, minlength=3)
    assert counts.min() > 0 and counts.max() - counts.min() <= 2 * 16
    assert np.all(np.diff(owner) >= 0)  # ranges of the numbering


def _reference_heat_share(order, inc_ptr, inc_spring, bound_spring, bound_ptr, dec, share_springs, rank):
    """The plan of :func:`thermonet.parallel.heat_share.heat_shares` made the plain way: every
    process's holdings and every colour's writers as whole-net masks (P arrays of m entries)."""
    from thermonet.parallel.heat_share import Plan, _touched, ranges

    inc_ptr, inc_spring = np.asarray(inc_ptr, dtype=np.int64), np.asarray(inc_spring, dtype=np.int64)
    m, size = len(dec.spring_owner), dec.size
    block_owner = dec.owner[order.node[order.block_ptr[:-1]]]
    holds, further, parts = [], [], []
    for q in range(size):
        blocks = np.flatnonzero(block_owner == q)
        nodes, incidence = _touched(order, inc_ptr, inc_spring, blocks)
        in_share, touched = np.zeros(m, dtype=bool), np.zeros(m, dtype=bool)
        in_share[share_springs[q]] = True
        touched[inc_spring[incidence]] = True
        further.append(touched & ~in_share)
        holds.append(touched | in_share)
        parts.append((blocks, nodes, incidence))
    springs = np.concatenate([share_springs[rank], np.flatnonzero(further[rank])])
    local = np.full(m, -1, dtype=np.int64)
    local[springs] = np.arange(len(springs))

    def plan(source, wants):
        send, recv = {}, {}
        for q in range(size):
            if q != rank and np.any((source == rank) & wants[q]):
                send[q] = local[np.flatnonzero((source == rank) & wants[q])]
            if q != rank and np.any((source == q) & wants[rank]):
                recv[q] = local[np.flatnonzero((source == q) & wants[rank])]
        return Plan(send, recv)

    colours = []
    for c in range(len(order.colour_ptr) - 1):
        source = np.full(m, -1, dtype=np.int64)
        in_colour = np.arange(order.colour_ptr[c], order.colour_ptr[c + 1])
        for q in range(size):
            source[inc_spring[_touched(order, inc_ptr, inc_spring, in_colour[block_owner[in_colour] == q])[1]]] = q
        colours.append(plan(source, holds))
    bound_source = np.full(m, -1, dtype=np.int64)
    bound_source[bound_spring] = dec.spring_owner[bound_spring]
    start_source = np.where(np.logical_or.reduce(further), dec.spring_owner, -1)
    bound = np.flatnonzero(dec.spring_owner[bound_spring] == rank)
    sizes = bound_ptr[bound + 1] - bound_ptr[bound]
    blocks, nodes, incidence = parts[rank]
    return dict(springs=springs, node=nodes, incidence=incidence, bound=bound,
                entries=np.repeat(bound_ptr[bound], sizes) + ranges(sizes),
                inc_spring=local[inc_spring[incidence]], start=plan(start_source, further), colours=colours,
                boundary=plan(bound_source, holds))


@pytest.mark.parametrize("size", [2, 3, 5])
def test_each_process_plans_its_conduction_exchanges_as_the_plain_whole_net_masks_do(size):
    """A process's part of the conduction sweep (the springs it holds, its blocks, and what it
    sends to and receives from each process before a sweep, after each colour and after the
    baths) is built visiting the other processes one at a time, in memory of the order of m; it
    is the plan made from every process's holdings as whole-net masks, for parts that cut the
    sweep's blocks (random owners) and for the `blocks` parts."""
    from thermonet.heat.graph import star_order
    from thermonet.layout import build_layout
    from thermonet.parallel.domain import decomposition, share
    from thermonet.parallel.heat_share import heat_shares
    from thermonet.parallel.partition import partition
    from thermonet.parallel.stepper import _block_spans
    from thermonet.parallel.sweep import _share_springs

    net = tn.lattice((9, 5, 4), neighbours=18, jitter=0.1, seed=2)
    layout = build_layout(net)
    rng = np.random.default_rng(size)
    not_bath = rng.random(net.n_nodes) > 0.1
    order = star_order(layout, np.ones(net.n_springs), not_bath, 16)
    bound_spring = np.unique(rng.choice(net.n_springs, 40, replace=False))
    bound_ptr = np.concatenate([[0], np.cumsum(rng.integers(1, 3, len(bound_spring)))]).astype(np.int64)
    owners = [rng.integers(0, size, net.n_nodes),
              partition(layout.nodes_to_internal(net.positions), layout.edges, size, "blocks", _block_spans(order))]
    for owner in owners:
        dec = decomposition(owner, layout.edges, size)
        shares = [share(dec, layout.edges, q).springs for q in range(size)]
        assert all(np.array_equal(a, b) for a, b in zip(_share_springs(dec, layout.edges), shares))
        for rank in range(size):
            got = heat_shares(order, layout.inc_ptr, layout.inc_spring, bound_spring, bound_ptr, dec, shares, rank)
            want = _reference_heat_share(order, layout.inc_ptr, layout.inc_spring, bound_spring, bound_ptr, dec,
                                         shares, rank)
            for k in ("springs", "node", "incidence", "bound", "entries", "inc_spring"):
                assert np.array_equal(getattr(got, k), want[k]), k
            for a, b in zip([got.start, got.boundary, *got.colours], [want["start"], want["boundary"],
                                                                       *want["colours"]]):
                for side in ("send", "recv"):
                    x, y = getattr(a, side), getattr(b, side)
                    assert sorted(x) == sorted(y) and all(np.array_equal(x[q], y[q]) for q in x), side
            assert len(got.colours) == len(want["colours"])
    assert any(len(p.send) for p in got.colours)  # (the plans are not all empty)
