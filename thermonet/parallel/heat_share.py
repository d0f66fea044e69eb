"""One process's part of the conduction sweep: its star blocks, the springs they touch, and who
sends which temperatures to whom between the sweep's phases.

The sweep's order is the whole net's (:class:`~thermonet.heat.graph.StarOrder`: colours of
blocks of junction nodes, each block's nodes one after the other). Each block is swept by one
process, the owner of its first node; a block never straddles two processes' work, so the
nodes of a block run in the order of one process. A colour's blocks share no spring, so within
a colour the processes need nothing from each other; after it, each spring a process's blocks
changed goes to every other process that holds it. The baths and sources of a spring are swept
by the process that reports it (:meth:`~thermonet.parallel.domain.Decomposition.owned_springs`),
which holds its temperature.

A process holds the temperatures of its share's springs (first, in the share's order: the
mechanical passes' θ) and of the further springs its blocks touch (after them, ascending).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Plan:
    """One exchange of spring values: send[q], recv[q] (k,) int64 local indices of the values
    going to / coming from process q, in ascending whole-net spring order on both sides."""

    send: dict
    recv: dict


@dataclass(frozen=True)
class HeatShare:
    """Rank r's part of the sweep (local indices where not said otherwise).

    springs: (ls,) int64 whole-net numbers of the springs r holds θ of (the share's ml first);
    colour_ptr: (C+1,) int64 r's blocks of each colour; block_ptr: (b+1,) int64 their nodes in
    nodes (0..k−1, in sweep order); node: (k,) int64 their whole-net numbers;
    incidence: (k',) int64 the whole-net incidence (position in inc_spring) of each of the
    nodes' springs, in order; inc_ptr (k+1,) int64, inc_spring (k',) uint32 the local lists;
    bound: (S_r,) int64 the whole-net boundary springs r sweeps (indices into bound_spring);
    entries: (E_r,) int64 their entries (whole-net entry numbers, ascending);
    start: the θ of the further springs before a sweep; colours: one Plan per colour; boundary:
    the Plan after the baths and sources.
    """

    springs: np.ndarray
    colour_ptr: np.ndarray
    block_ptr: np.ndarray
    node: np.ndarray
    incidence: np.ndarray
    inc_ptr: np.ndarray
    inc_spring: np.ndarray
    bound: np.ndarray
    entries: np.ndarray
    start: Plan
    colours: list
    boundary: Plan


def _touched(order, inc_ptr, inc_spring, blocks) -> tuple[np.ndarray, np.ndarray]:
    """(nodes, incidence positions) of ``blocks`` (ascending block numbers) in sweep order."""
    sizes = order.block_ptr[blocks + 1] - order.block_ptr[blocks]
    nodes = order.node[np.repeat(order.block_ptr[blocks], sizes) + ranges(sizes)]
    deg = inc_ptr[nodes + 1] - inc_ptr[nodes]
    return nodes, np.repeat(inc_ptr[nodes], deg) + ranges(deg)


def ranges(sizes: np.ndarray) -> np.ndarray:
    """0..s−1 for each s of sizes, concatenated."""
    total = int(sizes.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    starts = np.repeat(np.cumsum(sizes) - sizes, sizes)
    return np.arange(total, dtype=np.int64) - starts


def _plan(source: np.ndarray, wants: list, rank: int, local: np.ndarray) -> Plan:
    """The exchange where spring e's value goes from process source[e] (−1: none) to every other
    process q with wants[q][e]; local: (m,) this process's local index of each spring."""
    send, recv = {}, {}
    mine = source == rank
    for q, want in enumerate(wants):
        if q == rank:
            continue
        out = np.flatnonzero(mine & want)
        if len(out):
            send[q] = local[out]
        come = np.flatnonzero((source == q) & wants[rank])
        if len(come):
            recv[q] = local[come]
    return Plan(send, recv)


def heat_shares(order, inc_ptr, inc_spring, bound_spring, bound_ptr, dec, share_springs: list, rank: int):
    """Rank ``rank``'s :class:`HeatShare`, for the whole net's sweep ``order``
    (:class:`~thermonet.heat.graph.StarOrder`), incidence lists ``inc_ptr`` (n+1,),
    ``inc_spring`` (2m,), boundary springs ``bound_spring`` (S,) with entries ``bound_ptr``
    (S+1,); dec: the decomposition; share_springs: every process's share springs (ascending)."""
    inc_ptr = np.asarray(inc_ptr, dtype=np.int64)
    inc_spring = np.asarray(inc_spring, dtype=np.int64)
    m, size = len(dec.spring_owner), dec.size
    n_blocks = len(order.block_ptr) - 1
    block_owner = dec.owner[order.node[order.block_ptr[:-1]]] if n_blocks else np.zeros(0, dtype=np.int64)
    holds, further, parts = [], [], []  # per process: the springs it holds θ of; of those, beyond its share
    for q in range(size):
        blocks = np.flatnonzero(block_owner == q)
        nodes, incidence = _touched(order, inc_ptr, inc_spring, blocks)
        in_share = np.zeros(m, dtype=bool)
        in_share[share_springs[q]] = True
        touched = np.zeros(m, dtype=bool)
        touched[inc_spring[incidence]] = True
        further.append(touched & ~in_share)
        holds.append(touched | in_share)
        parts.append((blocks, nodes, incidence))
    blocks, nodes, incidence = parts[rank]
    springs = np.concatenate([share_springs[rank], np.flatnonzero(further[rank])])
    local = np.full(m, -1, dtype=np.int64)
    local[springs] = np.arange(len(springs))
    deg = inc_ptr[nodes + 1] - inc_ptr[nodes]
    block_sizes = order.block_ptr[blocks + 1] - order.block_ptr[blocks]
    colours = []
    spring_owner = dec.spring_owner
    for c in range(len(order.colour_ptr) - 1):  # who changes each spring in colour c
        source = np.full(m, -1, dtype=np.int64)
        in_colour = np.arange(order.colour_ptr[c], order.colour_ptr[c + 1])
        for q in range(size):
            _, inc_q = _touched(order, inc_ptr, inc_spring, in_colour[block_owner[in_colour] == q])
            source[inc_spring[inc_q]] = q
        colours.append(_plan(source, holds, rank, local))
    bound_source = np.full(m, -1, dtype=np.int64)
    bound_source[bound_spring] = spring_owner[bound_spring]
    start_source = np.where(np.logical_or.reduce(further), spring_owner, -1) if size else np.full(m, -1)
    bound = np.flatnonzero(spring_owner[bound_spring] == rank) if len(bound_spring) else np.zeros(0, dtype=np.int64)
    entry_sizes = bound_ptr[bound + 1] - bound_ptr[bound]
    entries = np.repeat(bound_ptr[bound], entry_sizes) + ranges(entry_sizes)
    return HeatShare(springs, np.searchsorted(blocks, order.colour_ptr).astype(np.int64),
                     np.concatenate([[0], np.cumsum(block_sizes)]).astype(np.int64), nodes, incidence,
                     np.concatenate([[0], np.cumsum(deg)]).astype(np.int64),
                     np.ascontiguousarray(local[inc_spring[incidence]], dtype=np.uint32),
                     bound, entries, _plan(start_source, further, rank, local), colours,
                     _plan(bound_source, holds, rank, local))
