"""The ParaView collection (.pvd) that indexes a time series of .vtu frames.

The index is rewritten atomically, and only after the frame files it lists are complete, so it
only ever lists frames that exist in full.
"""

from __future__ import annotations

import os
from xml.etree import ElementTree as ET
from xml.sax.saxutils import quoteattr

from .atomic import atomic_write


class PVDIndex:
    """Frames of one run: step -> (time, file name relative to the PVD's folder)."""

    def __init__(self, path, frames: dict[int, tuple[float, str]] | None = None):
        self.path = os.fspath(path)
        self.frames: dict[int, tuple[float, str]] = dict(frames or {})
        #: whether the file lists every recorded frame
        self.written = True

    def add(self, step: int, time: float, filename: str, write: bool = True) -> None:
        """Record a complete frame (a frame of the same step is replaced) and, with ``write``,
        rewrite the index."""
        self.frames[int(step)] = (float(time), filename)
        self.written = False
        if write:
            self.write()

    def write(self) -> None:
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 "  <Collection>"]
        for step in sorted(self.frames):
            time, name = self.frames[step]
            lines.append(f'    <DataSet timestep="{time!r}" group="" part="0" file={quoteattr(name)}/>')
        lines += ["  </Collection>", "</VTKFile>", ""]
        with atomic_write(self.path, "w") as f:
            f.write("\n".join(lines))
        self.written = True


def read_pvd(path) -> list[tuple[float, str]]:
    """(time, absolute file path) of every frame listed in a .pvd, in file order."""
    path = os.fspath(path)
    root = ET.parse(path).getroot()
    folder = os.path.dirname(os.path.abspath(path))
    return [(float(ds.get("timestep")), os.path.join(folder, ds.get("file")))
            for ds in root.iter("DataSet")]
