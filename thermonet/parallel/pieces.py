"""Checkpoints of a run over MPI processes: one piece per process and a manifest.

Each process writes its own part of the state to ``<name>.checkpoint.pieces/<step>-<tag>/
piece-<rank>.npz`` (:meth:`~thermonet.parallel.stepper.DistributedStepper.piece`: its nodes, and
the springs and bath or source entries it reports, named in the user's numbering); nothing is
sent to rank 0. Once every piece is on disk, rank 0 writes the manifest ``<name>.checkpoint.npz``
over the previous checkpoint (atomically): the metadata, the step and time, what every process
holds alike (the loads' work, the heat logs' cycle), and the pieces with their sizes. Only then
does it remove the pieces of earlier checkpoints. A run killed at any moment leaves one complete
checkpoint, the old one or the new one; a piece that cannot be written stops the run with an error
naming it and leaves the old checkpoint in place.

Reading the manifest (:func:`thermonet.io.load_checkpoint`) puts the pieces back together into
the whole state, so a run checkpointed on P processes resumes on any number of them, or in one
process, bit for bit.
"""

from __future__ import annotations

import os
import secrets
import shutil

import numpy as np

from ..errors import OutputError
from ..heat.logs import PER_SPRING_LOGS
from ..io.atomic import atomic_write
from ..io.checkpoint import PIECE_FORMAT, PIECES_FORMAT, extra_arrays, pieces_folder, save_arrays
from .world import on_root


def write_pieces(sim, path: str, meta: dict) -> None:
    """The checkpoint of distributed ``sim`` at ``path`` (the manifest) with one piece per process
    (see the module docstring); ``meta`` as :func:`thermonet.io.save_checkpoint`'s. Every process
    must call it; an error writing any piece or the manifest is raised on every process."""
    comm = sim.comm
    rank, size = comm.Get_rank(), comm.Get_size()
    step = int(sim.step)
    base = pieces_folder(path)
    tag = on_root(comm, _new_folder, base, step)
    name = f"piece-{rank:05d}.npz"
    sizes, error = [0, 0, 0], None
    try:  # (an error here is told to rank 0, which raises it on every process: none is left waiting)
        piece = sim.stepper.piece(sim._state)
        sizes = [len(piece["nodes"]), len(piece.get("springs", ())), len(piece.get("entries", ()))]
        header = {"format": PIECE_FORMAT, "process": rank, "processes": size, "step": step, "tag": tag}
        with atomic_write(os.path.join(base, tag, name)) as f:
            save_arrays(f, piece, header)
        del piece
    except OSError as exc:
        error = f"{os.path.join(base, tag, name)}: {exc.strerror or exc}"
    except Exception as exc:
        error = f"{os.path.join(base, tag, name)}: {type(exc).__name__}: {exc}"
    told = comm.gather((name, sizes, error), root=0)
    on_root(comm, _write_manifest, sim, path, meta, base, tag, told)


def _new_folder(base: str, step: int) -> str:
    """A new folder for the pieces of the checkpoint of ``step`` under ``base``; its name."""
    tag = f"{step:09d}-{secrets.token_hex(4)}"
    try:
        os.makedirs(os.path.join(base, tag))
    except OSError as exc:
        raise OutputError(f"{os.path.join(base, tag)}: cannot make the folder of the checkpoint's pieces: "
                          f"{exc.strerror or exc}") from None
    return tag


def _write_manifest(sim, path: str, meta: dict, base: str, tag: str, told: list) -> None:
    """Rank 0, every piece told: the manifest written over the previous checkpoint, then the
    pieces of earlier ones removed (none of it where a piece failed)."""
    failed = [error for _, _, error in told if error is not None]
    if failed:
        shutil.rmtree(os.path.join(base, tag), ignore_errors=True)
        raise OutputError(f"the checkpoint of step {sim.step} was not written ({'; '.join(failed)}); "
                          f"the previous one is kept")
    state, layout = sim._state, sim.layout
    stepper = sim.stepper
    shared = set(stepper._share_log_keys(state))
    logs = {key: layout.springs_to_user(value) if key in PER_SPRING_LOGS else value  # (held alike by every process)
            for key, value in (state.extra.get("heat") or {}).items() if key not in shared}
    arrays = {"time": np.float64(state.time), "step": np.int64(state.step), **extra_arrays(state.extra, logs)}
    pieces = {"folder": os.path.join(os.path.basename(base), tag), "files": [name for name, _, _ in told],
              "sizes": [sizes for _, sizes, _ in told], "tag": tag, "nodes": sim.system.n_nodes,
              "springs": sim.system.n_springs, "entries": stepper._entries, "thermal": bool(sim.system.thermal),
              "shared_heat_logs": sorted(shared)}
    try:
        with atomic_write(path) as f:
            save_arrays(f, arrays, {"format": PIECES_FORMAT, **meta, "pieces": pieces})
    except OSError as exc:
        shutil.rmtree(os.path.join(base, tag), ignore_errors=True)
        raise OutputError(f"{path}: the checkpoint of step {sim.step} was not written: {exc.strerror or exc}; "
                          f"the previous one is kept") from None
    for old in os.listdir(base):  # (the manifest no longer lists them)
        if old != tag:
            shutil.rmtree(os.path.join(base, old), ignore_errors=True)


__all__ = ["write_pieces"]
