"""The files of one run, written by observers outside the time-stepping loop.

``OUTDIR/<name>.pvd`` indexes ``OUTDIR/<name>_NNNNNN.vtu`` frames; ``OUTDIR/diagnostics.csv``;
``OUTDIR/summary.json``; ``OUTDIR/<name>.checkpoint.npz`` (the latest checkpoint; over MPI
processes a manifest of the pieces in ``OUTDIR/<name>.checkpoint.pieces/``, one per process).
Everything is in the user's numbering and written atomically.

A frame is filled from the state at its step, then written to disk by a writer thread while the
run goes on: direct to the device where the file system allows (``O_DIRECT``: no copy into the
page cache, so the thread mostly waits for the device and barely competes with the stepping
threads; measured +6 % end to end at 1e5 springs with every core stepping, against +14 % for a
write through the page cache either way). Where direct writes are refused, the frame goes through
the page cache: on the writer thread where a core is idle while the run steps (serial kernels on
a multi-core machine, fewer stepping threads than cores, the GPU backend), else in the observer
call (a copying writer thread only competes with the stepping threads). One frame is in flight at
most; the next frame, a checkpoint, the summary and the end of ``Simulation.run`` (normal or
not) wait for it, and an error of the write is raised there.
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import time as _time
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from .. import __version__
from ..errors import InputError
from ..parallel.frames import PieceWriter
from ..parallel.world import on_root
from .atomic import atomic_write, direct_writes_possible, release_page_cache
from .checkpoint import load_checkpoint, pieces_folder, save_checkpoint
from .folder import check_writable, prepare_output_folder, remove_stale_temporaries
from .pvd import PVDIndex
from .vtu import FrameImage, VTUWriter

#: output field -> (point or cell data, needs thermal coupling, meaning)
FIELDS: dict[str, tuple[str, bool, str]] = {
    "displacement": ("point", False, "x − x(0), (n, 3)"),
    "velocity": ("point", False, "p / m, (n, 3) (0 on anchored nodes)"),
    "momentum": ("point", False, "p, (n, 3)"),
    "anchored": ("point", False, "1 on anchored nodes, else 0 (UInt8)"),
    "node_temperature": ("point", True, "mean temperature of the springs meeting at a node, for smooth colouring "
                         "(with conduction: the junction temperature Σ g θ / Σ g)"),
    "temperature": ("cell", True, "spring temperature θ(l, η)"),
    "entropy": ("cell", True, "spring entropy η"),
    "strain": ("cell", False, "logarithmic strain ln(l / l0)"),
    "tension": ("cell", False, "spring tension T = ∂F/∂l"),
    "thermal_displacement": ("cell", True, "thermal displacement Φ"),
    "material": ("cell", False, "material region id (Int32; the order of the [materials.*] tables)"),
    "heat_rate": ("cell", True, "net heat flowing into each spring per time (conduction, baths, sources; needs "
                  "conduction)"),
}
THERMAL_FIELDS = tuple(k for k, v in FIELDS.items() if v[1])
#: fields that need conduction
CONDUCTION_FIELDS = ("heat_rate",)


def available_fields(sim) -> list[str]:
    """The fields ``sim`` has: thermal ones with thermal coupling, heat_rate with conduction."""
    heat = sim.system.heat
    conduction = heat is not None and heat.conduction
    return [f for f in FIELDS if (sim.system.thermal or f not in THERMAL_FIELDS)
            and (conduction or f not in CONDUCTION_FIELDS)]


#: stored dtype and components (0: scalar) of each field
_STORAGE = {name: (np.uint8 if name == "anchored" else np.int32 if name == "material" else np.float64,
                   3 if kind == "point" and name in ("displacement", "velocity", "momentum") else 0)
            for name, (kind, _, _) in FIELDS.items()}


class FrameFiller:
    """Fills a :class:`~thermonet.io.vtu.FrameImage` with a simulation's fields, user numbering.

    The changing fields are written straight into the image's arrays by the simulation
    (:meth:`thermonet.simulation.Simulation.output_fields`: one node pass, one spring pass); the
    fields that cannot change (anchored flag, material id) are written here once.

    sim: the Simulation; writer: a :class:`~thermonet.io.vtu.VTUWriter` of its net;
    fields: names from :data:`FIELDS`; material_id: (m,) int, user numbering.
    """

    def __init__(self, sim, writer: VTUWriter, fields, material_id: np.ndarray):
        self.fields = list(fields)
        spec = {kind: {n: _STORAGE[n] for n in self.fields if FIELDS[n][0] == kind} for kind in ("point", "cell")}
        self.image = writer.image(spec["point"], spec["cell"])
        if "anchored" in self.fields:
            self.image.point["anchored"][:] = sim.net.anchored
        if "material" in self.fields:
            self.image.cell["material"][:] = material_id
        changing = [n for n in self.fields if n not in ("anchored", "material")]
        self._output = sim.output_fields(self.image.points, {n: self.image.point[n] for n in changing if n in spec["point"]},
                                         {n: self.image.cell[n] for n in changing if n in spec["cell"]})

    def fill(self) -> FrameImage:
        """The image, holding the simulation's state now."""
        self._output.write()
        return self.image


class RunOutput:
    """Observers that write the run's files, and the state a checkpoint must carry.

    sim: the Simulation. folder: output folder. name: file stem.
    fields: output field names (see :data:`FIELDS`). frames_every, checkpoint_every: cadences in
    steps (0: never). material_id: (m,) int. scene: JSON-serialisable description stored in
    checkpoints and summary.json (must hold ``hash``). direct: write frame files past the page
    cache where the folder's file system allows (False: always through it). background: write
    frame files on the writer thread (True) or in the observer call (False); default: on the
    writer thread where the writes are direct or a core is idle while the run steps
    (:func:`idle_core`).

    ``Simulation.run`` calls :meth:`flush` when it returns or raises (an observer's owner with a
    ``flush`` method), so the files are complete when ``run`` is done.
    """

    #: rewrite the CSV at most this often (seconds) between checkpoints
    CSV_INTERVAL = 2.0
    #: rewrite the PVD index at most this often (seconds) while frames come: its rewrite grows
    #: with the number of frames; flush() (checkpoints, the summary, the end of a run) completes it
    PVD_INTERVAL = 1.0

    def __init__(self, sim, folder, name: str, *, fields, frames_every: int, diagnostics_every: int,
                 checkpoint_every: int, material_id, scene: dict, background: bool | None = None,
                 direct: bool = True):
        self.sim = sim
        self.folder = os.fspath(folder)
        self.name = name
        self.fields = list(fields)
        self.frames_every = int(frames_every)
        self.diagnostics_every = int(diagnostics_every)
        self.checkpoint_every = int(checkpoint_every)
        self.material_id = np.asarray(material_id, dtype=np.int32)
        self.scene = scene
        os.makedirs(self.folder, exist_ok=True)
        self.pvd = PVDIndex(os.path.join(self.folder, f"{name}.pvd"))
        self.csv_path = os.path.join(self.folder, "diagnostics.csv")
        self.checkpoint_path = os.path.join(self.folder, f"{name}.checkpoint.npz")
        self.summary_path = os.path.join(self.folder, "summary.json")
        #: a run over MPI processes (docs/parallel.md): rank 0 puts each frame together and writes
        #: its pieces, the diagnostics and the checkpoints; the other processes hold no frame
        comm = getattr(sim, "comm", None)
        self.root = comm is None or comm.Get_rank() == 0
        self._frame = (FrameFiller(sim, VTUWriter(sim.net.edges, sim.net.n_nodes), self.fields, self.material_id)
                       if self.frames_every and self.root else None)
        self._pieces = None
        if comm is not None and self.frames_every:
            self._pieces = PieceWriter(sim) if self.root else False
            background = False  # every process waits for the frame: on the calling thread
        self._csv_written = -np.inf
        #: step of the last checkpoint written (or restored), None before the first
        self.checkpoint_step = None
        #: seconds the run spent in frame observer calls (filling; waiting for a previous write)
        self.frame_seconds = 0.0
        #: seconds the frame files took to write (on the writer thread when ``background``)
        self.write_seconds = 0.0
        #: frame files written past the page cache (O_DIRECT)
        self.direct_writes = 0
        self.direct = bool(direct) and bool(self.frames_every) and direct_writes_possible(self.folder)
        if background is None:
            background = bool(self.frames_every) and (idle_core(sim) or self.direct)
        self.background = bool(background)
        self._last_frame = None
        self._pending = None
        self._pvd_written = -np.inf

    @classmethod
    def for_simulation(cls, sim, folder, name: str = "run", *, frames_every: int, diagnostics_every: int | None = None,
                       checkpoint_every: int = 0, fields=None, material_id=None, overwrite: bool = False,
                       resume: bool = False, **options) -> "RunOutput":
        """The files of a run of ``sim`` driven from a script, as ``thermonet run`` writes them::

            out = RunOutput.for_simulation(sim, "out/mine", frames_every=10)
            sim.run(t_end=1.0, diagnostics_every=out.diagnostics_every, observers=out.observers())
            out.write_summary(sim)          # optional: summary.json

        writes ``out/mine/run.pvd`` with a ``run_NNNNNN.vtu`` frame every 10 steps (and at the
        end), and ``diagnostics.csv``. folder: refused when it holds a previous run's files unless
        ``overwrite`` (which deletes them; :func:`~thermonet.io.folder.prepare_output_folder`).
        fields: default every field of :data:`FIELDS` the simulation has. diagnostics_every:
        default ``frames_every``. material_id: (m,) int (default 0). checkpoint_every: 0 (none)
        or a cadence (``load_checkpoint`` and ``sim.load_state`` continue from one). resume: the
        folder holds the run to continue (kept as it is; then :meth:`resume` from its checkpoint).
        """
        def prepare():
            if resume:
                check_writable(folder)
                remove_stale_temporaries(folder)
            else:
                prepare_output_folder(folder, overwrite=overwrite)

        on_root(getattr(sim, "comm", None), prepare)  # once, by rank 0, in a run over MPI processes
        if fields is None:
            fields = available_fields(sim)
        unknown = [f for f in fields if f not in FIELDS]
        if unknown:
            raise InputError(f"unknown output field {unknown[0]!r}; fields: {', '.join(FIELDS)}")
        if material_id is None:
            material_id = np.zeros(sim.net.n_springs, dtype=np.int32)
        return cls(sim, folder, name, fields=fields, frames_every=frames_every,
                   diagnostics_every=frames_every if diagnostics_every is None else diagnostics_every,
                   checkpoint_every=checkpoint_every, material_id=material_id,
                   scene={"name": name, "hash": None}, **options)

    # ------------------------------------------------------------------------------------------
    def observers(self) -> list:
        """(cadence, callback) pairs for ``Simulation.run``; checkpoints come last so that they
        include the frame and diagnostics row of their own step."""
        obs = []
        if self.frames_every:
            obs.append((self.frames_every, self.write_frame))
        obs.append((self.diagnostics_every, self._maybe_write_csv))
        if self.checkpoint_every:
            obs.append((self.checkpoint_every, self.write_checkpoint))
        return obs

    def resume(self, checkpoint) -> dict:
        """Continue the run from ``checkpoint`` (a ``*.checkpoint.npz`` path, or the ``(state,
        meta)`` of :func:`~thermonet.io.load_checkpoint`): the simulation takes its state, this
        output its diagnostics rows, frames and run time, the simulation's probes their rows up
        to that step (from this folder's ``probe_<name>.csv``). A run continued so is bit for
        bit the uninterrupted one. Returns the checkpoint's ``meta``::

            out = RunOutput.for_simulation(sim, "out/mine", frames_every=10, checkpoint_every=100,
                                           resume=True)
            out.resume("out/mine/run.checkpoint.npz")
            sim.run(t_end=2.0, diagnostics_every=out.diagnostics_every, observers=out.observers())
        """
        if isinstance(checkpoint, tuple):
            state, meta = checkpoint
        else:
            state, meta = load_checkpoint(checkpoint)
        self.sim.load_state(state)
        self.restore(meta)
        if self.sim.probes is not None:
            self.sim.probes.restore(self.folder, self.sim.step)
        return meta

    def restore(self, meta: dict) -> None:
        """Take back what a checkpoint recorded: diagnostics rows, frames, run time."""
        self.sim.diagnostics.rows = list(meta["diagnostics"])
        self.pvd.frames = {int(s): (float(t), f) for s, t, f in meta["frames"]}
        self.sim.wall_time = float(meta["wall_time_s"])
        self.sim.steps_run = int(meta["steps_run"])
        self.checkpoint_step = self.sim.step

    # ------------------------------------------------------------------------------------------
    def write_frame(self, sim) -> None:
        """Fill the frame of the current step and write it (on the writer thread when
        ``background``); the PVD lists it once its file is complete."""
        t0 = _time.perf_counter()
        self._wait()  # one image: the previous frame must be on disk before it is refilled
        step = sim.step
        if step in self.pvd.frames:
            filename = self.pvd.frames[step][1]
        else:
            filename = f"{self.name}_{len(self.pvd.frames):06d}.vtu"
        if self._pieces is not None:
            stem = filename.rsplit(".", 1)[0]
            filename = sim.on_root(lambda: self._pieces.write(self._frame.fill(), self.folder, stem, self.direct))
            self.pvd.add(step, sim.time, filename, write=self.root)
            self.frame_seconds += _time.perf_counter() - t0
            return
        image = self._frame.fill()
        args = (image, os.path.join(self.folder, filename), step, sim.time, filename)
        if self.background:
            self._pending = _writer().submit(self._store_frame, *args)
        else:
            self._store_frame(*args)
        self.frame_seconds += _time.perf_counter() - t0

    def _store_frame(self, image: FrameImage, path: str, step: int, time: float, filename: str) -> None:
        t0 = _time.perf_counter()
        direct = image.write(path, self.direct)
        now = _time.monotonic()  # listed only after the frame file is complete:
        self.pvd.add(step, time, filename, write=now - self._pvd_written >= self.PVD_INTERVAL)
        if self.pvd.written:
            self._pvd_written = now
        if not direct:  # written through the page cache: recycle its pages
            release_page_cache(path)
            if self._last_frame is not None:
                release_page_cache(self._last_frame)
            self._last_frame = path
        self.direct_writes += direct
        self.write_seconds += _time.perf_counter() - t0

    def _wait(self) -> None:
        """Wait until the frame being written is on disk; raise its write's error."""
        pending, self._pending = self._pending, None
        if pending is not None:
            pending.result()

    def flush(self) -> None:
        """Wait until the frame being written is on disk, then make the PVD list every frame
        written (also when that write failed); raise a write's error."""
        try:
            self._wait()
        finally:
            if not self.pvd.written and self.root:
                self.pvd.write()
                self._pvd_written = _time.monotonic()

    def _maybe_write_csv(self, sim) -> None:
        if _time.monotonic() - self._csv_written >= self.CSV_INTERVAL:
            self.write_csv()

    def write_csv(self) -> None:
        if self.root:
            self.sim.diagnostics.to_csv(self.csv_path)
        self._csv_written = _time.monotonic()

    def write_checkpoint(self, sim) -> None:
        self.flush()  # the checkpoint lists the frames written so far
        sim.record_diagnostics()
        meta = {
            "scene": self.scene,
            "diagnostics": sim.diagnostics.rows,
            "frames": [[s, t, f] for s, (t, f) in sorted(self.pvd.frames.items())],
            "wall_time_s": sim.wall_time,
            "steps_run": sim.steps_run,
        }
        if getattr(sim, "comm", None) is not None:  # over MPI processes: one piece each, and a manifest
            from ..parallel.pieces import write_pieces

            write_pieces(sim, self.checkpoint_path, meta)
        else:
            save_checkpoint(self.checkpoint_path, sim.state, meta)
            # (a run over processes continued in one: its pieces are no longer listed)
            shutil.rmtree(pieces_folder(self.checkpoint_path), ignore_errors=True)
        self.checkpoint_step = sim.step
        self.write_csv()

    def write_summary(self, sim, extra: dict | None = None) -> dict:
        """``summary.json``: scene hash, versions, steps, wall time, steps/s, and the initial value
        and max deviation of each conserved quantity."""
        self.flush()
        summary = sim.conservation_summary()
        run = summary.pop("_run")
        out = {
            "scene": self.scene.get("name"),
            "scene_hash": self.scene.get("hash"),
            "versions": versions(),
            "nodes": sim.net.n_nodes,
            "springs": sim.net.n_springs,
            "integrator": sim.integrator.name,
            "backend": sim.backend,
            **({"processes": sim.comm.Get_size()} if getattr(sim, "comm", None) is not None else {}),
            "h": sim.h,
            "steps": sim.step,
            "time": sim.time,
            "wall_time_s": run["wall_time_s"],
            "steps_per_s": run["steps_per_s"],
            "frames": len(self.pvd.frames),
            "conserved": summary,
            **({"newton": run["newton"]} if "newton" in run else {}),
            **({"conduction_every": {"k": sim.conduction_cycle.k, "sweeps": sim.conduction_cycle.sweeps,
                                     "why": sim.conduction_cycle.why}}
               if sim.conduction_cycle else {}),
            **(extra or {}),
        }
        if self.root:
            with atomic_write(self.summary_path, "w") as f:
                json.dump(out, f, indent=2, allow_nan=True)
                f.write("\n")
        return out


def idle_core(sim) -> bool:
    """Whether this process may use more cores than the simulation's stepping keeps busy: the
    CPU backend's threaded kernels use Numba's threads (``sim.threads`` or Numba's count), its
    serial kernels and the GPU backend one host thread."""
    affinity = getattr(os, "sched_getaffinity", None)
    cores = len(affinity(0)) if affinity is not None else (os.cpu_count() or 1)
    stepping = 1
    if sim.backend == "cpu" and sim.parallel:
        stepping = int(sim.threads) if sim.threads else numba.get_num_threads()
    return cores > stepping


_WRITER: ThreadPoolExecutor | None = None


def _writer() -> ThreadPoolExecutor:
    """The process's frame-writer thread (one: frames of every run are written in order)."""
    global _WRITER
    if _WRITER is None:
        _WRITER = ThreadPoolExecutor(max_workers=1, thread_name_prefix="thermonet-frames")
    return _WRITER


def versions() -> dict:
    import meshio
    import scipy

    return {"thermonet": __version__, "python": platform.python_version(), "numpy": np.__version__,
            "numba": numba.__version__, "scipy": scipy.__version__, "meshio": meshio.__version__}
