"""Nodes cut into P parts: recursive coordinate bisection (default) or METIS (pymetis).

Both are deterministic for a given net and P; the parts are computed once, by rank 0, and sent to
the others, so every process agrees on them whatever the partitioner does.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

METHODS = ("rcb", "metis")


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


def partition(points: np.ndarray, edges: np.ndarray, parts: int, method: str = "rcb") -> np.ndarray:
    """(n,) the part (rank) owning each node, by ``method`` ("rcb" or "metis").

    points: (n, 3) reference positions; edges: (m, 2) node pairs of the springs (any numbering,
    the same as points'). Every part gets nodes where the net has at least ``parts`` nodes.
    """
    if method not in METHODS:
        raise InputError(f"partition {method!r}: choose one of {', '.join(METHODS)}")
    n = len(points)
    if n < parts:
        raise InputError(f"a net of {n} nodes cannot be split over {parts} processes: use at most {n}")
    owner = bisect(np.asarray(points, dtype=np.float64), parts) if method == "rcb" else \
        metis(np.asarray(edges, dtype=np.int64), n, parts)
    if len(np.unique(owner)) != parts:
        raise InputError(f"partition {method!r} left a process without nodes; use 'rcb' or fewer processes")
    return owner
