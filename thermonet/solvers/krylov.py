"""GMRES on the assembled Newton matrix (``linear_solver="gmres"``) with a nodal block-Jacobi
preconditioner. It spends its time filling and reading a matrix of B² entries per spring-block;
the matrix-free solver (:mod:`.matrix_free`) does the same work without the matrix.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .pattern import BlockPattern


class Krylov:
    """SciPy GMRES with a nodal block-Jacobi preconditioner (the inverses of the diagonal B×B
    blocks, which carry the dominant inertia M/h). Converges in a few iterations for steps
    below the explicit stability limit; costs O(nnz) per iteration at any net size."""

    name = "gmres"
    assembled = True

    def __init__(self, pattern: BlockPattern, problem=None, rtol: float = 1e-10, maxiter: int = 200):
        self.pattern = pattern
        self.rtol = rtol
        self.maxiter = maxiter
        B = pattern.block
        rows = pattern.node_base[:, None, None] + np.arange(B)[None, :, None] * pattern.node_stride[:, None, None]
        self._diag_index = rows + np.arange(B)[None, None, :]  # (n_free, B, B) data indices
        self._A = None
        self._M = None
        self.iterations = 0

    def factorize(self, data: np.ndarray) -> None:
        p = self.pattern
        self._A = sp.csr_matrix((data, p.indices, p.indptr), shape=(p.size, p.size))
        inv = np.linalg.inv(data[self._diag_index])
        B = p.block
        blocks = sp.bsr_matrix((inv, np.arange(p.n_free), np.arange(p.n_free + 1)),
                               shape=(p.size, p.size), blocksize=(B, B))
        self._M = blocks

    def solve(self, rhs: np.ndarray, target: float = 0.0, settled: float = 0.0) -> np.ndarray:
        count = [0]

        def callback(_):
            count[0] += 1

        x, info = spla.gmres(self._A, rhs, M=self._M, rtol=self.rtol, atol=0.0, restart=50,
                             maxiter=self.maxiter, callback=callback, callback_type="pr_norm")
        self.iterations += count[0]
        return x
