"""A minimal VTK XML UnstructuredGrid (.vtu) writer for spring nets: points and line cells.

Data go in one raw appended block (no base64, no compression) with UInt64 size headers, so a
frame is a handful of ``tobytes()`` calls and numbers round-trip bit for bit. The topology
(connectivity, offsets, cell types) is encoded once per net and reused by every frame.
Readers checked by the tests: meshio and VTK (through PyVista).
"""

from __future__ import annotations

import numpy as np

from .atomic import atomic_write

VTK_LINE = 3

_VTK_TYPES = {
    np.dtype(np.float64): "Float64", np.dtype(np.float32): "Float32",
    np.dtype(np.int64): "Int64", np.dtype(np.int32): "Int32",
    np.dtype(np.uint8): "UInt8", np.dtype(np.int8): "Int8",
}


def _block(array: np.ndarray) -> tuple[bytes, memoryview]:
    """An appended-data block: its UInt64 byte count and the array's bytes (no copy when the
    array is already contiguous little-endian)."""
    data = np.ascontiguousarray(array)
    return np.array(data.nbytes, dtype="<u8").tobytes(), memoryview(data).cast("B")


class VTUWriter:
    """Writes frames of one net: fixed springs, moving points, changing fields.

    edges: (m, 2) node indices of each spring (written as VTK lines, in this order).
    n_nodes: number of points.
    """

    def __init__(self, edges: np.ndarray, n_nodes: int):
        edges = np.asarray(edges, dtype=np.int64)
        self.n_nodes = int(n_nodes)
        self.n_cells = len(edges)
        self._topology = [
            ("connectivity", _block(edges.reshape(-1).astype("<i8")), "Int64", 1),
            ("offsets", _block(np.arange(2, 2 * self.n_cells + 1, 2, dtype="<i8")), "Int64", 1),
            ("types", _block(np.full(self.n_cells, VTK_LINE, dtype=np.uint8)), "UInt8", 1),
        ]

    def write(self, path, points: np.ndarray, point_data: dict | None = None, cell_data: dict | None = None) -> None:
        """Write one frame to ``path`` atomically.

        points: (n, 3) float64 positions. point_data: name -> (n,) or (n, k) array.
        cell_data: name -> (m,) or (m, k) array, one row per spring.
        """
        points = np.asarray(points, dtype="<f8")
        if points.shape != (self.n_nodes, 3):
            raise ValueError(f"points must have shape ({self.n_nodes}, 3), got {points.shape}")
        blocks: list[tuple[bytes, memoryview]] = []
        offset = 0

        def array_tag(name: str, array: np.ndarray, rows: int) -> str:
            nonlocal offset
            array = np.asarray(array)
            if array.dtype == np.bool_:
                array = array.astype(np.uint8)
            dtype = array.dtype.newbyteorder("=")
            if dtype not in _VTK_TYPES:
                dtype = np.dtype(np.float64)
            if array.shape[0] != rows:
                raise ValueError(f"field {name!r} has {array.shape[0]} rows, expected {rows}")
            # scalars carry no NumberOfComponents, so that readers give them back as (rows,)
            components = "" if array.ndim == 1 else f' NumberOfComponents="{int(np.prod(array.shape[1:]))}"'
            block = _block(array.astype(dtype.newbyteorder("<"), copy=False))
            tag = (f'<DataArray type="{_VTK_TYPES[dtype]}" Name="{name}"{components} '
                   f'format="appended" offset="{offset}"/>')
            blocks.append(block)
            offset += len(block[0]) + len(block[1])
            return tag

        def topology_tag(name: str, block: bytes, vtk_type: str) -> str:
            nonlocal offset
            tag = f'<DataArray type="{vtk_type}" Name="{name}" format="appended" offset="{offset}"/>'
            blocks.append(block)
            offset += len(block[0]) + len(block[1])
            return tag

        xml = [
            '<?xml version="1.0"?>',
            '<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">',
            "<UnstructuredGrid>",
            f'<Piece NumberOfPoints="{self.n_nodes}" NumberOfCells="{self.n_cells}">',
            "<Points>", array_tag("Points", points, self.n_nodes), "</Points>",
            "<Cells>", *(topology_tag(n, b, t) for n, b, t, _ in self._topology), "</Cells>",
            "<PointData>", *(array_tag(k, v, self.n_nodes) for k, v in (point_data or {}).items()), "</PointData>",
            "<CellData>", *(array_tag(k, v, self.n_cells) for k, v in (cell_data or {}).items()), "</CellData>",
            "</Piece>",
            "</UnstructuredGrid>",
            '<AppendedData encoding="raw">',
        ]
        with atomic_write(path) as f:
            f.write("\n".join(xml).encode() + b"\n_")
            for header, data in blocks:
                f.write(header)
                f.write(data)
            f.write(b"\n</AppendedData>\n</VTKFile>\n")
