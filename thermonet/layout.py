"""Internal numbering of nodes and springs chosen for memory locality, and node→spring incidence.

The engine works in its own numbering (reverse Cuthill–McKee on nodes, springs sorted by their
first internal node) so that the springs touched by neighbouring nodes sit close in memory.
Everything a user sees is mapped back to the user's numbering.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from .net import Net


@dataclass(frozen=True)
class Layout:
    """Permutations between user and internal numbering, and the incidence lists.

    node_order: (n,) internal node i is user node node_order[i].
    node_rank: (n,) user node a is internal node node_rank[a].
    spring_order, spring_rank: (m,) the same for springs.
    edges: (m, 2) int32, internal node indices of internal spring e.
    inc_ptr: (n+1,) int64, incident springs of internal node a are inc_spring[inc_ptr[a]:inc_ptr[a+1]].
    inc_spring: (2m,) int32, spring index of each incidence.
    inc_other: (2m,) int32, the node at the spring's other end.
    """

    node_order: np.ndarray
    node_rank: np.ndarray
    spring_order: np.ndarray
    spring_rank: np.ndarray
    edges: np.ndarray
    inc_ptr: np.ndarray
    inc_spring: np.ndarray
    inc_other: np.ndarray

    @property
    def n_nodes(self) -> int:
        return len(self.node_order)

    @property
    def n_springs(self) -> int:
        return len(self.spring_order)

    # user <-> internal conversions (np.take: several times faster than fancy indexing on (n, 3))
    def nodes_to_internal(self, a: np.ndarray) -> np.ndarray:
        return np.take(a, self.node_order, axis=0)

    def nodes_to_user(self, a: np.ndarray) -> np.ndarray:
        return np.take(a, self.node_rank, axis=0)

    def springs_to_internal(self, a: np.ndarray) -> np.ndarray:
        return np.take(a, self.spring_order, axis=0)

    def springs_to_user(self, a: np.ndarray) -> np.ndarray:
        return np.take(a, self.spring_rank, axis=0)


def build_layout(net: Net, renumber: bool = True) -> Layout:
    """Choose the internal numbering of ``net`` and build its incidence lists."""
    n, m = net.n_nodes, net.n_springs
    user_edges = net.edges.astype(np.int64)
    if renumber and n > 2:
        adj = sp.coo_matrix((np.ones(m), (user_edges[:, 0], user_edges[:, 1])), shape=(n, n)).tocsr()
        adj = (adj + adj.T).tocsr()
        node_order = np.asarray(reverse_cuthill_mckee(adj, symmetric_mode=True), dtype=np.int64)
    else:
        node_order = np.arange(n, dtype=np.int64)
    node_rank = np.empty(n, dtype=np.int64)
    node_rank[node_order] = np.arange(n)
    internal = node_rank[user_edges]
    if renumber:
        spring_order = np.lexsort((internal.max(axis=1), internal.min(axis=1)))
    else:
        spring_order = np.arange(m, dtype=np.int64)
    spring_rank = np.empty(m, dtype=np.int64)
    spring_rank[spring_order] = np.arange(m)
    edges = internal[spring_order]

    inc_ptr, inc_spring, inc_other = incidence(edges, n)
    return Layout(
        node_order=node_order,
        node_rank=node_rank,
        spring_order=spring_order,
        spring_rank=spring_rank,
        edges=np.ascontiguousarray(edges, dtype=np.int32),
        inc_ptr=inc_ptr,
        inc_spring=inc_spring,
        inc_other=inc_other,
    )


def incidence(edges: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Incidence lists of ``edges`` (m, 2) over n nodes, each node's springs in spring order:
    (inc_ptr (n + 1,) int64, inc_spring (2m,) int32, inc_other (2m,) int32), node i's springs
    and their other ends at inc_ptr[i]:inc_ptr[i + 1]."""
    m = len(edges)
    ends = np.concatenate([edges[:, 0], edges[:, 1]])
    others = np.concatenate([edges[:, 1], edges[:, 0]])
    springs = np.concatenate([np.arange(m), np.arange(m)])
    order = np.lexsort((springs, ends))
    inc_ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(ends, minlength=n), out=inc_ptr[1:])
    return inc_ptr, springs[order].astype(np.int32), others[order].astype(np.int32)
