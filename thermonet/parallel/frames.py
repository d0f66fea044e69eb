"""Frames of a distributed run in ParaView's parallel format: per frame, every process writes its
piece (``<name>_NNNNNN_p<rank>.vtu``: its springs and their nodes) and rank 0 the ``.pvtu`` that
lists the pieces; the run's ``.pvd`` indexes the ``.pvtu`` files.

Each spring is in exactly one piece (that of the process reporting it,
:class:`~thermonet.parallel.domain.Decomposition`); a node at a spring between pieces is a point
of both. Everything is in the user's numbering, as in a frame of one process.
"""

from __future__ import annotations

import os

import numpy as np

from ..io.atomic import atomic_write
from ..io.vtu import _BYTE_ORDER, _VTK_TYPES, FrameImage

#: the point and cell fields a piece adds: the node's and the spring's number in the whole net
NODE_ID, SPRING_ID = "node_id", "spring_id"


class PieceWriter:
    """This process's piece of every frame, cut from the whole frame's image.

    sim: the distributed Simulation (``sim.stepper.decomposition``); whole: the whole frame's
    :class:`~thermonet.io.vtu.FrameImage` (its fields are the piece's).
    """

    def __init__(self, sim, whole: FrameImage):
        point_fields, cell_fields = (_spec(whole.point), _spec(whole.cell))
        comm = sim.comm
        self.comm, self.rank, self.size = comm, comm.Get_rank(), comm.Get_size()
        dec, layout = sim.stepper.decomposition, sim.layout
        springs = np.sort(layout.spring_order[dec.owned_springs(self.rank)])  # user numbering
        edges = np.asarray(sim.net.edges, dtype=np.int64)[springs]
        owned = layout.node_order[dec.owned_nodes(self.rank)]
        self.nodes = np.union1d(owned, edges.ravel())  # (k,) user node numbers of the piece's points
        self.springs = springs
        local = np.searchsorted(self.nodes, edges)
        # each point's and cell's number in the whole net: a reader joins the pieces by them
        point_fields = {**point_fields, NODE_ID: (np.dtype(np.int64), 0)}
        cell_fields = {**cell_fields, SPRING_ID: (np.dtype(np.int64), 0)}
        self.image = FrameImage(len(self.nodes), local, point_fields, cell_fields)
        self.image.point[NODE_ID][:] = self.nodes
        self.image.cell[SPRING_ID][:] = self.springs
        self.point_fields, self.cell_fields = point_fields, cell_fields

    def piece_name(self, stem: str, rank: int) -> str:
        return f"{stem}_p{rank}.vtu"

    def write(self, whole: FrameImage, folder: str, stem: str, direct: bool) -> str:
        """Write this process's piece of the filled frame ``whole``; rank 0 also writes
        ``<stem>.pvtu`` once every piece is on disk. Returns the .pvtu's file name."""
        piece = self.image
        np.take(whole.points, self.nodes, axis=0, out=piece.points)
        for name, view in piece.point.items():
            if name != NODE_ID:
                np.take(whole.point[name], self.nodes, axis=0, out=view)
        for name, view in piece.cell.items():
            if name != SPRING_ID:
                np.take(whole.cell[name], self.springs, axis=0, out=view)
        piece.write(os.path.join(folder, self.piece_name(stem, self.rank)), direct)
        self.comm.Barrier()  # the index lists complete pieces only
        name = f"{stem}.pvtu"
        if self.rank == 0:
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
