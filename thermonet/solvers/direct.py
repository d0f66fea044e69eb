"""The direct linear solver of a Newton step (``linear_solver="splu"``): SciPy's SuperLU. The
fill-reducing ordering is computed once (minimum degree on AᵀA + A of the node graph, METIS's
nested dissection on large nets) and baked into the pattern (:mod:`.pattern`), so each
factorization runs with the NATURAL ordering and skips the ordering phase; pivoting prefers
the (dominant) diagonal. For small nets: a 3D net's factorization fills in superlinearly.
"""

from __future__ import annotations

import math

import numba
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .pattern import BlockPattern
from .tree_solve import tree_factors, tree_solve


class SparseLU:
    """SuperLU on the pattern's (already fill-reduced) ordering. ``assembled``: it needs the
    CSR values (``factorize(data)``); ``solve(rhs, target)`` ignores the target (exact).

    The kernels fill a CSR matrix A; its arrays read as CSC are Aᵀ. The values are gathered
    into Aᵀ's order first (``pattern.transpose``), so that those arrays read as CSC are A and
    SuperLU solves A x = b directly (its transposed solve is the slower one)."""

    name = "splu"
    assembled = True

    def __init__(self, pattern: BlockPattern, problem=None):
        self.pattern = pattern
        self._lu = None
        #: factorize in single precision (float32 factors; :class:`ReusedLU` by default)
        self.single = False
        self._single = False  # the current factors' precision
        self._matrix = None  # (single factors) the double matrix they factorize

    def factorize(self, data: np.ndarray) -> None:
        p = self.pattern
        A = sp.csc_matrix((data[p.transpose], p.indices, p.indptr), shape=(p.size, p.size))
        self._single = single = bool(self.single)
        self._matrix = A if single else None
        self._lu = _superlu(A.astype(np.float32) if single else A)

    def solve(self, rhs: np.ndarray, target: float = 0.0, settled: float = 0.0) -> np.ndarray:
        if not self._single:
            return self._lu.solve(rhs)
        # single factors: the right-hand side scaled by a power of two (exact) into float32's
        # range, rounded to single, and the solution returned in double
        big = float(np.abs(rhs).max(initial=0.0))
        if big == 0.0 or not np.isfinite(big):
            return np.zeros_like(rhs) if big == 0.0 else np.full_like(rhs, np.nan)
        scale = 2.0 ** round(np.log2(big))
        return self._lu.solve((rhs / scale).astype(np.float32)).astype(np.float64) * scale


def _superlu(A):
    """SuperLU's factors of A (CSC, already in its fill-reducing order: see the module docstring)."""
    return spla.splu(A, permc_spec="NATURAL", diag_pivot_thresh=0.1, options=dict(SymmetricMode=True))


#: ReusedLU.contraction_limit: scaled residuals below this count as reached (EM2's floor of the
#: residual's rounding lies at 1e-10–1e-8 on parts at small strain), and the largest contraction
KEPT_FLOOR = 1e-10
KEPT_MAX_CONTRACTION = 0.9
#: a factorization worth at least this many solves is tried at any scaled residual, in the step
#: that made it too (a few line-search residuals wasted cost less than refactorizing)
KEPT_ANYWHERE_WORTH = 50.0
#: Kept factors solve on their elimination tree (:mod:`.tree_solve`: compiled threaded, its
#: subtrees on separate threads, the same bits at any thread count, so a run gives the same numbers
#: on one thread or two) on nets of TREE_MIN_UNKNOWNS unknowns or more, once the copy onto the tree
#: has paid. The first copy lays the factors out on the tree (a layout kept for later factors of the
#: same structure, which gather by it) and costs what 30–120 solves on the tree save (at 5 172
#: unknowns 46–58 ms against 0.6–1.5 ms a solve saves on one and two threads; at 47 637 unknowns
#: 1.5–2.1 s against 18–23 ms): so it waits until the run has made TREE_AFTER_SOLVES solves with
#: SuperLU's solve, over all its kept factorizations (ski rental: a run that stops sooner lost
#: at most about what the copy would have cost, one that goes on has paid for it by then). A layout
#: serves every later factorization: at 1e4× CO2's stable step each factorization lasts about 45
#: solves, and waiting for 200 solves of one factorization, as the switch first did, put none on
#: the tree there. Once laid out, each factorization goes on the tree after TREE_AFTER_LAID_OUT
#: solves: a copy by the kept layout costs what 2–8 solves save (2.4 ms at 5 172 unknowns, 0.14 s
#: at 47 637). The switch counts solves only, so where it happens is the same at any thread count
#: and in a resumed run (the counts go with a checkpoint). Where a copy is refused (SuperLU
#: pivoted off the diagonal, or the tree does not split), the count starts again.
TREE_AFTER_SOLVES = 60
TREE_MIN_UNKNOWNS = 5_000
TREE_AFTER_LAID_OUT = 6
#: Kept factors are single precision (float32) unless that fails: the residual and the
#: convergence test stay double, so the root (and EM2's exact energy) is the same; a correction
#: made with them contracts the residual about 1e-4 instead of 1e-5, and they cost 0.4–0.7× a
#: double factorization and 0.5–0.8× a double solve (they are half the bytes). A fresh single
#: factorization's first solve is checked against the double matrix: where its linear residual
#: max |b − A x| / max |b| exceeds SINGLE_MAX_LINEAR_RESIDUAL (the matrix is too ill-conditioned
#: for float32: a part free to move at steps far above the limit), or SuperLU finds the single
#: matrix singular, the solver factorizes in double from then on (and says so in the summary).
#: At 1e-2 a single correction contracts as much as two double ones at 1e-5 cost together.
#: Newton's floor test knows them (``single_factors``): a residual at its rounding floor after a
#: correction with single factors is converged, though it still fell by their contraction.
SINGLE_MAX_LINEAR_RESIDUAL = 1e-2
#: Below this many unknowns kept factors are double: a step there costs its Python and residuals
#: more than its solves, and single factors only move where Newton stops near the residual's
#: rounding floor (a single spring at h ω = 100: energy drift 1.07e-12 over 200 steps against
#: 8.9e-13 with double factors).
SINGLE_MIN_UNKNOWNS = 1000
#: A factorization carried from step to step grows stale as the net moves on from where it was made:
#: its corrections contract less and the steps take more of them (the steel part of 9 270 springs at
#: 100× the explicit limit: 2.0 a step over the first 75 steps, 3.0 by step 150, 4.0 by step 450; a
#: fresh factorization at step 400 brought them back to 2.1). So the solver counts the corrections
#: each step takes beyond the mean of the first STALE_BASELINE_STEPS steps of the factorization (not
#: counting the step that made it: the solves it made before it may differ), and once they add up to
#: STALE_SHARE × ``worth`` it refactorizes at the next step's start (ski rental: the corrections
#: lost to staleness have then cost about what a factorization costs). ``worth`` counts
#: multiply-adds; SuperLU does a factorization's in dense blocks, several times faster per operation
#: than a solve does its: on that part (worth 79) a fresh factorization made its step 41 ms longer,
#: about 14 corrections (solve, residual, line search) of the 3 ms each that an extra correction
#: took there, and 0.2 × 79 is 16.
STALE_BASELINE_STEPS = 3
STALE_SHARE = 0.2


def factorization_worth(lu) -> float:
    """What a factorization costs in solves with it, from its factors' structure (the same on
    any machine and any run): the multiply-adds of the elimination, Σ_k (column k of L below
    the diagonal) × (row k of U right of it), over those of a solve, nnz(L) + nnz(U)."""
    L, U = lu.L, lu.U
    below = np.diff(L.indptr) - 1
    right = np.bincount(U.indices, minlength=U.shape[0]) - 1
    return float(max(1.0, np.dot(below.astype(np.float64), right) / (L.nnz + U.nnz)))


class ReusedLU(SparseLU):
    """SuperLU whose factorization is kept across Newton iterations and steps (modified Newton,
    ``linear_solver="splu-reuse"``): :func:`thermonet.implicit.core.newton.newton` asks
    :meth:`usable` before each full iteration and, where it may, solves with the factorization
    of an earlier iterate (of this step, or of an earlier step of the same h: ``carried``)
    instead of assembling and factorizing the Jacobian at the current one. The convergence test
    is on the true residual either way, so the converged root is the same one (for EM2: the
    energy stays exact to the Newton tolerance); only the path to it changes. A reused
    factorization is dropped (the next iteration refactorizes) when the iteration it made
    reduced the scaled residual by less than :meth:`contraction_limit` (REUSE_CONTRACTION, or
    more where a factorization costs many solves: ``worth``). Within the step that made it, a
    factorization worth few solves is not used while the scaled residual is above REUSE_BELOW
    (far from the root, where a damped step with the matrix of an iterate far from the next
    would only stall); one carried from an earlier step is tried from the step's first
    iteration (the Jacobian of a slowly changing net moves little from step to step).

    ``point``: where the kept factorization was made, as the problem's ``jacobian_point()``
    returns it (None where the problem has none): a stepper saves it with the state and
    rebuilds the same factorization there on resume (``problem.refactorize_at(point)``), so a
    resumed run continues bit for bit."""

    name = "splu-reuse"
    reuses_factorization = True

    #: kept factors in single precision (see SINGLE_MAX_LINEAR_RESIDUAL) from SINGLE_MIN_UNKNOWNS on
    SINGLE = True

    def __init__(self, pattern: BlockPattern, problem=None):
        super().__init__(pattern, problem)
        self.single = self.SINGLE and pattern.size >= SINGLE_MIN_UNKNOWNS
        #: why the factors are double where single ones were asked for ("" while they are not)
        self.raised = ""
        self._check = False  # the next solve checks single factors against the double matrix
        self.problem = problem
        self.h = None  # the step of the factorized matrix (its inertia blocks are m/h)
        self.stale = True
        self.carried = False  # made in an earlier step (new_step)
        self.point = None
        self.worth = 1.0  # a factorization's cost in solves with it (factorization_worth)
        self._worth_of = None  # (row permutation, worth) of the last factors whose worth was read
        self.factorizations = 0
        self.reuses = 0
        self.solves = 0  # made with the kept factorization (saved with a carried one's state)
        self._tree = None  # its factors on the elimination tree (TREE_AFTER_SOLVES), or False
        self._layout = None  # where the last factors went on the tree (kept for the next ones)
        self.tree_after = TREE_AFTER_SOLVES  # (a benchmark may set these per solver)
        self.tree_after_laid_out = TREE_AFTER_LAID_OUT
        #: SuperLU solves toward the first layout (TREE_AFTER_SOLVES), and whether one was made
        self.superlu_solves = 0
        self.laid_out = False
        self.tree_min_unknowns = TREE_MIN_UNKNOWNS
        self.tree_solves = 0  # made by tree_solve, and the factorizations copied for it
        self.tree_copies = 0
        self.tree_layouts = 0  # of those, copies that laid the factors out anew
        #: how stale the kept factorization has grown (STALE_SHARE): [steps in its baseline,
        #: their corrections, the corrections beyond the baseline since, this step's so far]
        self.staleness = np.zeros(4)
        self.stale_refactorizations = 0  # refactorizations for staleness (STALE_SHARE)

    def factorize(self, data: np.ndarray, h: float | None = None) -> None:
        try:
            super().factorize(data)
        except RuntimeError as exc:  # (SuperLU: "Factor is exactly singular")
            if not self._single:
                raise
            self._raise_precision(f"SuperLU found the single-precision matrix singular ({exc})")
        self._check = self._single
        self.solves = 0
        self._tree = None
        self._read_worth()
        self.h = h
        self.stale = False
        self.carried = False
        self.staleness[:] = -1.0, 0.0, 0.0, 0.0  # (-1: the step that made it is not counted)
        point = getattr(self.problem, "jacobian_point", None)
        self.point = point() if point is not None else None
        self.factorizations += 1

    def _read_worth(self) -> None:
        """``worth`` of the current factors. Their structure follows from the pattern and the
        row pivots (but for entries that come out exactly zero): where those are the last ones',
        the last worth is taken (reading it copies the factors out of SuperLU: 2 s at 47 637
        unknowns, 0.5–0.8 s, about half what the factorization itself costs)."""
        perm = self._lu.perm_r
        if self._worth_of is None or not np.array_equal(perm, self._worth_of[0]):
            self._worth_of = (perm.copy(), factorization_worth(self._lu))
        self.worth = self._worth_of[1]

    @property
    def solves_before_tree(self) -> float:
        """The solves of the current factorization after which it goes on the elimination tree:
        TREE_AFTER_LAID_OUT once the run has laid factors out; before that, those that bring the
        run's SuperLU solves to TREE_AFTER_SOLVES (until then every solve of it is SuperLU's)."""
        if self.laid_out:
            return self.tree_after_laid_out
        return self.solves + max(0.0, self.tree_after - self.superlu_solves)

    def solve(self, rhs: np.ndarray, target: float = 0.0, settled: float = 0.0) -> np.ndarray:
        """SuperLU's solve, or, once the factorization has made ``solves_before_tree`` solves on a
        large enough net (TREE_AFTER_SOLVES, TREE_AFTER_LAID_OUT, TREE_MIN_UNKNOWNS), the compiled
        one on its elimination tree (the same bits at any thread count; where SuperLU pivoted off the diagonal,
        SuperLU's solve throughout)."""
        self.staleness[3] += 1.0
        if self._check:
            return self._checked_solve(rhs)
        if (self._tree is None and self.solves >= self.solves_before_tree
                and self.pattern.size >= self.tree_min_unknowns):
            self._copy_to_tree()
        self.solves += 1
        if self._tree:
            self.tree_solves += 1
            return tree_solve(self._tree, rhs)
        self.superlu_solves += not self.laid_out
        return super().solve(rhs)

    def _copy_to_tree(self) -> None:
        """The current factors onto their elimination tree (by the kept layout where it fits);
        where the tree refuses them, SuperLU's solve goes on and the count toward a layout
        starts again."""
        layout = self._layout
        tree, self._layout = tree_factors(self._lu, numba.get_num_threads(), layout)
        self._tree = tree if tree is not None else False
        if tree is None:
            self.laid_out = False
            self.superlu_solves = 0
            return
        self.laid_out = True
        self.tree_copies += 1
        self.tree_layouts += self._layout is not layout

    def restore_tree_count(self, count: np.ndarray) -> None:
        """(superlu_solves, laid_out) as the run a resumed state comes from had them (so its
        factorizations go on the tree where that run's did)."""
        self.superlu_solves = int(count[0])
        self.laid_out = bool(count[1])

    def _checked_solve(self, rhs: np.ndarray) -> np.ndarray:
        """The first solve with fresh single factors, checked against the double matrix (see
        SINGLE_MAX_LINEAR_RESIDUAL); where they fail, double factors of the same matrix solve."""
        self._check = False
        self.solves += 1
        self.superlu_solves += not self.laid_out
        x = super().solve(rhs)
        scale = float(np.abs(rhs).max(initial=0.0))
        left = float(np.abs(rhs - self._matrix @ x).max(initial=0.0))
        if np.isfinite(x).all() and left <= SINGLE_MAX_LINEAR_RESIDUAL * scale:
            self._matrix = None  # (checked: not needed any more)
            return x
        self._raise_precision(f"single-precision factors left a linear residual of {left / scale:.2g} of the "
                              f"right-hand side (> {SINGLE_MAX_LINEAR_RESIDUAL:g})" if scale > 0 and np.isfinite(left)
                              else "single-precision factors gave a solution that is not finite")
        return super().solve(rhs)

    def _raise_precision(self, why: str) -> None:
        """Factorize the current matrix in double, and every later one (``raised``: why)."""
        A = self._matrix
        self.single = False
        self.raised = why
        self._single = False
        self._lu = _superlu(A)
        self._matrix = None
        self._check = False
        self._tree = None
        self._read_worth()

    def restore_solves(self, solves: int, worth: float | None = None) -> None:
        """The kept factorization rebuilt on resume has made ``solves`` solves and is worth
        ``worth`` solves, as in the run that saved it (single factors passed their check there;
        where it goes on the tree follows from these and :meth:`restore_tree_count`). The worth read from factors of the same row
        pivots is taken for the next ones too; SuperLU leaves out entries that come out exactly
        zero, so the worth read from the rebuilt factors can differ from the one that run had
        kept (on the 8 mm part 21.77 against 20.92), and with it when the run refactorizes."""
        self.solves = int(solves)
        if worth is not None:
            self.worth = float(worth)
            self._worth_of = (self._lu.perm_r.copy(), self.worth)
        if self.solves > 0:
            self._check = False

    def restore_staleness(self, staleness: np.ndarray) -> None:
        """The kept factorization rebuilt on resume had grown as stale as ``staleness`` says (so
        it is refactorized at the step the run that saved it would have)."""
        self.staleness[:] = staleness

    def restore_precision(self, bits: float) -> None:
        """The run a resumed state comes from made its factors in ``bits`` (32 or 64) precision:
        where it had gone to double factors, so does this solver (it factorizes as that run did)."""
        if bits == 64.0 and self.single:
            self.single = False
            self.raised = "double factors in the run this state comes from"

    @property
    def bits(self) -> float:
        """32.0 or 64.0: the precision of the factors it makes now, as a checkpoint keeps it."""
        return 32.0 if self.single else 64.0

    @property
    def single_factors(self) -> bool:
        """Whether the current factors are single precision (Newton's floor test reads it)."""
        return self._single

    @property
    def precision(self) -> str:
        """"single" or "double": the precision of the factors it makes now."""
        return "single" if self.single else "double"

    @property
    def carries_factorization(self) -> bool:
        """Whether its factorization is carried from step to step (``worth``: KEPT_ANYWHERE_WORTH
        solves or more; none made yet: False)."""
        return self.worth >= KEPT_ANYWHERE_WORTH

    def new_step(self) -> None:
        """A new step starts: a kept factorization is now an earlier step's, kept where it is
        worth KEPT_ANYWHERE_WORTH solves or more (else refactorizing costs little, and a step
        that starts with exact Newton corrections ends nearer its root: on a single spring at
        h ω = 100, 5.8e-13 of the energy drifted over 200 steps with, 1.2e-12 without)."""
        if self.carries_factorization:
            self.carried = True
            self._count_staleness()
        else:
            self.stale = True
        self.staleness[3] = 0.0

    def _count_staleness(self) -> None:
        """The last step's corrections: into the baseline (its first STALE_BASELINE_STEPS), or
        beyond it, refactorizing at this step where those add up to STALE_SHARE × worth."""
        counted, baseline, beyond, last = self.staleness
        if self.stale or self._lu is None:
            return
        if counted < 0.0:
            self.staleness[0] = 0.0
            return
        if counted < STALE_BASELINE_STEPS:
            self.staleness[:2] = counted + 1.0, baseline + last
            return
        beyond += last - baseline / counted
        self.staleness[2] = beyond
        if beyond >= STALE_SHARE * self.worth:
            self.stale = True
            self.stale_refactorizations += 1

    def contraction_limit(self, rho: float, tolerance: float, least: float) -> float:
        """The largest contraction per correction for which the kept factorization still pays:
        the corrections that take the scaled residual from ``rho`` to ``tolerance`` (not below
        KEPT_FLOOR) at that contraction cost at most a quarter of a factorization (``worth``
        solves), and never less than ``least``. A factorization worth many solves (a large 3D
        net: 20–100) is kept at contractions up to 0.3–0.9."""
        decades = max(math.log10(max(rho, KEPT_FLOOR) / max(tolerance, KEPT_FLOOR)), 1.0)
        return min(max(least, 10.0 ** (-4.0 * decades / self.worth)), KEPT_MAX_CONTRACTION)

    def judged_by_cost(self) -> bool:
        """Whether the kept factorization is judged by its cost (newton: contraction_limit, and
        no fresh iteration to confirm a small kept correction): one worth KEPT_ANYWHERE_WORTH
        solves or more."""
        return self.worth >= KEPT_ANYWHERE_WORTH

    def usable(self, h: float, rho: float, below: float) -> bool:
        """Whether the kept factorization may make the next correction at step h, scaled
        residual rho (≤ ``below``, or any where the factorization was carried from an earlier
        step or is worth KEPT_ANYWHERE_WORTH solves)."""
        return (self._lu is not None and not self.stale and self.h == h
                and (rho <= below or self.carried or self.worth >= KEPT_ANYWHERE_WORTH))


class ReusedLUDouble(ReusedLU):
    """:class:`ReusedLU` with double-precision factors (``linear_solver="splu-reuse-double"``)."""

    name = "splu-reuse-double"
    SINGLE = False
