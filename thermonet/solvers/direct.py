"""The direct linear solver of a Newton step (``linear_solver="splu"``): SciPy's SuperLU. The
fill-reducing ordering is computed once (minimum degree on AᵀA + A of the node graph) and baked
into the pattern (:mod:`.pattern`), so each factorization runs with the NATURAL ordering and
skips the ordering phase; pivoting prefers the (dominant) diagonal. For small nets: a 3D net's
factorization fills in superlinearly.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .pattern import BlockPattern


class SparseLU:
    """SuperLU on the pattern's (already fill-reduced) ordering. ``assembled``: it needs the
    CSR values (``factorize(data)``); ``solve(rhs, target)`` ignores the target (exact).

    The kernels fill a CSR matrix A; its arrays read as CSC are Aᵀ, which is factorized without
    copying, and A x = b is solved as the transposed system."""

    name = "splu"
    assembled = True

    def __init__(self, pattern: BlockPattern, problem=None):
        self.pattern = pattern
        self._lu = None

    def factorize(self, data: np.ndarray) -> None:
        p = self.pattern
        At = sp.csc_matrix((data, p.indices, p.indptr), shape=(p.size, p.size))
        self._lu = spla.splu(At, permc_spec="NATURAL", diag_pivot_thresh=0.1,
                             options=dict(SymmetricMode=True))

    def solve(self, rhs: np.ndarray, target: float = 0.0, settled: float = 0.0) -> np.ndarray:
        return self._lu.solve(rhs, trans="T")
