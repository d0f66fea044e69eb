"""Output a ParaView user expects, and what a restart needs: VTU frames + a PVD index, the
diagnostics CSV, ``summary.json`` and checkpoints. Every file is written atomically."""

from .atomic import atomic_write
from .checkpoint import load_checkpoint, save_checkpoint
from .pvd import PVDIndex, read_pvd
from .series import FIELDS, THERMAL_FIELDS, FrameFiller, RunOutput
from .vtu import FrameImage, VTUWriter

__all__ = [
    "atomic_write", "save_checkpoint", "load_checkpoint", "PVDIndex", "read_pvd", "VTUWriter", "FrameImage",
    "RunOutput", "FrameFiller", "FIELDS", "THERMAL_FIELDS",
]
