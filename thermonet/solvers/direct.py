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


class ReusedLU(SparseLU):
    """SuperLU whose factorization is kept across Newton iterations and steps (modified Newton,
    ``linear_solver="splu-reuse"``): :func:`thermonet.solvers.newton.newton` asks
    :meth:`usable` before each full iteration and, where it may, solves with the factorization
    of an earlier iterate (of this step, or of an earlier step of the same h: ``carried``)
    instead of assembling and factorizing the Jacobian at the current one. The convergence test
    is on the true residual either way, so the converged root is the same one (for EM2: the
    energy stays exact to the Newton tolerance); only the path to it changes. A reused
    factorization is dropped (the next iteration refactorizes) when the iteration it made
    reduced the scaled residual by less than REUSE_CONTRACTION. Within the step that made it,
    it is not used while the scaled residual is above REUSE_BELOW (far from the root, where a
    damped step with the matrix of an iterate far from the next would only stall); one carried
    from an earlier step is tried from the step's first iteration (the Jacobian of a slowly
    changing net moves little from step to step).

    ``point``: where the kept factorization was made, as the problem's ``jacobian_point()``
    returns it (None where the problem has none): a stepper saves it with the state and
    rebuilds the same factorization there on resume (``problem.refactorize_at(point)``), so a
    resumed run continues bit for bit."""

    name = "splu-reuse"
    reuses_factorization = True

    def __init__(self, pattern: BlockPattern, problem=None):
        super().__init__(pattern, problem)
        self.problem = problem
        self.h = None  # the step of the factorized matrix (its inertia blocks are m/h)
        self.stale = True
        self.carried = False  # made in an earlier step (new_step)
        self.point = None
        self.factorizations = 0
        self.reuses = 0

    def factorize(self, data: np.ndarray, h: float | None = None) -> None:
        super().factorize(data)
        self.h = h
        self.stale = False
        self.carried = False
        point = getattr(self.problem, "jacobian_point", None)
        self.point = point() if point is not None else None
        self.factorizations += 1

    def new_step(self) -> None:
        """A new step starts: a kept factorization is now an earlier step's."""
        self.carried = True

    def usable(self, h: float, rho: float, below: float) -> bool:
        """Whether the kept factorization may make the next correction at step h, scaled
        residual rho (≤ ``below``, or any where the factorization was carried from an earlier
        step)."""
        return self._lu is not None and not self.stale and self.h == h and (rho <= below or self.carried)
