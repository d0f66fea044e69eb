"""A minimal VTK XML UnstructuredGrid (.vtu) writer for spring nets: points and line cells.

Data go in one raw appended block (no base64, no compression) with UInt64 size headers, so numbers
round-trip bit for bit. The whole file of a frame is assembled once per net and field list as one
byte image (:class:`FrameImage`): XML header, topology (connectivity, offsets, cell types) and the
size header of every array are written once; each array is a NumPy view into the image that a
frame overwrites in place, and a frame is then a single ``write`` of the image, direct to the
device where the file system allows (no copy into the page cache). Arrays whose size
is a multiple of 8 bytes come first in the appended block, so every float64 view is aligned.
Readers checked by the tests: meshio and VTK (through PyVista).
"""

from __future__ import annotations

import sys
from typing import NamedTuple

import numpy as np

from .atomic import aligned_buffer, atomic_write_direct

VTK_LINE = 3

_VTK_TYPES = {
    np.dtype(np.float64): "Float64", np.dtype(np.float32): "Float32",
    np.dtype(np.int64): "Int64", np.dtype(np.int32): "Int32",
    np.dtype(np.uint8): "UInt8", np.dtype(np.int8): "Int8",
}
_HEADER = np.dtype(np.uint64)  # header_type="UInt64": the byte count before each array
_BYTE_ORDER = "LittleEndian" if sys.byteorder == "little" else "BigEndian"
_FOOTER = b"\n</AppendedData>\n</VTKFile>\n"
#: connectivity and offsets are Int32 below this many nodes and connectivity entries, else Int64
INT32_LIMIT = 2**31


def field_dtype(array: np.ndarray) -> np.dtype:
    """The dtype a field is stored with: its own if VTK has it (bool as UInt8), else float64."""
    dtype = np.dtype(np.uint8) if array.dtype == np.bool_ else array.dtype.newbyteorder("=")
    return dtype if dtype in _VTK_TYPES else np.dtype(np.float64)


class _Array(NamedTuple):
    """One array of the appended block: its XML section and name, dtype and shape, and its data
    where it never changes (the topology), else None."""

    section: str
    name: str
    dtype: np.dtype
    shape: tuple
    constant: np.ndarray | None

    @property
    def nbytes(self) -> int:
        return int(np.prod(self.shape)) * self.dtype.itemsize


class FrameImage:
    """The bytes of one .vtu file of a net, with a writable view per array.

    n_nodes, edges: (m, 2) node indices of each spring (VTK lines, in this order).
    point_fields, cell_fields: name -> (dtype, components); components 0 for a scalar (written
    without NumberOfComponents, so readers give it back as (rows,)).

    Attributes: ``points`` (n, 3) float64; ``point[name]`` and ``cell[name]`` of shape (rows,) or
    (rows, components). Fill them, then :meth:`write`.
    """

    def __init__(self, n_nodes: int, edges: np.ndarray, point_fields: dict, cell_fields: dict):
        edges = np.asarray(edges)
        n, m = int(n_nodes), len(edges)
        index = np.dtype(np.int32) if max(n, 2 * m) < INT32_LIMIT else np.dtype(np.int64)
        arrays = [_Array("Points", "Points", np.dtype(np.float64), (n, 3), None),
                  _Array("Cells", "connectivity", index, (2 * m,), edges.reshape(-1)),
                  _Array("Cells", "offsets", index, (m,), np.arange(2, 2 * m + 1, 2)),
                  _Array("Cells", "types", np.dtype(np.uint8), (m,), np.full(m, VTK_LINE))]
        for section, rows, fields in (("PointData", n, point_fields), ("CellData", m, cell_fields)):
            for name, (dtype, components) in fields.items():
                arrays.append(_Array(section, name, np.dtype(dtype), (rows, components) if components else (rows,), None))
        # 8-byte multiples first: each of those starts 8-aligned (the data start is aligned too)
        order = sorted(range(len(arrays)), key=lambda k: (arrays[k].nbytes % 8 != 0, k))
        offsets, offset = {}, 0
        for k in order:
            offsets[k] = offset
            offset += _HEADER.itemsize + arrays[k].nbytes
        tags = {"Points": [], "Cells": [], "PointData": [], "CellData": []}
        for k, a in enumerate(arrays):
            components = f' NumberOfComponents="{a.shape[1]}"' if len(a.shape) == 2 else ""
            tags[a.section].append(f'<DataArray type="{_VTK_TYPES[a.dtype]}" Name="{a.name}"{components} '
                                   f'format="appended" offset="{offsets[k]}"/>')
        head = "\n".join([
            '<?xml version="1.0"?>',
            f'<VTKFile type="UnstructuredGrid" version="1.0" byte_order="{_BYTE_ORDER}" header_type="UInt64">',
            "<UnstructuredGrid>",
            f'<Piece NumberOfPoints="{n}" NumberOfCells="{m}">',
            *(line for section in tags for line in (f"<{section}>", *tags[section], f"</{section}>")),
            "</Piece>",
            "</UnstructuredGrid>",
        ]).encode()
        tail = b'\n<AppendedData encoding="raw">\n_'
        head += b" " * (-(len(head) + len(tail)) % 8)
        start = len(head) + len(tail)
        size = start + offset + len(_FOOTER)
        self._padded = aligned_buffer(size)
        self.buffer = self._padded[:size]
        self.buffer[:start] = np.frombuffer(head + tail, dtype=np.uint8)
        self.buffer[start + offset:] = np.frombuffer(_FOOTER, dtype=np.uint8)
        self.points = None
        self.point, self.cell = {}, {}
        for k, a in enumerate(arrays):
            at = start + offsets[k]
            self.buffer[at:at + _HEADER.itemsize].view(_HEADER)[0] = a.nbytes
            at += _HEADER.itemsize
            view = self.buffer[at:at + a.nbytes].view(a.dtype).reshape(a.shape)
            if a.constant is not None:
                view[...] = a.constant
            elif a.section == "Points":
                self.points = view
            else:
                (self.point if a.section == "PointData" else self.cell)[a.name] = view
        self.n_nodes, self.n_cells = n, m

    def write(self, path, direct: bool = True) -> bool:
        """Write the image to ``path`` atomically, one write call, bypassing the page cache where
        the file system allows and ``direct`` (:func:`~thermonet.io.atomic.atomic_write_direct`);
        returns whether it did."""
        return atomic_write_direct(path, self._padded, len(self.buffer), direct)


class VTUWriter:
    """Writes frames of one net: fixed springs, moving points, changing fields.

    edges: (m, 2) node indices of each spring (written as VTK lines, in this order).
    n_nodes: number of points.
    """

    def __init__(self, edges: np.ndarray, n_nodes: int):
        self.edges = np.asarray(edges, dtype=np.int64)
        self.n_nodes = int(n_nodes)
        self.n_cells = len(self.edges)
        self._image: FrameImage | None = None
        self._schema = None

    def image(self, point_fields: dict, cell_fields: dict) -> FrameImage:
        """The :class:`FrameImage` for these fields (name -> (dtype, components)), kept while the
        fields stay the same."""
        schema = (tuple(point_fields.items()), tuple(cell_fields.items()))
        if schema != self._schema:
            self._image = FrameImage(self.n_nodes, self.edges, point_fields, cell_fields)
            self._schema = schema
        return self._image

    def write(self, path, points: np.ndarray, point_data: dict | None = None, cell_data: dict | None = None) -> None:
        """Write one frame to ``path`` atomically.

        points: (n, 3) float64 positions. point_data: name -> (n,) or (n, k) array.
        cell_data: name -> (m,) or (m, k) array, one row per spring.
        """
        points = np.asarray(points, dtype=np.float64)
        if points.shape != (self.n_nodes, 3):
            raise ValueError(f"points must have shape ({self.n_nodes}, 3), got {points.shape}")
        fields = []
        for data, rows in ((point_data or {}, self.n_nodes), (cell_data or {}, self.n_cells)):
            spec = {}
            for name, array in data.items():
                array = np.asarray(array)
                if array.shape[0] != rows:
                    raise ValueError(f"field {name!r} has {array.shape[0]} rows, expected {rows}")
                spec[name] = (field_dtype(array), int(np.prod(array.shape[1:])) if array.ndim > 1 else 0)
            fields.append(spec)
        image = self.image(*fields)
        image.points[...] = points
        for data, views in ((point_data or {}, image.point), (cell_data or {}, image.cell)):
            for name, array in data.items():
                views[name][...] = np.asarray(array).reshape(views[name].shape)
        image.write(path)
