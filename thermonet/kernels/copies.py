"""Row and value copies: templates shared by the explicit CPU kernel
(:mod:`thermonet.explicit.cpu`, which specializes ``_copy_rows`` per kernel variant) and the
compiled Newton driver of the implicit schemes."""

from __future__ import annotations

from numba import njit, prange


def _copy_rows(source, target):
    """target[:] = source for (n, 3) arrays, rows in parallel."""
    for a in prange(source.shape[0]):
        target[a, 0] = source[a, 0]
        target[a, 1] = source[a, 1]
        target[a, 2] = source[a, 2]


@njit(inline="always", error_model="numpy", boundscheck=False)
def _copy_values(source, target):
    """target[:] = source for (m,) arrays."""
    for e in range(source.shape[0]):
        target[e] = source[e]
