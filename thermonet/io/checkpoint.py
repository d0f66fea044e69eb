"""Checkpoints: the full integrator state (user numbering, exact float64; with heat flow its logs),
the step counter, the scene hash and what the outputs need to continue (diagnostics rows, frames written so far).

A ``.npz`` file written atomically; resuming from it continues a run bit for bit. A run over MPI
processes writes it as a manifest with one piece per process beside it
(:mod:`thermonet.parallel.pieces`); :func:`load_checkpoint` reads either kind into the whole state.
"""

from __future__ import annotations

import json
import os

import numpy as np

from ..errors import InputError
from ..heat.logs import ENTRY_LOGS
from ..state import State
from .atomic import atomic_write

FORMAT = "thermonet-checkpoint-1"
#: a manifest listing one piece per process, and a piece (thermonet.parallel.pieces)
PIECES_FORMAT = "thermonet-checkpoint-pieces-1"
PIECE_FORMAT = "thermonet-checkpoint-piece-1"


def pieces_folder(path) -> str:
    """The folder holding the pieces of the checkpoint ``path`` (``<name>.checkpoint.pieces``)."""
    path = os.fspath(path)
    return (path[:-len(".npz")] if path.endswith(".npz") else path) + ".pieces"


def save_arrays(f, arrays: dict, meta: dict) -> None:
    """``arrays`` and ``meta`` (JSON, under the key "meta") into the open binary file ``f`` as a ``.npz``."""
    np.savez(f, **arrays, meta=np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8))


def save_checkpoint(path, state: State, meta: dict) -> None:
    """Write ``state`` (user numbering) and ``meta`` (JSON-serialisable; floats are kept exactly,
    since JSON writes ``repr`` of a float) to ``path`` atomically."""
    arrays = {
        "positions": state.positions,
        "momenta": state.momenta,
        "time": np.float64(state.time),
        "step": np.int64(state.step),
    }
    if state.entropy is not None:
        arrays["entropy"] = state.entropy
        arrays["thermal_displacement"] = state.thermal_displacement
    arrays.update(extra_arrays(state.extra, state.extra.get("heat") or {}))
    with atomic_write(path) as f:
        save_arrays(f, arrays, {"format": FORMAT, **meta})


def load_checkpoint(path) -> tuple[State, dict]:
    """The state and metadata saved by :func:`save_checkpoint`, or put together from the pieces
    a run over MPI processes wrote. Errors name the file."""
    path = os.fspath(path)
    z, meta = _open(path)
    try:
        if meta.get("format") == PIECES_FORMAT:
            return _assembled(path, z, meta), meta
        return _state_of(path, z), meta
    finally:
        z.close()


def _open(path: str, expected: tuple = (FORMAT, PIECES_FORMAT), what: str = "checkpoint"):
    """The open ``.npz`` at ``path`` and its metadata, checked to be of one of the ``expected``
    formats; the caller closes it."""
    if not os.path.isfile(path):
        raise InputError(f"{path}: no such {what} file")
    try:
        with open(path, "rb") as f:
            magic = f.read(4)
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {what}: {exc.strerror}") from None
    if magic != b"PK\x03\x04":  # every .npz is a zip file
        raise InputError(f"{path}: not a readable thermonet {what} (not a .npz file: corrupt, truncated to "
                         f"{os.path.getsize(path)} bytes, or another kind of file)")
    z = None
    try:
        z = np.load(path, allow_pickle=False)
        meta = json.loads(bytes(z["meta"]).decode())
    except Exception as exc:  # zipfile.BadZipFile, EOFError, zlib.error, OSError, ValueError, KeyError, ...
        if z is not None:
            z.close()
        raise _unreadable(path, exc, what) from None
    if not isinstance(meta, dict) or meta.get("format") not in expected:
        z.close()
        found = meta.get("format") if isinstance(meta, dict) else None
        raise InputError(f"{path}: not a thermonet {what} (format {found!r}, expected {' or '.join(expected)})")
    return z, meta


def _unreadable(path: str, exc: Exception, what: str = "checkpoint") -> InputError:
    reason = str(exc) or type(exc).__name__
    return InputError(f"{path}: not a readable thermonet {what} (corrupt or truncated? {reason})")


def _state_of(path: str, z) -> State:
    """The State of a one-file checkpoint ``z``."""
    try:
        thermal = "entropy" in z.files
        state = State(
            positions=z["positions"].copy(),
            momenta=z["momenta"].copy(),
            thermal_displacement=z["thermal_displacement"].copy() if thermal else None,
            entropy=z["entropy"].copy() if thermal else None,
            time=float(z["time"]),
            step=int(z["step"]),
            extra=_extra_of(z),
        )
    except Exception as exc:
        raise _unreadable(path, exc) from None
    return state


def extra_arrays(extra: dict, logs: dict) -> dict:
    """A checkpoint's arrays of a State's ``extra``: the heat-flow ``logs`` given as "heat_<key>",
    the accumulators (the loads' work, ...) as "extra.<key>"; :func:`_extra_of` reads them back."""
    arrays = {f"heat_{key}": value for key, value in logs.items()}
    arrays.update({f"extra.{key}": value for key, value in extra.items() if isinstance(value, np.ndarray)})
    return arrays


def _extra_of(z) -> dict:
    """A State's ``extra`` from the arrays of ``z``: "extra.<key>" ones, and the heat logs "heat_<key>"."""
    extra = {k[len("extra."):]: z[k].copy() for k in z.files if k.startswith("extra.")}
    logs = {k[len("heat_"):]: z[k].copy() for k in z.files if k.startswith("heat_")}
    if logs:
        extra["heat"] = logs
    return extra


def _assembled(path: str, z, meta: dict) -> State:
    """The whole State from the manifest ``z`` at ``path`` and the pieces it lists: each node,
    spring and entry placed from the one piece that holds it (an error names a missing, foreign
    or damaged piece, or a node, spring or entry no piece holds)."""
    try:
        pieces = meta["pieces"]
        folder = os.path.join(os.path.dirname(path), pieces["folder"])
        n, m, entries, thermal = int(pieces["nodes"]), int(pieces["springs"]), int(pieces["entries"]), bool(
            pieces["thermal"])
        files, sizes, tag = list(pieces["files"]), list(pieces["sizes"]), pieces["tag"]
        shared = list(pieces["shared_heat_logs"])
        time, step = float(z["time"]), int(z["step"])
        extra = _extra_of(z)
    except Exception as exc:
        raise _unreadable(path, exc) from None
    whole = {"positions": np.empty((n, 3)), "momenta": np.empty((n, 3))}
    if thermal:
        whole["thermal_displacement"], whole["entropy"] = np.empty(m), np.empty(m)
    for k in shared:
        whole[f"heat_{k}"] = np.empty(entries if k in ENTRY_LOGS else m)
    held = {"nodes": np.zeros(n, dtype=bool), "springs": np.zeros(m, dtype=bool),
            "entries": np.zeros(entries, dtype=bool)}
    for q, (name, size) in enumerate(zip(files, sizes)):
        piece_path = os.path.join(folder, name)
        try:
            p, header = _open(piece_path, (PIECE_FORMAT,), "checkpoint piece")
        except InputError as exc:
            raise InputError(f"{exc} (one of the {len(files)} pieces {path} lists)") from None
        try:
            if (header.get("tag"), header.get("process"), header.get("processes")) != (tag, q, len(files)):
                raise InputError(f"{piece_path}: a piece of another checkpoint (process {header.get('process')} of "
                                 f"{header.get('processes')}, {header.get('tag')}), not process {q} of {len(files)} "
                                 f"of {path} ({tag})")
            _place(piece_path, p, size, whole, held)
        finally:
            p.close()
    for j, (kind, seen) in enumerate(held.items()):
        if kind != "springs" or thermal:
            missing = np.flatnonzero(~seen)
            if len(missing):
                raise InputError(f"{path}: no piece holds {kind[:-1]} {missing[0]} ({len(missing)} {kind} missing)")
            if sum(size[j] for size in sizes) != len(seen):  # (all held, so some piece holds one twice)
                raise InputError(f"{path}: its pieces hold {sum(size[j] for size in sizes)} {kind} for {len(seen)}")
    heat = extra.pop("heat", {})
    heat.update({k: whole.pop(f"heat_{k}") for k in shared})
    if heat:
        extra["heat"] = heat
    return State(positions=whole["positions"], momenta=whole["momenta"],
                 thermal_displacement=whole.get("thermal_displacement"), entropy=whole.get("entropy"),
                 time=time, step=step, extra=extra)


#: which index array of a piece names the rows of each of its arrays
_INDEX_OF = {"positions": "nodes", "momenta": "nodes", "thermal_displacement": "springs", "entropy": "springs",
             **{f"heat_{k}": "entries" for k in ENTRY_LOGS}}


def _place(path: str, p, size: list, whole: dict, held: dict) -> None:
    """The arrays of piece ``p`` (at ``path``, listed with ``size`` = [nodes, springs, entries])
    into ``whole``; ``held`` marks what it placed (a node, spring or entry met twice is an error)."""
    try:
        index = {kind: p[kind] if kind in p.files else np.zeros(0, dtype=np.int64) for kind in held}
        arrays = {k: p[k] for k in whole}
    except Exception as exc:
        raise _unreadable(path, exc, "checkpoint piece") from None
    for (kind, idx), expected in zip(index.items(), size):
        if (idx.ndim != 1 or idx.dtype.kind not in "iu" or len(idx) != expected
                or (len(idx) and (idx.min() < 0 or idx.max() >= len(held[kind])))):
            raise InputError(f"{path}: its {kind} are not those the manifest lists ({len(idx)} against {expected}, "
                             f"or out of range)")
        seen = held[kind]
        if seen[idx].any():
            raise InputError(f"{path}: {kind[:-1]} {idx[seen[idx]][0]} is in another piece too")
        seen[idx] = True
    for k, values in arrays.items():
        idx = index[_INDEX_OF.get(k, "springs")]
        if values.shape != (len(idx),) + whole[k].shape[1:]:
            raise InputError(f"{path}: {k} has shape {values.shape} for {len(idx)} {_INDEX_OF.get(k, 'springs')}")
        whole[k][idx] = values
