"""The blocked spring pass's shared pieces: every pass over the springs in blocks (the explicit
CPU kernel's spring pass, the diagnostics sums, the output fields) gathers a block's squared
lengths in one scalar loop and does its arithmetic in a second, vectorized one."""

from __future__ import annotations

import numpy as np
from numba import njit

from . import subflows

#: springs per block of the spring pass: small enough that a block of s, η, l0, Φ stays in L1
BLOCK = 512

_squared_length = njit(inline="always", error_model="numpy", boundscheck=False)(subflows.squared_length)


@njit(inline="always", error_model="numpy", boundscheck=False)
def squared_lengths(x, edges, lo, n, out, base):
    """out[base + i] = |x_b − x_a|² of springs lo … lo + n − 1: the gather half of a blocked
    spring pass (kept apart from the arithmetic so that the arithmetic loop vectorizes).
    edges: (m, 2) uint32."""
    for i in range(n):
        out[base + i] = _squared_length(x, edges, np.uint64(lo + i))
