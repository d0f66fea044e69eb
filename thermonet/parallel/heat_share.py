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


def ascending_set(values: np.ndarray, m: int, without: np.ndarray | None = None) -> np.ndarray:
    """(k,) int64 the distinct ``values`` (in 0..m−1) ascending, but those in ``without``: a mask
    of m bytes (faster than sorting the values for the sizes here)."""
    mask = np.zeros(m, dtype=bool)
    mask[values] = True
    if without is not None:
        mask[without] = False
    return np.flatnonzero(mask)


def _springs_of(order, inc_ptr, inc_spring, blocks, m: int) -> np.ndarray:
    """(k,) int64 the springs ``blocks`` touch, ascending."""
    return ascending_set(inc_spring[_touched(order, inc_ptr, inc_spring, blocks)[1]], m)


def heat_shares(order, inc_ptr, inc_spring, bound_spring, bound_ptr, dec, share_springs: list, rank: int):
    """Rank ``rank``'s :class:`HeatShare`, for the whole net's sweep ``order``
    (:class:`~thermonet.heat.graph.StarOrder`), incidence lists ``inc_ptr`` (n+1,),
    ``inc_spring`` (2m,), boundary springs ``bound_spring`` (S,) ascending with entries
    ``bound_ptr`` (S+1,); dec: the decomposition; share_springs: every process's share springs
    (ascending).

    Process q *holds* a spring's θ when it is in q's share or one of q's blocks touches it; it
    *changes* it in colour c when one of q's blocks of colour c touches it (one process at most:
    a colour's blocks share no spring). The other processes are visited one at a time, each
    through the springs its blocks touch and its share: memory of the order of m, whatever the
    number of processes.
    """
    inc_ptr = np.asarray(inc_ptr, dtype=np.int64)
    inc_spring = np.asarray(inc_spring, dtype=np.int64)
    m, size = len(dec.spring_owner), dec.size
    spring_owner = dec.spring_owner
    n_blocks = len(order.block_ptr) - 1
    n_colours = len(order.colour_ptr) - 1
    block_owner = dec.owner[order.node[order.block_ptr[:-1]]] if n_blocks else np.zeros(0, dtype=np.int64)
    block_colour = np.repeat(np.arange(n_colours), np.diff(order.colour_ptr))

    def blocks_of(q, colour=None):
        mask = block_owner == q
        if colour is not None:
            mask &= block_colour == colour
        return np.flatnonzero(mask)

    blocks = blocks_of(rank)
    nodes, incidence = _touched(order, inc_ptr, inc_spring, blocks)
    share_me = np.asarray(share_springs[rank], dtype=np.int64)
    further_me = ascending_set(inc_spring[incidence], m, without=share_me)
    springs = np.concatenate([share_me, further_me])
    local = np.full(m, -1, dtype=np.int64)
    local[springs] = np.arange(len(springs))
    held_me = local >= 0
    changed = [_springs_of(order, inc_ptr, inc_spring, blocks_of(rank, c), m) for c in range(n_colours)]
    has_bound = len(bound_spring) > 0
    bound_spring = np.asarray(bound_spring, dtype=np.int64)
    bound_owner = spring_owner[bound_spring] if has_bound else np.zeros(0, dtype=np.int64)
    bound_me = bound_spring[bound_owner == rank]
    colours = [Plan({}, {}) for _ in range(n_colours)]
    start, boundary = Plan({}, {}), Plan({}, {})

    def add(into: dict, q: int, whole: np.ndarray) -> None:
        if len(whole):
            into[q] = local[whole]

    for q in range(size):
        if q == rank:
            continue
        share_q = np.asarray(share_springs[q], dtype=np.int64)
        touched_q = _springs_of(order, inc_ptr, inc_spring, blocks_of(q), m)
        for c in range(n_colours):  # what I change and q holds; what q changes and I hold
            mine = changed[c]
            add(colours[c].send, q, mine[np.isin(mine, touched_q) | np.isin(mine, share_q)])
            theirs = _springs_of(order, inc_ptr, inc_spring, blocks_of(q, c), m)
            add(colours[c].recv, q, theirs[held_me[theirs]])
        if has_bound:  # the boundary springs each process reports, to the others holding them
            add(boundary.send, q, bound_me[np.isin(bound_me, touched_q) | np.isin(bound_me, share_q)])
            theirs = bound_spring[bound_owner == q]
            add(boundary.recv, q, theirs[held_me[theirs]])
        # before a sweep: the further springs' θ from the processes reporting them
        further_q = touched_q[~np.isin(touched_q, share_q)]
        add(start.send, q, further_q[spring_owner[further_q] == rank])
        add(start.recv, q, further_me[spring_owner[further_me] == q])
    bound = np.flatnonzero(bound_owner == rank) if has_bound else np.zeros(0, dtype=np.int64)
    entry_sizes = bound_ptr[bound + 1] - bound_ptr[bound]
    entries = np.repeat(bound_ptr[bound], entry_sizes) + ranges(entry_sizes)
    deg = inc_ptr[nodes + 1] - inc_ptr[nodes]
    block_sizes = order.block_ptr[blocks + 1] - order.block_ptr[blocks]
    return HeatShare(springs, np.searchsorted(blocks, order.colour_ptr).astype(np.int64),
                     np.concatenate([[0], np.cumsum(block_sizes)]).astype(np.int64), nodes, incidence,
                     np.concatenate([[0], np.cumsum(deg)]).astype(np.int64),
                     np.ascontiguousarray(local[inc_spring[incidence]], dtype=np.uint32),
                     bound, entries, start, colours, boundary)
