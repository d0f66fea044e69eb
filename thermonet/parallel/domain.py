"""One process's share of a partitioned net: its nodes, the springs it needs, one ghost layer.

Everything here is in the engine's internal numbering (:mod:`thermonet.layout`) restricted to
the share: a process's nodes (owned and ghost) and springs keep the order they have in the whole
net (the internal order restricted: the reverse Cuthill–McKee order of the share), so each owned
node lists its springs in the same order as in one process and sums its force in that order:
the force, bit for bit. A spring with ends on two processes is kept and computed by both.
Ghost nodes are held still in the local node pass (as anchors are) and take their positions from
their owners at every stage (:mod:`thermonet.parallel.halo`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels import records
from ..layout import incidence


@dataclass(frozen=True)
class Share:
    """Rank r's part of the net (internal numbering of the whole net where not said otherwise).

    nodes: (nl,) int64 the share's nodes, owned and ghost, ascending; springs: (ml,) int64 the
    springs with an owned end, ascending; owned: (nl,) bool which local nodes r owns;
    topology: the local :class:`~thermonet.kernels.records.Topology` (local indices);
    send, recv: neighbour rank -> (k,) int64 local indices of the owned nodes whose positions go
    to it / of the ghosts that come from it, in ascending internal order on both sides.
    """

    rank: int
    nodes: np.ndarray
    springs: np.ndarray
    owned: np.ndarray
    topology: records.Topology
    send: dict
    recv: dict

    @property
    def ghosts(self) -> int:
        return int(len(self.nodes) - np.count_nonzero(self.owned))


@dataclass(frozen=True)
class Decomposition:
    """Who owns what, known on every process (for the halo and for gathering the state).

    owner: (n,) int64 rank of each internal node; spring_owner: (m,) int64 the rank that reports
    each spring when the state is gathered (the owner of its first end), each spring once.
    """

    owner: np.ndarray
    spring_owner: np.ndarray
    size: int

    def owned_nodes(self, rank: int) -> np.ndarray:
        return np.flatnonzero(self.owner == rank)

    def owned_springs(self, rank: int) -> np.ndarray:
        return np.flatnonzero(self.spring_owner == rank)


def decomposition(owner: np.ndarray, edges: np.ndarray, size: int) -> Decomposition:
    """The :class:`Decomposition` of ``owner`` (n,) over internal ``edges`` (m, 2)."""
    owner = np.asarray(owner, dtype=np.int64)
    return Decomposition(owner, owner[edges[:, 0]], int(size))


def share(dec: Decomposition, edges: np.ndarray, rank: int) -> Share:
    """Rank ``rank``'s :class:`Share` of a net with internal ``edges`` (m, 2)."""
    owner = dec.owner
    e0, e1 = edges[:, 0].astype(np.int64), edges[:, 1].astype(np.int64)
    o0, o1 = owner[e0], owner[e1]
    springs = np.flatnonzero((o0 == rank) | (o1 == rank))
    nodes = np.union1d(dec.owned_nodes(rank), np.concatenate([e0[springs], e1[springs]]))
    local = np.full(len(owner), -1, dtype=np.int64)
    local[nodes] = np.arange(len(nodes))
    local_edges = np.stack([local[e0[springs]], local[e1[springs]]], axis=1)
    send, recv = _halo_lists(owner, e0, e1, o0, o1, rank, local)
    return Share(rank, nodes, springs, owner[nodes] == rank, _topology(local_edges, len(nodes)), send, recv)


def _halo_lists(owner, e0, e1, o0, o1, rank, local) -> tuple[dict, dict]:
    """Per neighbour q: local indices of r's nodes that are ghosts on q, and of q's nodes that
    are ghosts on r; both in ascending internal order, so the two sides agree on the order."""
    cross = o0 != o1
    node = np.concatenate([e0[cross], e1[cross]])  # a node at a crossing spring ...
    to = np.concatenate([o1[cross], o0[cross]])  # ... is a ghost on the other end's owner
    pairs = np.unique(np.stack([to, node], axis=1), axis=0)  # sorted by (to, node)
    send, recv = {}, {}
    mine = pairs[owner[pairs[:, 1]] == rank]
    for q in np.unique(mine[:, 0]):
        send[int(q)] = local[mine[mine[:, 0] == q, 1]]
    theirs = pairs[pairs[:, 0] == rank]
    for q in np.unique(owner[theirs[:, 1]]):
        recv[int(q)] = local[theirs[owner[theirs[:, 1]] == q, 1]]
    return send, recv


def _topology(edges: np.ndarray, n: int) -> records.Topology:
    """The incidence lists of local ``edges`` (ml, 2) over n local nodes, built as the whole
    net's are (:func:`thermonet.layout.build_layout`: each node's springs in spring order)."""
    inc_ptr, inc_spring, inc_other = incidence(edges, n)
    return records.Topology(np.ascontiguousarray(edges, dtype=np.int32).view(np.uint32), inc_ptr,
                            inc_spring.view(np.uint32), inc_other.view(np.uint32))
