"""Checkpoints: the full integrator state (user numbering, exact float64; with heat flow its logs),
the step counter, the scene hash and what the outputs need to continue (diagnostics rows, frames written so far).

A ``.npz`` file written atomically; resuming from it continues a run bit for bit.
"""

from __future__ import annotations

import json
import os

import numpy as np

from ..errors import InputError
from ..state import State
from .atomic import atomic_write

FORMAT = "thermonet-checkpoint-1"


def save_checkpoint(path, state: State, meta: dict) -> None:
    """Write ``state`` (user numbering) and ``meta`` (JSON-serialisable; floats are kept exactly,
    since JSON writes ``repr`` of a float) to ``path`` atomically."""
    arrays = {
        "positions": state.positions,
        "momenta": state.momenta,
        "time": np.float64(state.time),
        "step": np.int64(state.step),
        "meta": np.frombuffer(json.dumps({"format": FORMAT, **meta}).encode(), dtype=np.uint8),
    }
    if state.entropy is not None:
        arrays["entropy"] = state.entropy
        arrays["thermal_displacement"] = state.thermal_displacement
    for key, value in (state.extra.get("heat") or {}).items():  # heat-flow logs
        arrays[f"heat_{key}"] = value
    for key, value in state.extra.items():  # accumulators such as the loads' work
        if isinstance(value, np.ndarray):
            arrays[f"extra.{key}"] = value
    with atomic_write(path) as f:
        np.savez(f, **arrays)


def load_checkpoint(path) -> tuple[State, dict]:
    """The state and metadata saved by :func:`save_checkpoint`. Errors name the file."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"{path}: no such checkpoint file")
    try:
        with open(path, "rb") as f:
            magic = f.read(4)
    except OSError as exc:
        raise InputError(f"{path}: cannot read the checkpoint: {exc.strerror}") from None
    if magic != b"PK\x03\x04":  # every .npz is a zip file
        raise InputError(f"{path}: not a readable thermonet checkpoint (not a .npz file: corrupt, truncated to "
                         f"{os.path.getsize(path)} bytes, or another kind of file)")
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(bytes(z["meta"]).decode())
            thermal = "entropy" in z.files
            state = State(
                positions=z["positions"].copy(),
                momenta=z["momenta"].copy(),
                thermal_displacement=z["thermal_displacement"].copy() if thermal else None,
                entropy=z["entropy"].copy() if thermal else None,
                time=float(z["time"]),
                step=int(z["step"]),
                extra={k[len("extra."):]: z[k].copy() for k in z.files if k.startswith("extra.")},
            )
            logs = {k[len("heat_"):]: z[k].copy() for k in z.files if k.startswith("heat_")}
            if logs:
                state.extra["heat"] = logs
    except Exception as exc:  # zipfile.BadZipFile, EOFError, zlib.error, OSError, ValueError, KeyError, ...
        reason = str(exc) or type(exc).__name__
        raise InputError(f"{path}: not a readable thermonet checkpoint (corrupt or truncated? {reason})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        found = meta.get("format") if isinstance(meta, dict) else None
        raise InputError(f"{path}: not a thermonet checkpoint (format {found!r}, expected {FORMAT})")
    return state, meta
