"""The reductions of one diagnostics row, as exactly rounded sums (:mod:`.exact`): each sum is
accumulated without rounding and rounded once, so its bits do not depend on how the springs and
nodes are split among threads or processes, nor on the order they come in. A process of a
distributed run reduces its own springs and nodes, the processes' accumulators are added as
integers, and the row is the one process's to the last bit.

The springs' energies are evaluated per model (:func:`diagnostic_sums_kernel`) into an array
that the exact sum then reads, so that the exact accumulation is compiled once for every model.
Each exact sum works in at most ``CHUNKS`` chunks of whole blocks of ``BLOCK`` terms (parallel over
chunks when compiled so), each chunk into its own accumulator, added up at the end; the chunks
only split the work (an accumulator holds up to 2^30 terms: nets of up to 6e10 springs).
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import math
import sys

import numpy as np
from numba import njit, prange

from . import exact, subflows
from .subflows import bind_subflows
from .blocks import BLOCK, squared_lengths
from .exact import WIDTH, add_block, add_terms, normalize
from .specialize import function_fingerprint, kernel_namespace, model_fingerprint, specialize, specialize_by_content

# Bound per model by specialize(); see thermonet.explicit.cpu for THERMAL / REFERENCE_TEMPERATURE /
# UNIFORM.
spring_temperature = spring_energy = None
spring_energies_block = row_sums_chunk = None  # (bound by the kernel factories below)
THERMAL = True
REFERENCE_TEMPERATURE = 0
UNIFORM = False

#: the most chunks a reduction is cut into (each with its own accumulator of 552 bytes)
CHUNKS = 64
#: the node sums, in the order of their accumulators: kinetic energy, gravity potential, p, L
NODE_SUMS = ("kinetic", "potential", "px", "py", "pz", "Lx", "Ly", "Lz")
#: a row's accumulators: Σ U, Σ η, then the node sums
ROW_SUMS = 2 + len(NODE_SUMS)

_CACHE: dict = {}
#: in the exact sums' names: a change to the exact accumulation is a new kernel (Numba's disk
#: cache watches this module's file, not the functions it inlines from another)
_EXACT = function_fingerprint(add_block.py_func, add_terms.py_func, normalize.py_func)


#: the fewest blocks of a chunk (fewer, larger chunks for small nets: each costs an accumulator
#: zeroed, normalized and added)
CHUNK_BLOCKS = 8


@njit(inline="always")
def chunk_length(k):
    """Terms per chunk of a reduction over k terms: whole blocks, at least CHUNK_BLOCKS of them
    and at most CHUNKS chunks."""
    blocks = (k + BLOCK - 1) // BLOCK
    return max(CHUNK_BLOCKS, (blocks + CHUNKS - 1) // CHUNKS) * BLOCK


@functools.lru_cache(maxsize=1)
def rows_digest() -> str:
    """A short hash of the exact sums' and this module's sources: part of the cache names of the
    stepping kernels, which inline their chunking and accumulation (Numba's disk cache watches
    the kernel's own file only, and a chunking constant changed here must not meet scratch sized
    by the old one)."""
    text = inspect.getsource(exact) + inspect.getsource(sys.modules[__name__])
    return hashlib.sha256(text.encode()).hexdigest()[:8]


def closing_chunks(n: int) -> int:
    """The chunks of a reduction over n terms (at least 1): a closing node pass's accumulators."""
    per_chunk = max(CHUNK_BLOCKS, -(-(-(-n // BLOCK)) // CHUNKS)) * BLOCK  # chunk_length(n)
    return max(1, -(-n // per_chunk))


@njit(inline="always", error_model="numpy", boundscheck=False)
def node_diagnostic_terms(x0, x1, x2, p0, p1, p2, mass, gravity, ref):
    """One free node's terms of a diagnostics row: kinetic energy, gravity potential −m g·x, p,
    and (x − ref) × p (shared by the fused closing kick and the stand-alone reduction)."""
    r0 = x0 - ref[0]
    r1 = x1 - ref[1]
    r2 = x2 - ref[2]
    return (0.5 * (p0 * p0 + p1 * p1 + p2 * p2) / mass,
            -(mass * (gravity[0] * x0 + gravity[1] * x1 + gravity[2] * x2)),
            r1 * p2 - r2 * p1, r2 * p0 - r0 * p2, r0 * p1 - r1 * p0)


def diagnostic_sums_kernel(model, thermal: bool, parallel: bool, uniform: bool = False):
    """``spring_energies(x, eta, l0, P, edges_uint32, energy) -> (θ_min, θ_max)``: each spring's
    U into energy (m,) (what :func:`row_sums_kernel`'s sums then take), the range of θ; P a
    shared (k, 1) column when ``uniform`` (as the stepping kernels read it). The one reduction
    compiled per model: the exact sums are compiled once, apart."""
    key = (model_fingerprint(model), bool(thermal), bool(parallel), bool(uniform))
    if key not in _CACHE:
        ns = kernel_namespace(model, thermal, uniform)
        tag = (f"{model.name}_{key[0]}_{'thermal' if thermal else 'mech'}_{'par' if parallel else 'ser'}"
               f"{'_uniform' if uniform else ''}_s{subflows.source_digest()}")
        bind_subflows(ns, tag, njit(inline="always", error_model="numpy", boundscheck=False))
        # (the block function is serial, shared by the serial and the threaded kernel)
        ns["spring_energies_block"] = specialize_by_content(_spring_energies_block, tag, ns, cache=True,
                                                            error_model="numpy")
        _CACHE[key] = specialize(_spring_energies, tag, ns, cache=True, error_model="numpy", parallel=bool(parallel))
    return _CACHE[key]


def _spring_energies(x, eta, l0, P, edges, energy):
    """energy[e] = U(l_e, η_e) (F(l_e, θ0) when not THERMAL); returns min and max of θ_e.

    edges: (m, 2) uint32; energy: (m,). Blocked like the stepping kernel's spring pass: gather the
    squared lengths of a block, evaluate θ and U in a loop over contiguous arrays (which
    vectorizes), then the block's range.
    """
    m = edges.shape[0]
    theta_min = math.inf
    theta_max = -math.inf
    for blk in prange((m + BLOCK - 1) // BLOCK):  # (the body one call of a serial function: see
        # explicit.cpu._spring_pass)
        lo = np.int64(blk) * BLOCK
        block_min, block_max = spring_energies_block(x, eta, l0, P, edges, energy, lo, min(BLOCK, m - lo))
        theta_min = min(theta_min, block_min)
        theta_max = max(theta_max, block_max)
    return theta_min, theta_max


def _spring_energies_block(x, eta, l0, P, edges, energy, lo, n):
    """Springs lo … lo + n − 1 of :func:`_spring_energies`; returns their range of θ."""
    length = np.empty(BLOCK)
    theta = np.empty(BLOCK)
    squared_lengths(x, edges, lo, n, length, 0)
    for i in range(n):
        e = np.uint64(lo + i)
        k = np.uint64(0) if UNIFORM else e
        l = math.sqrt(length[i])
        eta_e = eta[e] if THERMAL else 0.0
        th = spring_temperature(l, eta_e, l0[e], P, k)
        theta[i] = th
        energy[e] = spring_energy(l, eta_e, th, l0[e], P, k)
    block_min = math.inf
    block_max = -math.inf
    for i in range(n):
        block_min = min(block_min, theta[i])
        block_max = max(block_max, theta[i])
    return block_min, block_max


def _row_sums(x, p, masses, anchored, ref, gravity, energy, eta, counted):
    """Accumulators (ROW_SUMS, WIDTH) int64 of a row: Σ energy and Σ η over the counted springs
    (``counted`` (m,) uint8, or (0,): every spring; η (0,) without thermal coupling: no sum),
    then over the free nodes the kinetic energy, the gravity potential −Σ m g·x, Σ p and
    Σ (x − ref) × p (NODE_SUMS order). x, p: (n, 3); masses: (n,); anchored: (n,) bool (a node
    held still counts for nothing); energy: (m,). One parallel loop over the springs' chunks and
    then the nodes' (one loop compiles once)."""
    m = energy.shape[0]
    n = x.shape[0]
    every = counted.shape[0] == 0
    thermal = eta.shape[0] > 0
    per_spring = chunk_length(m)
    per_node = chunk_length(n)
    spring_chunks = (m + per_spring - 1) // per_spring
    chunks = spring_chunks + (n + per_node - 1) // per_node
    accs = np.zeros((chunks, ROW_SUMS, WIDTH), dtype=np.int64)
    for c in prange(chunks):  # (the body one call of a serial function: see explicit.cpu._spring_pass)
        row_sums_chunk(np.int64(c), spring_chunks, per_spring, per_node, x, p, masses, anchored, ref, gravity, energy,
                       eta, counted, every, thermal, accs)
    total = np.zeros((ROW_SUMS, WIDTH), dtype=np.int64)
    for c in range(chunks):
        total += accs[c]
    return total


def _row_sums_chunk(c, spring_chunks, per_spring, per_node, x, p, masses, anchored, ref, gravity, energy, eta,
                    counted, every, thermal, accs):
    """Chunk c of :func:`_row_sums` into accs[c]: a chunk of springs (c < spring_chunks) or of
    nodes."""
    m = energy.shape[0]
    n = x.shape[0]
    terms = np.empty((8, BLOCK))
    rest = np.empty(BLOCK)
    if c < spring_chunks:
        for lo in range(c * per_spring, min(m, (c + 1) * per_spring), BLOCK):
            k = min(BLOCK, m - lo)
            if every:  # (read in place)
                add_block(accs[c, 0], energy[lo:], k, rest)
                if thermal:
                    add_block(accs[c, 1], eta[lo:], k, rest)
            else:
                for i in range(k):
                    skipped = not counted[lo + i]
                    terms[0, i] = 0.0 if skipped else energy[lo + i]
                    terms[1, i] = 0.0 if skipped or not thermal else eta[lo + i]
                for q in range(2 if thermal else 1):
                    add_block(accs[c, q], terms[q], k, rest)
    else:
        b = c - spring_chunks
        for lo in range(b * per_node, min(n, (b + 1) * per_node), BLOCK):
            k = min(BLOCK, n - lo)
            for i in range(k):  # (an anchor's terms are zeros, which add nothing: no branch in the loop)
                a = np.uint64(lo + i)
                p0 = p[a, 0]
                p1 = p[a, 1]
                p2 = p[a, 2]
                kin, pot, l0_, l1_, l2_ = node_diagnostic_terms(x[a, 0], x[a, 1], x[a, 2], p0, p1, p2,
                                                                masses[a], gravity, ref)
                held = anchored[a]
                j = np.uint64(i)
                terms[0, j] = 0.0 if held else kin
                terms[1, j] = 0.0 if held else pot
                terms[2, j] = 0.0 if held else p0
                terms[3, j] = 0.0 if held else p1
                terms[4, j] = 0.0 if held else p2
                terms[5, j] = 0.0 if held else l0_
                terms[6, j] = 0.0 if held else l1_
                terms[7, j] = 0.0 if held else l2_
            for q in range(8):
                add_block(accs[c, 2 + q], terms[q], k, rest)
    first, stop = (0, 2) if c < spring_chunks else (2, ROW_SUMS)  # (the accumulators it filled)
    for q in range(first, stop):
        normalize(accs[c, q])


_OPTIONS = dict(cache=True, error_model="numpy", boundscheck=False)


def row_sums_kernel(parallel: bool):
    """The compiled :func:`_row_sums` (model-independent), multi-threaded where ``parallel``."""
    key = ("row", bool(parallel))
    if key not in _CACHE:
        if "row_chunk" not in _CACHE:  # (serial: one dispatcher shared by both kernels)
            _CACHE["row_chunk"] = specialize(_row_sums_chunk, f"x{_EXACT}", {}, **_OPTIONS)
        chunk = _CACHE["row_chunk"]
        tag = f"{'par' if parallel else 'ser'}_x{_EXACT}"
        _CACHE[key] = specialize(_row_sums, tag, {"row_sums_chunk": chunk}, parallel=bool(parallel), **_OPTIONS)
    return _CACHE[key]


#: ``counted`` for a reduction over every spring
EVERY = np.zeros(0, dtype=np.uint8)
