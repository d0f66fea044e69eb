"""``thermonet run``: run a scene (default: the built-in 3D truss block), write its ParaView
time series, diagnostics, summary and checkpoints, and print the conservation summary."""

from __future__ import annotations

import contextlib
import datetime
import os
import signal
import sys
import threading
import warnings

from ..blowup import remedy
from ..errors import InputError, OutputError, SimulationError, ThermonetError
from ..io import RunOutput, atomic_write, load_checkpoint
from ..io.folder import (check_output_folder, check_writable, describe_os_error, fresh_folder,
                         prepare_output_folder, remove_stale_temporaries)
from ..parallel.world import is_root, on_root, world
from ..probes import scene_probes
from ..run_guards import broken_conservation
from ..scenes import load_scene, scene_from_text
from ..scenes.scene import FREE_ON_RESUME, trajectory_changes
from ..step_policy import StepWarning, UnstableStepError, check_step
from .progress import ProgressBar
from .report import format_summary

HELP = "run a scene and write VTU/PVD frames, diagnostics.csv, summary.json and checkpoints"

#: the copy of the scene as run, in the output folder
SCENE_AS_RUN = "scene-as-run.toml"


def add_args(p) -> None:
    p.add_argument("scene", nargs="?", default=None,
                   help="scene file (.toml); default: the built-in 3D truss block (scenes/default.toml)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="output folder (default: the scene's output.folder, or thermonet-out/<name>; when that "
                        "holds a previous run, the first of <folder>-2, <folder>-3, ... that does not)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                   help="override a scene key, e.g. --set integrator.h=1e-4 --set effects.gravity=false "
                        "(the value is read as TOML; repeatable)")
    p.add_argument("--resume", default=None, metavar="CHECKPOINT",
                   help="continue from a checkpoint (.npz file, or the output folder holding it); "
                        "the result is bit-for-bit that of an uninterrupted run")
    p.add_argument("--integrator", default=None, help="shorthand for --set integrator.name=NAME")
    p.add_argument("--h", type=float, default=None, help="shorthand for --set integrator.h=H")
    p.add_argument("--t-end", type=float, default=None, help="shorthand for --set integrator.t_end=T")
    p.add_argument("--allow-unstable-step", action="store_true",
                   help="run even when h is far above the estimated stability limit (> 1.5 h_max; "
                        "same as --set integrator.check_step=false); it is still warned about")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the output of a previous run in the output folder (its files are deleted "
                        "first); without it such a folder is refused")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")


def overrides_of(args) -> list[str]:
    """``--set`` items plus the shorthands, in that order (shorthands win)."""
    items = list(args.overrides or [])
    if args.integrator is not None:
        items.append(f'integrator.name="{args.integrator}"')
    if args.h is not None:
        items.append(f"integrator.h={args.h!r}")
    if args.t_end is not None:
        items.append(f"integrator.t_end={args.t_end!r}")
    return items


def handle(args) -> int:
    if not is_root(world()):  # a run over MPI processes: rank 0 speaks and writes the shared files
        args.quiet = args.echo = True
    progress = None if args.quiet else ProgressBar()
    record = RunLog(getattr(args, "argv", None))
    with record.capturing():
        try:
            # nothing said while the scene is built and checked (a bad input is then the only
            # line); the run's own watch says when its kernels compile
            with _run_warnings(args.quiet, progress):
                return _run(args, progress, record)
        except ThermonetError as exc:
            record.note(f"thermonet: error: {exc}")
            raise
        except KeyboardInterrupt:
            record.note("thermonet: interrupted")
            raise
        finally:
            record.write()


class RunLog:
    """What ``thermonet run`` prints (stdout and stderr, not the progress bar), kept and written
    to ``run.log`` in the output folder once that is known (appended to on resume)."""

    NAME = "run.log"

    def __init__(self, argv=None):
        self.parts: list[str] = []
        self.folder = None
        self.argv = list(argv) if argv is not None else ["run"]

    def note(self, line: str) -> None:
        self.parts.append(line + "\n")

    @contextlib.contextmanager
    def capturing(self):
        saved = sys.stdout, sys.stderr
        sys.stdout, sys.stderr = _Tee(saved[0], self.parts), _Tee(saved[1], self.parts)
        try:
            yield self
        finally:
            sys.stdout, sys.stderr = saved

    def write(self) -> None:
        if self.folder is None:
            return
        stamp = datetime.datetime.now().astimezone().isoformat(timespec="seconds")
        head = f"# {stamp}: thermonet {' '.join(self.argv)}\n"
        try:
            with open(os.path.join(self.folder, self.NAME), "a", encoding="utf-8") as f:
                f.write(head + "".join(self.parts))
        except OSError:
            pass  # the run's own files were the ones to report on


class _Tee:
    """A text stream that also keeps what is written to it."""

    def __init__(self, stream, parts: list):
        self._stream, self._parts = stream, parts

    def write(self, text):
        self._parts.append(text)
        return self._stream.write(text)

    def __getattr__(self, name):
        return getattr(self._stream, name)


class StopRequest:
    """Ctrl-C (SIGINT) or SIGTERM while a run steps: the run stops at the end of the current chunk
    of steps (at most a diagnostics interval), a consistent state that is then checkpointed; a
    second signal stops it at once. Called as the run's progress callback (forwarding to the
    progress bar, if any)."""

    def __init__(self, progress, comm=None):
        self.progress = progress
        self.comm = comm  # a run over MPI processes: they stop together, at the same chunk
        self.compiling = getattr(progress, "compiling", None)
        #: the signal received (None: none), and whether a second one cut a step short
        self.signal = None
        self.forced = False

    def __call__(self, done, total, elapsed) -> None:
        if self.progress is not None:
            self.progress(done, total, elapsed)
        if self.comm is not None:
            signals = self.comm.allgather(self.signal)
            self.signal = next((s for s in signals if s is not None), None)
        if self.signal is not None:
            raise KeyboardInterrupt

    def _handler(self, signum, frame) -> None:
        if self.signal is not None:
            self.forced = True
            raise KeyboardInterrupt
        self.signal = signum

    @contextlib.contextmanager
    def installed(self):
        if threading.current_thread() is not threading.main_thread():
            yield self
            return
        previous = {sig: signal.signal(sig, self._handler) for sig in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield self
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)

    @property
    def clean(self) -> bool:
        """Whether the run stopped on a signal at a chunk's end (its state is a whole step)."""
        return self.signal is not None and not self.forced


def _run(args, progress, record=None) -> int:
    comm = world()  # None in one process; the folder is chosen and prepared by rank 0 only

    overrides = overrides_of(args)
    state = meta = None
    if args.resume and args.overwrite:
        raise InputError("--resume continues the run in its folder; --overwrite would delete it: give one of them")
    if args.resume:
        checkpoint = args.resume
        if os.path.isdir(checkpoint):
            found = sorted(f for f in os.listdir(checkpoint) if f.endswith(".checkpoint.npz"))
            if not found:
                raise InputError(f"{checkpoint}: no *.checkpoint.npz in this folder")
            checkpoint = os.path.join(checkpoint, found[0])
        state, meta = load_checkpoint(checkpoint)
        missing = [k for k in ("scene", "diagnostics", "frames", "wall_time_s", "steps_run") if k not in meta]
        if missing:
            raise InputError(f"{checkpoint}: not a checkpoint of `thermonet run` (no {', '.join(missing)} in it)")
        saved = meta["scene"]
        if args.scene:
            scene = load_scene(args.scene, overrides)
        else:
            scene = scene_from_text(saved["text"], file=saved["file"], base_dir=saved["base_dir"],
                                    overrides=list(saved["overrides"]) + overrides)
        if scene.hash != saved["hash"]:
            _refuse_other_scene(checkpoint, saved, scene)
        folder = args.out or os.path.dirname(os.path.abspath(checkpoint))
        if os.path.exists(folder) and not os.path.isdir(folder):
            raise InputError(f"--out {folder}: exists and is not a folder")
        try:
            check_writable(folder)
        except OSError as exc:
            raise OutputError(f"--resume: cannot write the output folder {folder}: {describe_os_error(exc)}") from None
        on_root(comm, remove_stale_temporaries, folder)
    else:
        scene = load_scene(args.scene, overrides)

        def choose_folder():
            folder = args.out
            if folder is None:  # never refused: a previous run there keeps its files, this one goes beside it
                base = scene["output"].get("folder") or os.path.join("thermonet-out", scene.name)
                folder = base if args.overwrite else fresh_folder(base)
                if folder != base and not args.quiet:
                    print(f"thermonet: {base} holds a previous run: writing to {folder} (--out DIR chooses the "
                          f"folder, --overwrite replaces that run)", file=sys.stderr)
            check_output_folder(folder, overwrite=args.overwrite)  # refused before anything is built
            return folder

        folder = on_root(comm, choose_folder)

    built = scene.build()
    sim = built.simulation
    if args.allow_unstable_step:
        sim.stability_guard.mode = "warn"
    if state is None:
        _check_step(sim, scene, args)
        note = on_root(sim.comm, lambda: sim.net.pieces_note())  # (rank 0 alone holds the net)
        if note and not args.quiet:
            print(f"thermonet: warning: {note}", file=sys.stderr)
    total = scene.total_steps()
    probes = scene_probes(scene, sim)  # attached: every run of sim records them
    if state is None:  # the new run is built and checked: only now may a previous run's files go
        on_root(comm, lambda: prepare_output_folder(folder, overwrite=args.overwrite))
    if record is not None and is_root(comm):
        record.folder = folder

    def write_scene():  # the scene as run (overrides applied), beside its output
        try:
            with atomic_write(os.path.join(folder, SCENE_AS_RUN), "w") as f:
                f.write(scene.as_run())
        except OSError as exc:
            raise OutputError(f"cannot write to the output folder: {describe_os_error(exc)}") from None

    on_root(comm, write_scene)
    try:
        output = RunOutput(
            sim, folder, scene.name,
            fields=scene.output_fields(),
            frames_every=scene.cadence("frames_every", total),
            diagnostics_every=scene.cadence("diagnostics_every", total),
            checkpoint_every=scene.cadence("checkpoint_every", total),
            material_id=built.material_id,
            scene=scene.describe(),
        )
    except OSError as exc:
        raise OutputError(f"cannot write to the output folder: {describe_os_error(exc)}") from None
    if state is not None:
        output.resume((state, meta))  # the state, the diagnostics rows, frames and probe series
    observers = list(output.observers())
    stop = StopRequest(progress, comm)
    try:
        with stop.installed():
            sim.run(steps=max(0, total - sim.step), diagnostics_every=output.diagnostics_every,
                    observers=observers, progress=stop)
    except BaseException as exc:
        if progress:
            progress.close()
        failure = OutputError(f"writing the output failed at step {sim.step}: {describe_os_error(exc)}"
                              ) if isinstance(exc, OSError) else None
        if (isinstance(exc, SimulationError) or (isinstance(exc, KeyboardInterrupt) and stop.clean)) \
                and output.checkpoint_every:
            # the last good state (a failed run was rewound to it), or the step a signal stopped at
            _try(output.write_checkpoint, sim)
        _try(output.write_csv)
        if probes is not None and is_root(comm):  # probes
            _try(probes.to_csv, folder)
        if not args.quiet or failure is not None:
            print(_where_to_continue(sim, output, exc), file=sys.stderr)
        if failure is not None:
            raise failure from None
        raise
    if progress:
        progress.close()
    try:
        output.write_csv()
        probe_files = probes.to_csv(folder) if probes is not None and is_root(comm) else []  # probes
        output.write_summary(sim, {"broken_conservation": broken_conservation(sim, sim.energy_tolerance),
                                   "files": {"scene_as_run": SCENE_AS_RUN, "log": RunLog.NAME},
                                   # continuum materials are given in SI units; spring parameters in the
                                   # model's own (thermonet plot labels its axes with it)
                                   "units": "SI" if built.continuum is not None else "model units"})
    except OSError as exc:
        raise OutputError(f"writing the output failed at the end of the run: {describe_os_error(exc)}") from None
    if not args.quiet:
        print(format_summary(sim, scene.name, folder))
        if comm is not None:
            print(f"  over {comm.Get_size()} MPI processes ({sim.threads} thread(s) each); frames as .pvtu + one .vtu "
                  f"piece per process")
        files = [f"{scene.name}.pvd ({len(output.pvd.frames)} frames)" if output.frames_every else None,
                 "diagnostics.csv", *probe_files, "summary.json", SCENE_AS_RUN, RunLog.NAME,
                 os.path.basename(output.checkpoint_path) if output.checkpoint_every else None]
        print(f"  wrote {', '.join(f for f in files if f)}")
    broken = broken_conservation(sim, sim.energy_tolerance)
    if broken:
        raise SimulationError(f"the run ended with broken conservation: {'; '.join(broken)}; the result is not a "
                              f"solution to trust (the files in {folder} are kept). "
                              f"{_remedy(sim.integrator, sim.h)}")
    return 0


def _refuse_other_scene(checkpoint, saved, scene) -> None:
    """A checkpoint whose scene hash differs: allowed where only keys free on resume changed
    (a checkpoint of another version's hash), refused naming the keys that changed the trajectory,
    or the mesh file."""
    free = ", ".join(f"integrator.{k}" for k in FREE_ON_RESUME)
    try:
        before = scene_from_text(saved["text"], file=saved["file"], base_dir=saved["base_dir"],
                                 overrides=list(saved["overrides"]))
    except Exception:
        before = None
    if before is not None:
        changes = trajectory_changes(before, scene)
        if changes:
            more = f" (and {len(changes) - 1} more: {'; '.join(changes[1:4])})" if len(changes) > 1 else ""
            raise InputError(f"{checkpoint}: written by a different scene: {changes[0]}{more}; that changes the "
                             f"trajectory, so the run cannot continue from it (free to change on resume: the "
                             f"outputs, {free})")
        if before.hash == scene.hash and scene.mesh_path() is None:
            return  # the same trajectory: a checkpoint of another version's hash
    mesh = scene.mesh_path()
    what = (f"the mesh file {mesh} differs from the one it was written with (or the checkpoint is of another "
            f"thermonet version)") if mesh else "its scene differs"
    raise InputError(f"{checkpoint}: written by a different scene (hash {saved['hash'][:12]}, this scene "
                     f"{scene.hash[:12]}): {what}")


def _remedy(integrator, h) -> str:
    return remedy(integrator, h)


def _try(write, *args) -> None:
    """A write after a failure: attempted, its own error dropped (the first one is reported)."""
    try:
        write(*args)
    except Exception:
        pass


def _where_to_continue(sim, output, exc) -> str:
    """Where the run stopped and which step --resume starts from."""
    stop = "interrupted" if isinstance(exc, KeyboardInterrupt) else "stopped"
    step = output.checkpoint_step
    if step is None or not os.path.exists(output.checkpoint_path):
        return f"thermonet: {stop} at step {sim.step}; no checkpoint was written (output.checkpoint_every)"
    return (f"thermonet: {stop} at step {sim.step}; the last checkpoint is of step {step}: continue from there "
            f"with: thermonet run --resume {output.checkpoint_path}")


@contextlib.contextmanager
def _run_warnings(quiet: bool, progress):
    """Warnings while running (a step close to the stability limit, ...) as one line each:
    ``thermonet: warning: ...`` on stderr (none with --quiet)."""
    def show(message, category, filename, lineno, file=None, line=None):
        if quiet:
            return
        if progress is not None and progress.shown and progress.tty:
            sys.stderr.write("\n")
        print(f"thermonet: warning: {message}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.simplefilter("always", StepWarning)  # the guard warns once per run itself
        warnings.showwarning = show
        yield


def _check_step(sim, scene, args) -> None:
    """The step-limit policy (thermonet.step_policy) at the initial state: refuse (an InputError)
    or warn on stderr."""
    allow = args.allow_unstable_step or not scene["integrator"]["check_step"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StepWarning)
        try:
            verdict = check_step(sim, allow_unstable=allow, warn=False)
        except UnstableStepError as exc:  # at the key that sets the step: file:line or --set
            raise scene.error("integrator.h", str(exc)) from None
    if verdict.message and not args.quiet:
        print(f"thermonet: warning: {verdict.message}", file=sys.stderr)
