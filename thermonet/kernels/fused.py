"""One pass over memory per explicit stage: the spring pass and the node pass of a kick–drift
stage fused, for the layouts :func:`sweep_layout` accepts (every renumbered one).

A stage done as two passes (:mod:`thermonet.kernels.splitting`) writes T/l of every spring to
memory and reads it back in the node pass, and reads the positions twice. Here one sweep in the
internal node order does both: per block of ``SWEEP_BLOCK`` springs, the spring half (the
two-pass kernel's blocked loops: a scalar loop gathering |x_b − x_a|², then the vectorized loop
for l, θ, T/l and Φ) writes T/l into a ring of ``R`` springs that stays in cache; then every node
whose springs are all done gets its force, kick and drift (into the other position buffer, so
the old positions stay readable). Springs are sorted by their lower node, so node a's springs
all lie below ``first_spring[a + 1]``: nodes complete in order, at most ``W + SWEEP_BLOCK``
springs behind the sweep (``W``: :func:`sweep_layout`), which the ring covers. Blocks are long
(the alternation between the two halves costs cache and prefetch misses: blocks of 512 springs
cost about 30 % more time on one core than the two passes, blocks of 32 768 about the same).

Threads take contiguous ranges of nodes (chunks, balanced by springs) and the springs whose lower
node is theirs. A node with a spring of an earlier chunk (*deferred*: only nodes within ``Wn`` of
the chunk's start) waits for a second parallel loop; the springs it needs lie within ``W`` of its
chunk's start, so every chunk also writes the T/l of its first and last ``W`` springs to the full
(m,) array (all of them when a chunk is shorter than ``W``), from which the deferred nodes read.
Every T/l, force sum, kick and drift is the two-pass kernel's computation, the same operations in
the same order: results are bit for bit those of the two passes, whatever the number of threads.
The ring lives in ``scratch.s`` beyond its first m entries (``R`` per thread).
"""

from __future__ import annotations

import hashlib
import inspect
import math
import sys

import numpy as np
from numba import njit, prange

from . import subflows
from .specialize import rebind, specialize

#: springs per block of the two-pass kernel's spring pass: a block of s, η, l0, Φ stays in L1
BLOCK = 512
#: springs per block of the one-sweep stage (module doc)
SWEEP_BLOCK = 32768

# bound per kernel variant by thermonet.kernels.splitting.splitting_kernels()
spring_force = outside_admissible = advance_thermal_displacement = kick_momentum = drift_position = None
load_row = store_row = None
THERMAL = True
UNIFORM = False
PARALLEL = True

_squared_length = njit(inline="always", error_model="numpy", boundscheck=False)(subflows.squared_length)


@njit(inline="always", error_model="numpy", boundscheck=False)
def squared_lengths(x, edges, lo, n, out, base):
    """out[base + i] = |x_b − x_a|² of springs lo … lo + n − 1: the gather half of a blocked
    spring pass (kept apart from the arithmetic so that the arithmetic loop vectorizes).
    edges: (m, 2) uint32."""
    for i in range(n):
        out[base + i] = _squared_length(x, edges, np.uint64(lo + i))


def source_digest() -> str:
    """A short hash of this module's source, for the kernels' cache names (as
    :func:`thermonet.kernels.subflows.source_digest`)."""
    return hashlib.sha256(inspect.getsource(sys.modules[__name__]).encode()).hexdigest()[:8]


def bind_fused(ns: dict, tag: str, compile_, parallel: bool, options: dict) -> None:
    """Bind ``fused_stage`` (the one-sweep stage) into the kernel namespace ``ns`` (which holds
    the model, the constants and the sub-flows), its helpers compiled by ``compile_``."""
    own = dict(ns, PARALLEL=bool(parallel))
    for fn in (chunk_start, masked_force, node_stage):
        own[fn.__name__] = compile_(rebind(fn, tag, own))
    ns["fused_stage"] = specialize(_fused_stage, tag, own, parallel=parallel, **options)


def sweep_layout(edges: np.ndarray, inc_ptr: np.ndarray, inc_spring: np.ndarray, inc_other: np.ndarray):
    """(first_spring (n+1,) int64, sweep (4,) int64) of a layout: first_spring[a] is the first
    spring whose first (lower) node is a; sweep = (W, Wn, R, R − 1) with W = max over nodes of
    (first_spring[a+1] − the node's lowest spring), Wn the largest node distance of a spring and R
    the ring length (a power of two ≥ W + SWEEP_BLOCK, or ≥ m); R = 0 where the layout cannot be
    swept (springs not sorted by their lower node, incidence lists not in spring order)."""
    n, m = len(inc_ptr) - 1, len(edges)
    first = np.zeros(n + 1, dtype=np.int64)
    sweep = np.zeros(4, dtype=np.int64)
    if m == 0 or n == 0:
        return first, sweep
    counts = np.diff(inc_ptr)
    node = np.repeat(np.arange(n), counts)
    upper = inc_other.astype(np.int64) > node
    same = node[:-1] == node[1:]
    if np.any(upper[:-1] & ~upper[1:] & same) or int(upper.sum()) != m:
        return first, sweep
    if not np.array_equal(inc_spring[upper].astype(np.int64), np.arange(m)):
        return first, sweep
    np.cumsum(np.bincount(node[upper], minlength=n), out=first[1:])
    has = counts > 0
    lowest = inc_spring[inc_ptr[:-1][has]].astype(np.int64)
    w = int(np.max(first[1:][has] - lowest))
    wn = int(np.max(np.abs(edges[:, 1].astype(np.int64) - edges[:, 0])))
    r = 1 << int(math.ceil(math.log2(min(w + SWEEP_BLOCK, m))))  # (R ≥ m: the ring never wraps)
    sweep[:] = (w, wn, r, r - 1)
    return first, sweep


def ring_slots(sweep: np.ndarray, threads: int) -> int:
    """Entries of ``scratch.s`` beyond m the sweep needs for ``threads`` threads (0: the layout
    cannot be swept)."""
    r = int(sweep[2])
    return 0 if r == 0 else threads * r


def chunk_start(t, chunks, first_spring):
    """First node of chunk t of ``chunks`` (balanced by springs; chunks == t gives n)."""
    n = first_spring.shape[0] - 1
    if t >= chunks:
        return n
    return np.searchsorted(first_spring, first_spring[n] * t // chunks)


def masked_force(a, x, s, mask, inc_ptr, inc_spring, inc_other, masses, gravity, with_gravity):
    """:func:`thermonet.kernels.subflows.gather_force` with T/l of spring e at s[e & mask] (a
    ring of mask + 1 springs, or all ones: the full array): the same sum in the same order."""
    xa0 = x[a, 0]
    xa1 = x[a, 1]
    xa2 = x[a, 2]
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    for j in range(inc_ptr[a], inc_ptr[a + 1]):
        ju = np.uint64(j)
        se = s[np.uint64(inc_spring[ju]) & mask]
        b = inc_other[ju]
        f0 += se * (x[b, 0] - xa0)
        f1 += se * (x[b, 1] - xa1)
        f2 += se * (x[b, 2] - xa2)
    if with_gravity:
        f0 += masses[a] * gravity[0]
        f1 += masses[a] * gravity[1]
        f2 += masses[a] * gravity[2]
    return f0, f1, f2


def node_stage(a, cur, nxt, p, s, mask, topology, nodes, steps):
    """The node half of a stage for node a (as the two-pass kernel's node pass with force_source
    0): f from s (s[e & mask]), p += kick1 f, += kick2 f, nxt[a] = cur[a] + drift p / m."""
    kick1, kick2, drift = steps
    xa0, xa1, xa2 = load_row(cur, a)
    if nodes.anchored[a]:
        store_row(nxt, a, xa0, xa1, xa2)
        return
    p0, p1, p2 = load_row(p, a)
    f0, f1, f2 = masked_force(a, cur, s, mask, topology.inc_ptr, topology.inc_spring, topology.inc_other,
                              nodes.masses, nodes.gravity, nodes.with_gravity)
    p0, p1, p2 = kick_momentum(p0, p1, p2, f0, f1, f2, kick1, kick2)
    store_row(p, a, p0, p1, p2)
    drift_position(nxt, a, xa0, xa1, xa2, p0, p1, p2, drift * nodes.inv_mass[a])


def _fused_stage(cur, nxt, state, topology, springs, nodes, scratch, steps, run):
    """One stage (kick of steps[0] + steps[1], drift of steps[2]; fractions of h times h) as one
    sweep (module doc): Φ updated, p kicked, the drifted positions in nxt. Returns the number of
    springs outside the admissible states, or −1 when the layout or the buffers do not allow a
    sweep (the caller runs the two passes)."""
    inc_ptr = topology.inc_ptr
    inc_spring = topology.inc_spring
    edges = topology.edges
    first_spring = topology.first_spring
    w = topology.sweep[0]
    wn = topology.sweep[1]
    r = topology.sweep[2]
    mask = np.uint64(topology.sweep[3])
    full = np.uint64(0xFFFFFFFFFFFFFFFF)
    l0 = springs.rest
    P = springs.P
    eta = state.eta
    phi = state.phi
    p = state.p
    s = scratch.s
    m = first_spring[first_spring.shape[0] - 1]
    n = cur.shape[0]
    if r == 0 or m == 0 or first_spring.shape[0] != n + 1:
        return -1
    chunks = min(run.threads if PARALLEL else 1, (s.shape[0] - m) // r)
    if chunks < 1:
        return -1
    kick1, kick2, drift = steps
    track_phi = THERMAL and run.track_phi
    stretch_min = run.stretch_min
    stretch_max = run.stretch_max
    keep_all = False  # a chunk shorter than W: every T/l to the full array
    for t in range(chunks):
        if first_spring[chunk_start(t + 1, chunks, first_spring)] - first_spring[chunk_start(t, chunks, first_spring)] < w:
            keep_all = True
    bad = 0
    for t in prange(chunks):
        n0 = chunk_start(t, chunks, first_spring)
        n1 = chunk_start(t + 1, chunks, first_spring)
        e0 = first_spring[n0]
        e1 = first_spring[n1]
        ring = s[m + t * r:m + (t + 1) * r]
        na = n0  # the next node to move
        lo = e0
        while True:
            hi = min((lo // SWEEP_BLOCK + 1) * SWEEP_BLOCK, e1)
            cnt = hi - lo
            off = np.uint64(lo) & mask
            squared_lengths(cur, edges, lo, cnt, ring, off)
            for i in range(cnt):
                e = np.uint64(lo + i)
                k = off + np.uint64(i)
                c = np.uint64(0) if UNIFORM else e
                length = math.sqrt(ring[k])
                rest = l0[e]
                theta, force = spring_force(length, eta[e] if THERMAL else 0.0, rest, P, c)
                ring[k] = force
                bad += outside_admissible(length, rest, force, theta, stretch_min, stretch_max)
                if track_phi:
                    advance_thermal_displacement(phi, e, theta, kick1, kick2)
            if cnt > 0 and chunks > 1 and (keep_all or (t > 0 and lo < e0 + w) or (t < chunks - 1 and hi > e1 - w)):
                for i in range(cnt):
                    s[lo + i] = ring[off + np.uint64(i)]
            # the nodes whose springs are all done: those with first_spring[a + 1] <= hi
            nb = n1 if hi >= e1 else min(n1, np.searchsorted(first_spring, hi, side="right") - 1)
            for a in range(na, nb):
                if a <= n0 + wn and inc_ptr[a + 1] > inc_ptr[a] and inc_spring[np.uint64(inc_ptr[a])] < e0:
                    continue  # a spring of an earlier chunk: deferred
                node_stage(a, cur, nxt, p, ring, mask, topology, nodes, steps)
            na = max(na, nb)
            if hi >= e1:
                break
            lo = hi
    for t in prange(1, chunks):  # the deferred nodes, from the full array
        n0 = chunk_start(t, chunks, first_spring)
        e0 = first_spring[n0]
        for a in range(n0, min(chunk_start(t + 1, chunks, first_spring), n0 + wn + 1)):
            j0 = inc_ptr[a]
            if inc_ptr[a + 1] > j0 and inc_spring[np.uint64(j0)] < e0:
                node_stage(a, cur, nxt, p, s, full, topology, nodes, steps)
    return bad
