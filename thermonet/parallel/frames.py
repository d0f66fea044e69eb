"""Frames of a distributed run in ParaView's parallel format: per frame, one piece per process
(``<name>_NNNNNN_p<rank>.vtu``: the springs it reports and their nodes) and the ``.pvtu`` that
lists the pieces; the run's ``.pvd`` indexes the ``.pvtu`` files.

Rank 0 puts the frame together from the shares and writes every piece and the ``.pvtu``: the
other processes hold only their shares (no frame, no net). Each spring is in exactly one piece
(that of the process reporting it, :class:`~thermonet.parallel.domain.Decomposition`); a node at
a spring between pieces is a point of both. Everything is in the user's numbering, as in a frame
of one process.
"""

from __future__ import annotations

import os

import numpy as np

from ..io.atomic import atomic_write
from ..io.vtu import _BYTE_ORDER, _VTK_TYPES, FrameImage

#: the point and cell fields a piece adds: the node's and the spring's number in the whole net
NODE_ID, SPRING_ID = "node_id", "spring_id"


class PieceWriter:
    """The pieces of every frame, cut on rank 0 from the whole frame's image (rank 0 only).

    sim: the distributed Simulation (``sim.stepper.decomposition``, ``sim.layout``, ``sim.net``).
    Each piece q keeps its points' user numbers (k_q,) and its springs' (m_q,), ascending; its
    image is filled and written one piece at a time, so that rank 0 holds one piece's more.
    """

    def __init__(self, sim):
        self.size = sim.comm.Get_size()
        dec, layout = sim.stepper.decomposition, sim.layout
        edges = np.asarray(sim.net.edges, dtype=np.int64)
        self.nodes, self.springs, self._local = [], [], []
        for q in range(self.size):
            springs = np.sort(layout.spring_order[dec.owned_springs(q)])  # user numbering
            nodes = np.union1d(layout.node_order[dec.owned_nodes(q)], edges[springs].ravel())
            self.nodes.append(nodes)
            self.springs.append(springs)
            self._local.append(np.searchsorted(nodes, edges[springs]))
        self.point_fields = self.cell_fields = None

    def piece_name(self, stem: str, rank: int) -> str:
        return f"{stem}_p{rank}.vtu"

    def write(self, whole: FrameImage, folder: str, stem: str, direct: bool) -> str:
        """Write every piece of the filled frame ``whole``, then ``<stem>.pvtu`` listing them.
        Returns the .pvtu's file name."""
        # each point's and cell's number in the whole net: a reader joins the pieces by them
        self.point_fields = {**_spec(whole.point), NODE_ID: (np.dtype(np.int64), 0)}
        self.cell_fields = {**_spec(whole.cell), SPRING_ID: (np.dtype(np.int64), 0)}
        for q in range(self.size):
            nodes, springs = self.nodes[q], self.springs[q]
            piece = FrameImage(len(nodes), self._local[q], self.point_fields, self.cell_fields)
            piece.point[NODE_ID][:] = nodes
            piece.cell[SPRING_ID][:] = springs
            np.take(whole.points, nodes, axis=0, out=piece.points)
            for name, view in piece.point.items():
                if name != NODE_ID:
                    np.take(whole.point[name], nodes, axis=0, out=view)
            for name, view in piece.cell.items():
                if name != SPRING_ID:
                    np.take(whole.cell[name], springs, axis=0, out=view)
            piece.write(os.path.join(folder, self.piece_name(stem, q)), direct)
        name = f"{stem}.pvtu"  # (listed once its pieces are on disk)
        with atomic_write(os.path.join(folder, name), "w") as f:
            f.write(self.pvtu([self.piece_name(stem, q) for q in range(self.size)]))
        return name

    def pvtu(self, pieces: list[str]) -> str:
        """The text of a .pvtu listing ``pieces`` (file names beside it)."""
        def arrays(fields):
            for name, (dtype, components) in fields.items():
                comps = f' NumberOfComponents="{components}"' if components else ""
                yield f'<PDataArray type="{_VTK_TYPES[np.dtype(dtype)]}" Name="{name}"{comps}/>'

        return "\n".join([
            '<?xml version="1.0"?>',
            f'<VTKFile type="PUnstructuredGrid" version="1.0" byte_order="{_BYTE_ORDER}" header_type="UInt64">',
            '<PUnstructuredGrid GhostLevel="0">',
            '<PPoints><PDataArray type="Float64" NumberOfComponents="3"/></PPoints>',
            "<PPointData>", *arrays(self.point_fields), "</PPointData>",
            "<PCellData>", *arrays(self.cell_fields), "</PCellData>",
            *(f'<Piece Source="{p}"/>' for p in pieces),
            "</PUnstructuredGrid>",
            "</VTKFile>",
            "",
        ])


def _spec(views: dict) -> dict:
    """name -> (dtype, components) of a frame image's field views."""
    return {name: (v.dtype, v.shape[1] if v.ndim == 2 else 0) for name, v in views.items()}
