"""The conduction graph of a net: which springs exchange heat, through which conductance.

Nodes are heat junctions without heat capacity (docs/theory.md §5.1). Eliminating junction i (a
star–mesh transform, exact because it holds no heat) couples every pair of springs e ≠ f meeting
at i with ``κ_ef = g_e g_f / G_i``, ``G_i = Σ_{s at i} g_s``, summed over the nodes e and f share.
A node held at a bath temperature is not eliminated: each spring touching it exchanges with the
bath through its own g (:func:`bath_ends`).

Conduction is swept junction by junction (:mod:`thermonet.heat.exchange`) in the order of a
:class:`StarOrder` (:func:`star_order`): the junction nodes cut into blocks, the blocks coloured
so that no two blocks of one colour share a spring. A colour's blocks run in parallel, each
block's nodes one after the other, so the result does not depend on the thread count. The
thermal waves' pairs are coloured the same way (:func:`colour_pairs`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit


class PairGraph(NamedTuple):
    """Spring pairs sorted by colour.

    first, second: (P,) int32 springs of each pair (first < second); kappa: (P,) conductance of
    each pair for the weights it was built from (one column per weight: (P, W));
    colour_ptr: (C+1,) int64, colour c is pairs colour_ptr[c]:colour_ptr[c+1].
    """

    first: np.ndarray
    second: np.ndarray
    kappa: np.ndarray
    colour_ptr: np.ndarray

    @property
    def n_pairs(self) -> int:
        return len(self.first)

    @property
    def n_colours(self) -> int:
        return len(self.colour_ptr) - 1


@njit(cache=True)
def _count_pairs(inc_ptr, inc_spring, weight_sum, skip):
    total = 0
    for i in range(len(inc_ptr) - 1):
        if skip[i] or weight_sum[i] <= 0.0:
            continue
        d = inc_ptr[i + 1] - inc_ptr[i]
        total += d * (d - 1) // 2
    return total


@njit(cache=True)
def _junction_pairs(inc_ptr, inc_spring, weights, weight_sum, skip, first, second, kappa):
    """Every pair of springs at each eliminated junction, with g_e g_f / G_i per weight column."""
    k = 0
    G = np.empty(weights.shape[0])
    for i in range(len(inc_ptr) - 1):
        if skip[i] or weight_sum[i] <= 0.0:
            continue
        lo = inc_ptr[i]
        hi = inc_ptr[i + 1]
        for w in range(weights.shape[0]):
            total = 0.0
            for s in range(lo, hi):
                total += weights[w, inc_spring[s]]
            G[w] = total
        for u in range(lo, hi):
            for v in range(u + 1, hi):
                e = inc_spring[u]
                f = inc_spring[v]
                first[k] = min(e, f)
                second[k] = max(e, f)
                for w in range(weights.shape[0]):
                    kappa[k, w] = weights[w, e] * weights[w, f] / G[w] if G[w] > 0.0 else 0.0
                k += 1
    return k


@njit(cache=True)
def _greedy_colours(first, second, n_springs):
    """The smallest colour free at both springs, pair by pair (at most 2Δ − 1 colours for a
    spring pair degree Δ). Colours of each spring kept as bit masks of 64 colours per word, as
    many words as the pair of largest degree sum can need (fewer than deg e + deg f colours are
    taken at its springs when it is coloured), made before the loop: the masks grown in the loop
    (an array rebound there) took Numba 4× as long to compile."""
    n = len(first)
    degree = np.zeros(n_springs, dtype=np.int64)
    for k in range(n):
        degree[first[k]] += 1
        degree[second[k]] += 1
    most = 1
    for k in range(n):
        most = max(most, degree[first[k]] + degree[second[k]] - 1)
    colour = np.empty(n, dtype=np.int64)
    used = np.zeros((n_springs, (most + 63) // 64), dtype=np.uint64)
    for k in range(n):
        e = first[k]
        f = second[k]
        w = 0
        free = ~(used[e, 0] | used[f, 0])
        while free == 0:
            w += 1
            free = ~(used[e, w] | used[f, w])
        bit = 0
        while (free >> np.uint64(bit)) & np.uint64(1) == 0:
            bit += 1
        mask = np.uint64(1) << np.uint64(bit)
        used[e, w] |= mask
        used[f, w] |= mask
        colour[k] = 64 * w + bit
    return colour


def colour_pairs(first: np.ndarray, second: np.ndarray, n_springs: int) -> np.ndarray:
    """(P,) int64 colour of each pair: no two pairs of one colour share a spring."""
    if len(first) == 0:
        return np.empty(0, dtype=np.int64)
    return _greedy_colours(first.astype(np.int64), second.astype(np.int64), int(n_springs))


def pair_graph(layout, weights: np.ndarray, junction: np.ndarray | None = None) -> PairGraph:
    """The coloured spring pairs of the junctions of ``layout`` (internal numbering).

    weights: (W, m) per-spring conductances (g, and g* for thermal waves; a pair is kept when any
    column couples it); junction: (n,) bool, the nodes to eliminate (default all; bath nodes are
    not junctions). Pairs meeting at several junctions (parallel springs) are merged, their κ
    summed.
    """
    weights = np.ascontiguousarray(np.atleast_2d(weights), dtype=np.float64)
    n, m = layout.n_nodes, layout.n_springs
    skip = np.zeros(n, dtype=np.bool_) if junction is None else ~np.asarray(junction, dtype=np.bool_)
    inc_ptr = layout.inc_ptr.astype(np.int64)
    inc_spring = layout.inc_spring.astype(np.int64)
    node_of = np.repeat(np.arange(n), np.diff(inc_ptr))
    weight_sum = np.zeros(n)
    np.add.at(weight_sum, node_of, weights.sum(axis=0)[inc_spring])
    total = _count_pairs(inc_ptr, inc_spring, weight_sum, skip)
    first = np.empty(total, dtype=np.int64)
    second = np.empty(total, dtype=np.int64)
    kappa = np.empty((total, weights.shape[0]))
    _junction_pairs(inc_ptr, inc_spring, weights, weight_sum, skip, first, second, kappa)
    keep = kappa.max(axis=1, initial=0.0) > 0.0
    first, second, kappa = first[keep], second[keep], kappa[keep]
    key = first * m + second
    order = np.argsort(key, kind="stable")
    key, first, second, kappa = key[order], first[order], second[order], kappa[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]]) if len(key) else np.empty(0, dtype=np.int64)
    if len(starts) < len(key):
        kappa = np.add.reduceat(kappa, starts, axis=0)
        first, second = first[starts], second[starts]
    colour = colour_pairs(first, second, m)
    order = np.argsort(colour, kind="stable")
    n_colours = int(colour.max()) + 1 if len(colour) else 0
    colour_ptr = np.zeros(n_colours + 1, dtype=np.int64)
    colour_ptr[1:] = np.cumsum(np.bincount(colour, minlength=n_colours))
    return PairGraph(np.ascontiguousarray(first[order], dtype=np.int32), np.ascontiguousarray(second[order], dtype=np.int32),
                     np.ascontiguousarray(kappa[order]), colour_ptr)


def bath_ends(layout, bath_of_node: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(spring, bath) of every spring end on a bath node, sorted by spring: (B,) int64 each.
    bath_of_node: (n,) int64, the bath holding each node (−1: none)."""
    edges = layout.edges.astype(np.int64)
    springs, ends = np.nonzero(bath_of_node[edges] >= 0)
    return springs.astype(np.int64), bath_of_node[edges[springs, ends]].astype(np.int64)


def pairs_per_spring(graph: PairGraph, n_springs: int) -> float:
    """Mean number of pairs a spring belongs to (2 P / m)."""
    return 2.0 * graph.n_pairs / max(n_springs, 1)


class StarOrder(NamedTuple):
    """The order of a conduction sweep: colour c is blocks colour_ptr[c]:colour_ptr[c+1]
    ((C+1,) int64); block b is the nodes node[block_ptr[b]:block_ptr[b+1]] ((B+1,), (N,) int64),
    swept in that order. No two blocks of one colour share a spring."""

    colour_ptr: np.ndarray
    block_ptr: np.ndarray
    node: np.ndarray

    @property
    def n_colours(self) -> int:
        return len(self.colour_ptr) - 1

    @property
    def n_blocks(self) -> int:
        return len(self.block_ptr) - 1


@njit(cache=True)
def _colour_blocks(inc_ptr, inc_other, block_of, block_ptr, nodes):
    """Greedy colours of the blocks, in block order: the smallest colour no block that shares a
    spring with it has (blocks meet where a spring joins their nodes)."""
    n_blocks = block_ptr.shape[0] - 1
    colour = np.full(n_blocks, -1, dtype=np.int64)
    seen = np.full(n_blocks + 1, -1, dtype=np.int64)  # seen[c] == b: colour c is taken next to b
    for b in range(n_blocks):
        for k in range(block_ptr[b], block_ptr[b + 1]):
            a = nodes[k]
            for j in range(inc_ptr[a], inc_ptr[a + 1]):
                other = block_of[inc_other[j]]
                if other >= 0 and other != b and colour[other] >= 0:
                    seen[colour[other]] = b
        c = 0
        while seen[c] == b:
            c += 1
        colour[b] = c
    return colour


def star_order(layout, g: np.ndarray, junction: np.ndarray, block_nodes: int | None) -> StarOrder:
    """The sweep order of the junction nodes of ``layout`` (internal numbering).

    g: (m,) conductances; junction: (n,) bool, the nodes that are junctions (bath nodes are not);
    only junctions with two or more conducting springs exchange anything and are kept.
    block_nodes: nodes per block, as index ranges of the internal numbering (renumbered for
    locality, so a block is a compact piece of the net and its springs lie close in memory);
    None: the net's bandwidth (the largest index difference across a spring, at least 64), so
    that a block meets only its two neighbours and two colours suffice — the CPU's order; 1:
    one node per block, nodes coloured greedily — the GPU's order (many short tasks).
    """
    inc_ptr = np.asarray(layout.inc_ptr, dtype=np.int64)
    inc_spring = np.asarray(layout.inc_spring, dtype=np.int64)
    inc_other = np.asarray(layout.inc_other, dtype=np.int64)
    n = len(inc_ptr) - 1
    conducting = np.zeros(n, dtype=np.int64)
    node_of = np.repeat(np.arange(n), np.diff(inc_ptr))
    np.add.at(conducting, node_of, (np.asarray(g)[inc_spring] > 0.0).astype(np.int64))
    active = np.flatnonzero(np.asarray(junction, dtype=bool) & (conducting >= 2)).astype(np.int64)
    if block_nodes is None:
        edges = np.asarray(layout.edges, dtype=np.int64)
        width = int(np.abs(edges[:, 0] - edges[:, 1]).max()) if len(edges) else 1
        block_nodes = max(width, 64)
    block_nodes = int(block_nodes)
    if block_nodes < 1:
        raise ValueError(f"block_nodes must be >= 1, got {block_nodes}")
    key = active // block_nodes
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]]) if len(active) else np.empty(0, dtype=np.int64)
    block_ptr = np.append(starts, len(active)).astype(np.int64)
    block_of = np.full(n, -1, dtype=np.int64)
    block_of[active] = np.repeat(np.arange(len(starts)), np.diff(block_ptr))
    colour = _colour_blocks(inc_ptr, inc_other, block_of, block_ptr, active)
    order = np.argsort(colour, kind="stable")
    n_colours = int(colour.max()) + 1 if len(colour) else 0
    colour_ptr = np.zeros(n_colours + 1, dtype=np.int64)
    colour_ptr[1:] = np.cumsum(np.bincount(colour, minlength=n_colours))
    sizes = np.diff(block_ptr)[order]
    new_ptr = np.zeros(len(order) + 1, dtype=np.int64)
    new_ptr[1:] = np.cumsum(sizes)
    nodes = np.concatenate([active[block_ptr[b]:block_ptr[b + 1]] for b in order]) if len(order) else active
    return StarOrder(colour_ptr, new_ptr, np.ascontiguousarray(nodes, dtype=np.int64))


def fastest_rate(layout, g: np.ndarray, capacity: np.ndarray, junction: np.ndarray) -> np.ndarray:
    """(m,) each spring's total diffusive rate ``(Σ_f κ_ef + g at bath ends) / C_e``: at each end
    that is a junction ``g_e (1 − g_e / G_i)``, at a bath end ``g_e`` (the rate of its slowest
    neighbour-free mode bound: the largest over springs bounds the conduction operator's
    spectrum within a factor 2)."""
    g = np.asarray(g, dtype=np.float64)
    edges = np.asarray(layout.edges, dtype=np.int64)
    n = layout.n_nodes
    G = np.zeros(n)
    np.add.at(G, edges[:, 0], g)
    np.add.at(G, edges[:, 1], g)
    rate = np.zeros(len(g))
    for end in (0, 1):
        node = edges[:, end]
        at_junction = np.asarray(junction, dtype=bool)[node]
        with np.errstate(invalid="ignore", divide="ignore"):
            coupling = np.where(G[node] > 0.0, g * (1.0 - g / np.where(G[node] > 0.0, G[node], 1.0)), 0.0)
        rate += np.where(at_junction, coupling, g)
    return rate / np.asarray(capacity, dtype=np.float64)
