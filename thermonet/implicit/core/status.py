"""The bottom of the implicit kernels, below both the start kernel (:mod:`thermonet.implicit.core.start`) and
the kernels' registry and shared helpers (:mod:`thermonet.implicit.core.schemes`, which re-exports these names):
the springs per block of a spring pass, the status codes a residual or finish kernel returns, and
the two branch-free helpers every spring pass uses.
"""

from __future__ import annotations

import math

from numba import njit

#: springs per block of a spring pass (as the explicit kernel's)
BLOCK = 512

OK, COLLAPSED, NO_TEMPERATURE, NOT_FINITE = 0, 1, 2, 3
STATUS_TEXT = {
    COLLAPSED: "spring collapsed (length not positive or not finite)",
    NO_TEMPERATURE: "no positive finite temperature solves the spring's thermal equations",
    NOT_FINITE: "non-finite momentum or entropy after the step",
}


@njit(cache=True, inline="always")
def _admissible(t):
    """Positive and finite, written without branches (for the vectorized loops)."""
    return (t > 0.0) & (t < math.inf)


@njit(cache=True, inline="always")
def _first_flagged(flag, lo, n, none):
    """The smallest index lo ≤ e < lo + n with flag[e] != 0, else ``none``."""
    for i in range(n):
        if flag[lo + i] != 0:
            return lo + i
    return none
