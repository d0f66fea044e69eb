"""The matrix-free linear solver of a Newton step (``linear_solver="matfree"``): inertia-
preconditioned sweeps of matrix-free products (Numba, threaded; the schemes' ``sweep`` kernels),
with SciPy GMRES on the same product as fallback. The one for large nets.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse.linalg as spla

from .pattern import BlockPattern


class MatrixFree:
    """Inertia-preconditioned Richardson sweeps on matrix-free products (see
    :mod:`thermonet.implicit.core.schemes`), until the linear residual's max norm is below
    the target; SciPy GMRES on the same product when the sweeps stall (a step so large that
    the springs rival the inertia). Needs from the problem: ``linearize()`` (per-spring
    coefficients at the last residual's point), ``sweep(du, rhs, r, update, first) -> max|r|`` and
    ``apply_inverse_inertia(v) -> D⁻¹ v``."""

    name = "matfree"
    assembled = False
    #: sweeps allowed before GMRES takes over
    MAX_SWEEPS = 40
    #: the sweeps have stalled when a sweep reduces the residual by less than this factor
    STALL = 0.5

    def __init__(self, pattern: BlockPattern, problem):
        self.pattern = pattern
        self.problem = problem
        self._du = np.zeros(pattern.size)
        self._r = np.zeros(pattern.size)
        self._zero = np.zeros(pattern.size)
        self.iterations = 0  # sweeps, and GMRES iterations of the fallback
        self.fallbacks = 0
        #: the largest factor by which a sweep of the last solve reduced the linear residual
        #: (inf: unknown, or the sweeps stalled); what a Jacobi step may be expected to achieve
        self.contraction = math.inf

    def factorize(self, data: np.ndarray) -> None:  # nothing to factorize
        pass

    def jacobi(self, rhs: np.ndarray) -> np.ndarray:
        """D⁻¹ rhs: one sweep from du = 0, which needs no linearization (the inertia only)."""
        self.problem.sweep(self._du, rhs, self._r, True, True)
        self.iterations += 1
        return self._du

    def solve(self, rhs: np.ndarray, target: float = 0.0, settled: float = 0.0) -> np.ndarray:
        """du with max |rhs − J du| ≤ target: sweeps until the residual a sweep measures (that of
        its du before its update) is below ``target``, or until the residual its update leaves,
        estimated as that times the worst contraction seen in this solve, is below ``settled``
        (one sweep fewer once the rest of the error would be negligible anyway)."""
        du = self._du
        previous = math.inf
        worst = math.nan  # the largest reduction of a sweep in this solve (nan: none seen yet)
        for k in range(self.MAX_SWEEPS):
            # the first sweep starts from du = 0 (it neither reads du nor needs it zeroed)
            rmax = self.problem.sweep(du, rhs, self._r, True, k == 0)
            self.iterations += 1
            if k > 0:  # (previous > target ≥ 0 here)
                worst = rmax / previous if math.isnan(worst) else max(worst, rmax / previous)
            if rmax <= target or (k > 0 and rmax * worst <= settled):
                self.contraction = math.inf if math.isnan(worst) else worst
                return du
            if not math.isfinite(rmax) or rmax > self.STALL * previous:
                break
            previous = rmax
        self.contraction = math.inf
        return self._gmres(rhs, target)

    def _gmres(self, rhs: np.ndarray, target: float) -> np.ndarray:
        self.fallbacks += 1
        size = self.pattern.size
        problem, r, zero = self.problem, self._r, self._zero

        def matvec(v):
            problem.sweep(np.ascontiguousarray(v, dtype=np.float64).ravel(), zero, r, False, False)
            return -r

        A = spla.LinearOperator((size, size), matvec=matvec, dtype=np.float64)
        M = spla.LinearOperator((size, size), matvec=problem.apply_inverse_inertia, dtype=np.float64)
        count = [0]

        def callback(_):
            count[0] += 1

        x, _ = spla.gmres(A, rhs, M=M, rtol=0.0, atol=target, restart=50, maxiter=20,
                          callback=callback, callback_type="pr_norm")
        self.iterations += count[0]
        self._du[:] = x
        return self._du
