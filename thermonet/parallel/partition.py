"""Nodes cut into P parts: recursive coordinate bisection (default), METIS (pymetis), or ranges
of the internal numbering cut between the conduction sweep's blocks (the default with conduction).

All are deterministic for a given net and P; the parts are computed once, by rank 0, and sent to
the others, so every process agrees on them whatever the partitioner does. The parts never change
the results, only the messages: a conduction block cut by a part's border makes its owner hold
and exchange the temperatures of the other side's springs at every colour of every sweep, which
"blocks" avoids (docs/parallel.md).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

METHODS = ("rcb", "metis", "blocks")


def bisect(points: np.ndarray, parts: int) -> np.ndarray:
    """Recursive coordinate bisection: (n,) part of each point, 0 … parts − 1.

    points: (n, 3). Each cut is across the longest side of the box of its points, at the point
    that splits them in proportion to the parts on either side (a stable sort: ties keep the
    points' order, so the cut is reproducible).
    """
    owner = np.zeros(len(points), dtype=np.int64)
    stack = [(np.arange(len(points)), 0, parts)]
    while stack:
        idx, first, count = stack.pop()
        if count == 1 or len(idx) == 0:
            owner[idx] = first
            continue
        left = count // 2
        p = points[idx]
        axis = int(np.argmax(p.max(axis=0) - p.min(axis=0))) if len(idx) else 0
        order = idx[np.argsort(p[:, axis], kind="stable")]
        cut = (len(idx) * left) // count
        stack.append((order[:cut], first, left))
        stack.append((order[cut:], first + left, count - left))
    return owner


def metis(edges: np.ndarray, n: int, parts: int) -> np.ndarray:
    """(n,) part of each node by METIS (pymetis) on the nodes' spring graph; edges: (m, 2)."""
    try:
        import pymetis
    except ImportError:
        raise InputError("partition 'metis' needs pymetis (pip install pymetis); 'rcb' needs nothing") from None
    both = np.concatenate([edges, edges[:, ::-1]])
    order = np.lexsort((both[:, 1], both[:, 0]))
    both = both[order]
    xadj = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(both[:, 0], minlength=n), out=xadj[1:])
    if hasattr(pymetis, "CSRAdjacency"):  # (pymetis ≥ 2025.2; the keywords are deprecated there)
        _, membership = pymetis.part_graph(parts, adjacency=pymetis.CSRAdjacency(xadj, both[:, 1]))
    else:
        _, membership = pymetis.part_graph(parts, xadj=xadj, adjncy=both[:, 1])
    return np.asarray(membership, dtype=np.int64)


def block_ranges(n: int, spans: np.ndarray, parts: int) -> np.ndarray | None:
    """(n,) part of each node: ranges of the numbering cut only between blocks, each cut the
    allowed one nearest to an even split; None where there are too few places to cut.

    spans: (B, 2) first and last node of each block (a block's nodes are a range of the numbering
    with gaps: the conduction sweep's blocks, :func:`thermonet.heat.graph.star_order`).
    """
    inside = np.zeros(n + 1, dtype=np.int64)  # a cut before node c is inside a block where lo < c ≤ hi
    np.add.at(inside, spans[:, 0] + 1, 1)
    np.add.at(inside, spans[:, 1] + 1, -1)
    allowed = np.flatnonzero(np.cumsum(inside)[1:n] == 0) + 1  # cuts 1 … n − 1
    cuts = []
    for q in range(1, parts):
        later = allowed[allowed > (cuts[-1] if cuts else 0)]
        if len(later) < parts - q:
            return None
        target = (q * n) // parts
        k = int(np.argmin(np.abs(later[:len(later) - (parts - q - 1)] - target)))
        cuts.append(int(later[k]))
    return np.searchsorted(np.asarray(cuts, dtype=np.int64), np.arange(n), side="right").astype(np.int64)


def partition(points: np.ndarray, edges: np.ndarray, parts: int, method: str = "rcb",
              spans: np.ndarray | None = None) -> np.ndarray:
    """(n,) the part (rank) owning each node, by ``method`` ("rcb", "metis" or "blocks").

    points: (n, 3) reference positions; edges: (m, 2) node pairs of the springs (any numbering,
    the same as points'; "blocks": the internal numbering, with ``spans`` the conduction
    blocks' of :func:`block_ranges`, and "rcb" where the blocks leave too few places to cut or
    there are none). Every part gets nodes where the net has at least ``parts`` nodes.
    """
    if method not in METHODS:
        raise InputError(f"partition {method!r}: choose one of {', '.join(METHODS)}")
    n = len(points)
    if n < parts:
        raise InputError(f"a net of {n} nodes cannot be split over {parts} processes: use at most {n}")
    owner = block_ranges(n, np.asarray(spans, dtype=np.int64), parts) if method == "blocks" and spans is not None \
        else None
    if owner is None:
        owner = metis(np.asarray(edges, dtype=np.int64), n, parts) if method == "metis" else \
            bisect(np.asarray(points, dtype=np.float64), parts)
    if len(np.unique(owner)) != parts:
        raise InputError(f"partition {method!r} left a process without nodes; use 'rcb' or fewer processes")
    return owner
