"""Newton's method on step equations with a sparse exact Jacobian.

The unknowns come in blocks of B values per free node (B = 3 for GTR-α, 6 for HO4) and the
springs couple the blocks of their two ends, so the Jacobian has the block sparsity of the
node graph. Three pieces, each with one job:

- :class:`BlockPattern`: that sparsity as a scalar CSR structure, built once per net, with the
  block rows in a fill-reducing order, and for each spring and node the place of its blocks in
  the CSR value array (the kernels refill only the values, every iteration);
- :class:`SparseLU` (``linear_solver="splu"``): SciPy's SuperLU. The fill-reducing ordering
  is computed once (minimum degree on AᵀA + A of the node graph) and baked into the pattern, so
  each factorization runs with the NATURAL ordering and skips the ordering phase; pivoting
  prefers the (dominant) diagonal. :class:`MatrixFree` (``"matfree"``) never forms the matrix:
  inertia-preconditioned sweeps of matrix-free products (Numba, threaded), with SciPy GMRES on
  the same product as fallback; it is the one for large nets, where a direct factorization of a
  3D net fills in superlinearly and an assembled Krylov solve (:class:`Krylov`, ``"gmres"``)
  spends its time filling and reading a matrix of 36 entries per spring-block;
- :func:`newton`: the iteration, its convergence test, its record and its timings.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import InputError


@dataclass(frozen=True)
class NewtonOptions:
    """Convergence control of the Newton iteration of one step.

    tolerance: converged when ‖R‖∞ / max(Rabs) ≤ tolerance, the residual scaled by the largest
        sum of magnitudes of the terms in a row (its round-off floor is a few 1e-16).
    rtol, atol: also converged when the last Newton correction is ≤ rtol ‖u‖∞ + atol (u: the
        displacements over the step) and the scaled residual is ≤ 1e3 tolerance: the unknowns
        have reached their round-off floor.
    max_iterations: linear solves allowed per step before the step fails.
    retry: on a failed step, retry it as 2, 4, …, 2**retry substeps (0: never; reported).
    linear_solver: "splu" (SciPy SuperLU), "matfree" (matrix-free inertia-preconditioned
        sweeps, GMRES fallback; each solve ends when the linear residual is below
        LINEAR_FRACTION × tolerance in the Newton scaling, so the inexact step cannot hold
        Newton above its tolerance), "gmres" (SciPy GMRES on the assembled matrix with a nodal
        block-Jacobi preconditioner, relative tolerance 1e-10 per solve), or "auto" (default:
        splu up to DIRECT_MAX_UNKNOWNS unknowns, matfree above; see benchmarks/README.md).
    """

    tolerance: float = 1e-12
    rtol: float = 1e-14
    atol: float = 0.0
    max_iterations: int = 12
    retry: int = 0
    linear_solver: str = "auto"

    @classmethod
    def from_options(cls, **options) -> "NewtonOptions":
        unknown = set(options) - set(cls.__dataclass_fields__)
        if unknown:
            raise InputError(f"unknown Newton option(s) {', '.join(sorted(unknown))}; "
                             f"known: {', '.join(cls.__dataclass_fields__)}")
        opts = cls(**options)
        if not (opts.tolerance > 0 and opts.rtol >= 0 and opts.atol >= 0):
            raise InputError(f"Newton tolerances must be positive: {opts}")
        if int(opts.max_iterations) < 1 or int(opts.retry) < 0:
            raise InputError(f"max_iterations must be >= 1 and retry >= 0: {opts}")
        if opts.linear_solver not in LINEAR_SOLVERS and opts.linear_solver != "auto":
            raise InputError(f"unknown linear_solver {opts.linear_solver!r}; known: auto, "
                             f"{', '.join(LINEAR_SOLVERS)}")
        return opts


# ---------------------------------------------------------------------------------------------
# sparsity


@dataclass(frozen=True, eq=False)
class BlockPattern:
    """The Jacobian's sparsity for B unknowns per free node, built once per net.

    block: B. n_free: free nodes. size: B n_free unknowns.
    free_index: (n,) int64, block row of each internal node (−1 on anchored nodes).
    indptr (size+1,), indices (nnz,): scalar CSR structure (int32), block rows in fill-reducing
        order, each block stored row-major inside its block row.
    node_base, node_stride: (n_free,) int64, data index of the (0, 0) entry of diagonal block k
        and the distance between its rows.
    spring_base, spring_stride: (m, 4) int64, the same for the blocks (a,a), (a,b), (b,a),
        (b,b) of spring e = (a, b); −1 where an end is anchored.
    """

    block: int
    n_free: int
    free_index: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray
    node_base: np.ndarray
    node_stride: np.ndarray
    spring_base: np.ndarray
    spring_stride: np.ndarray

    @property
    def size(self) -> int:
        return self.block * self.n_free

    @property
    def nnz(self) -> int:
        return len(self.indices)

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """The CSR matrix with these values (shares ``data``)."""
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.size, self.size))

    @classmethod
    def build(cls, edges: np.ndarray, anchored: np.ndarray, block: int, ordering: str = "mmd") -> "BlockPattern":
        """Pattern for springs ``edges`` (m, 2) on nodes with ``anchored`` (n,) bool.

        ordering: "mmd" (minimum degree, computed once), or "natural" (the layout's own
        reverse Cuthill–McKee numbering)."""
        n = len(anchored)
        B = int(block)
        free_nodes = np.flatnonzero(~anchored)
        nf = len(free_nodes)
        rank = np.full(n, -1, dtype=np.int64)
        rank[free_nodes] = np.arange(nf)
        ea, eb = rank[edges[:, 0]], rank[edges[:, 1]]
        both = (ea >= 0) & (eb >= 0)
        order = _node_ordering(ea[both], eb[both], nf, ordering)
        new_of = np.empty(nf, dtype=np.int64)
        new_of[order] = np.arange(nf)
        free_index = np.full(n, -1, dtype=np.int64)
        free_index[free_nodes] = new_of
        ka = free_index[edges[:, 0]]
        kb = free_index[edges[:, 1]]
        both = (ka >= 0) & (kb >= 0)
        rows = np.concatenate([np.arange(nf), ka[both], kb[both]])
        cols = np.concatenate([np.arange(nf), kb[both], ka[both]])
        keys = np.unique(rows * nf + cols)
        brow, bcol = keys // nf, keys % nf
        bptr = np.zeros(nf + 1, dtype=np.int64)
        np.cumsum(np.bincount(brow, minlength=nf), out=bptr[1:])
        nb = np.diff(bptr)  # blocks per block row

        # scalar CSR: row (k, r) holds, for each block slot s of block row k, columns B bcol + c
        row_len = np.repeat(B * nb, B)
        indptr = np.zeros(B * nf + 1, dtype=np.int64)
        np.cumsum(row_len, out=indptr[1:])
        slot_cols = B * bcol[:, None] + np.arange(B)[None, :]  # (nnzb, B)
        indices = _scalar_indices(slot_cols, bptr, B)

        def place(r, c):
            """(base, stride) of block (r, c); −1 where r or c < 0."""
            r = np.asarray(r)
            c = np.asarray(c)
            ok = (r >= 0) & (c >= 0)
            key = np.where(ok, r * nf + c, 0)
            pos = np.searchsorted(keys, key)
            rr = np.where(ok, r, 0)
            slot = pos - bptr[rr]
            base = B * B * bptr[rr] + slot * B
            stride = B * nb[rr]
            return np.where(ok, base, -1), np.where(ok, stride, 0)

        node_base, node_stride = place(np.arange(nf), np.arange(nf))
        sb = np.empty((len(edges), 4), dtype=np.int64)
        ss = np.empty((len(edges), 4), dtype=np.int64)
        for q, (r, c) in enumerate(((ka, ka), (ka, kb), (kb, ka), (kb, kb))):
            sb[:, q], ss[:, q] = place(r, c)
        return cls(B, nf, free_index, indptr.astype(np.int32), indices.astype(np.int32),
                   node_base.astype(np.int64), node_stride.astype(np.int64), sb, ss)


def _scalar_indices(slot_cols: np.ndarray, bptr: np.ndarray, B: int) -> np.ndarray:
    """Column indices of the scalar CSR: each block row's column list repeated for its B rows."""
    nf = len(bptr) - 1
    nb = np.diff(bptr)
    flat = slot_cols.ravel()  # block rows' column lists, concatenated
    starts = B * bptr[:-1]
    lengths = B * nb
    # for each scalar row (k, r): the range flat[starts[k] : starts[k] + lengths[k]]
    row_start = np.repeat(starts, B)
    row_len = np.repeat(lengths, B)
    offsets = np.arange(row_len.sum()) - np.repeat(np.cumsum(row_len) - row_len, row_len)
    return flat[np.repeat(row_start, row_len) + offsets] if nf else np.zeros(0, dtype=np.int64)


def _node_ordering(ra: np.ndarray, rb: np.ndarray, nf: int, ordering: str) -> np.ndarray:
    """Fill-reducing order of the free nodes (new → old) for the graph with edges (ra, rb)."""
    if ordering == "natural" or nf <= 2:
        return np.arange(nf)
    if ordering != "mmd":
        raise InputError(f"unknown ordering {ordering!r}; known: mmd, natural")
    adj = sp.coo_matrix((np.ones(len(ra)), (ra, rb)), shape=(nf, nf))
    adj = (adj + adj.T).tocsc()
    degree = np.asarray(adj.sum(axis=1)).ravel()
    graph = (adj + sp.diags(degree + 1.0)).tocsc()  # diagonally dominant: no pivoting
    lu = spla.splu(graph, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                   options=dict(SymmetricMode=True))
    return np.argsort(lu.perm_c)


# ---------------------------------------------------------------------------------------------
# linear solvers: factorize(data) once per Newton iteration, then solve(rhs)


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


class MatrixFree:
    """Inertia-preconditioned Richardson sweeps on matrix-free products (see
    :mod:`thermonet.kernels.implicit_operator`), until the linear residual's max norm is below
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


LINEAR_SOLVERS = {"splu": SparseLU, "matfree": MatrixFree, "gmres": Krylov}

#: "auto" uses the direct solver up to this many unknowns (measured crossover on 3D lattices:
#: at ~200 unknowns SuperLU and an iterative solve cost the same, at ~1000 SuperLU is 10× slower)
DIRECT_MAX_UNKNOWNS = 500


def make_linear_solver(name: str, pattern: BlockPattern, problem=None):
    """The linear solver ``name`` for ``pattern`` (``problem``: the stepper, for matfree)."""
    if name == "auto":
        name = "splu" if pattern.size <= DIRECT_MAX_UNKNOWNS else "matfree"
    return LINEAR_SOLVERS[name](pattern, problem)


# ---------------------------------------------------------------------------------------------
# the iteration


#: an inexact linear solve leaves a residual below this fraction of max(tolerance, ρ²) (in the
#: Newton scaling, ρ the current scaled residual): Newton stays quadratic and the last linear
#: error cannot keep the next Newton residual above the tolerance
LINEAR_FRACTION = 0.1
#: After a full Newton iteration, a scaled residual that few inertia-preconditioned (block-Jacobi)
#: steps u −= D⁻¹ R can bring below the tolerance is finished by them, without linearizing or
#: sweeping: below the stability limit the inertia dominates the Newton matrix, so each is an
#: inexact Newton step whose linear residual is a fraction of R, the fraction by which a sweep
#: of the last linear solve contracted (measured 0.005–0.05 on the benchmark lattices; the
#: scaled residual then falls 0.006–0.015× per Jacobi step). A Jacobi step costs a residual and
#: a node-only sweep, about a third of a full iteration (linearization, two or three full
#: sweeps, residual), so Jacobi steps are taken while that contraction says that at most
#: JACOBI_MAX_STEPS of them reach the tolerance (after each, by the contraction it achieved),
#: and never from above JACOBI_RANGE times the tolerance. Each result is checked like any other
#: iterate (matrix-free solver only).
JACOBI_RANGE = 1e4
JACOBI_MAX_STEPS = 2
#: Where the problem offers local Jacobi steps (HO4), a Jacobi step first updates only the free
#: nodes whose residual rows exceed LOCAL_FRACTION × the tolerance (after a full iteration, a few
#: per cent of the nodes at most on the benchmark lattices) and recomputes the residual only at
#: their springs and the ends of those: the same new residual as a global step's evaluation where
#: the rest are left, at a few per cent of its cost. Local steps go on while each reduces the
#: scaled residual at least LOCAL_STALL×, at most LOCAL_MAX_ROUNDS per solve.
LOCAL_FRACTION = 0.1
LOCAL_STALL = 0.5
LOCAL_MAX_ROUNDS = 8


def _jacobi_pays(rho: float, contraction: float, tolerance: float) -> bool:
    """Whether at most JACOBI_MAX_STEPS Jacobi steps, each reducing the scaled residual ``rho``
    by ``contraction``, reach ``tolerance``."""
    return (rho <= JACOBI_RANGE * tolerance and contraction < 1.0
            and rho * contraction**JACOBI_MAX_STEPS <= tolerance)


@dataclass
class NewtonTimers:
    """Cumulative seconds spent in each phase and counts, over the life of a stepper."""

    residual: float = 0.0
    assembly: float = 0.0
    factorization: float = 0.0
    solve: float = 0.0
    linear_solves: int = 0
    residuals: int = 0
    jacobi_steps: int = 0
    local_steps: int = 0

    def as_dict(self) -> dict:
        return dict(self.__dict__)


@dataclass
class NewtonResult:
    """What one Newton solve did: converged or why not, scaled residual history (one entry per
    residual evaluation, the predictor's first), the linear solves made, and for a
    non-physical iterate the status code and spring (internal numbering)."""

    converged: bool
    iterations: int
    history: list = field(default_factory=list)
    status: int = 0
    spring: int = -1
    reason: str = ""
    #: of the iterations, those that were Jacobi steps (u −= D⁻¹ R, no linearization)
    jacobi_steps: int = 0

    @property
    def full_iterations(self) -> int:
        """Iterations that linearized and solved: what ``newton_iterations`` reports."""
        return self.iterations - self.jacobi_steps


def newton(problem, u: np.ndarray, options: NewtonOptions, solver, timers: NewtonTimers) -> NewtonResult:
    """Solve ``problem.residual(u) = 0`` for ``u`` in place, from the predictor in ``u``.

    problem: ``residual(u) -> (status, spring)`` fills ``problem.R`` and ``problem.Rabs`` (and,
    optionally, ``problem.norms`` = (max |R|, max Rabs)) and whatever the Jacobian needs;
    ``jacobian(data)`` fills the CSR values at the last residual's point, ``data`` its value
    array (assembled solvers); ``linearize()`` the per-spring coefficients of a matrix-free
    product (:class:`MatrixFree`); optionally ``local_jacobi(u, fraction)``, a Jacobi step on
    the nodes whose residual rows exceed that fraction of max Rabs, which also brings R and
    ``norms`` up to date (None where it declines). The residual is always evaluated last at the
    returned ``u``.

    ``max_iterations`` bounds the full iterations and global Jacobi steps; local Jacobi steps
    are bounded by LOCAL_MAX_ROUNDS.
    """
    history: list[float] = []
    increment = math.inf
    jacobi = getattr(solver, "jacobi", None)
    local = getattr(problem, "local_jacobi", None) if jacobi is not None else None
    last = "full"  # the kind of the last correction: "full", "jacobi" (global) or "local"
    corrections = 0  # of every kind
    local_rounds = 0
    jacobi_steps = 0
    evaluated = None  # (status, spring) of the residual a local step brought up to date
    while True:
        it = corrections
        if evaluated is None:
            t0 = time.perf_counter()
            status, spring = problem.residual(u)
            timers.residual += time.perf_counter() - t0
            timers.residuals += 1
        else:
            status, spring = evaluated
            evaluated = None
        if status != 0:
            return NewtonResult(False, it, history, status, spring, "non-physical iterate", jacobi_steps)
        norms = getattr(problem, "norms", None)  # (max |R|, max Rabs), where the kernel had them
        if norms is not None:
            rmax, scale = norms
        else:
            scale = problem.Rabs.max() if problem.Rabs.size else 0.0
            rmax = np.abs(problem.R).max() if problem.R.size else 0.0
        rho = float(rmax / scale) if scale > 0 else 0.0
        history.append(rho)
        if not math.isfinite(rho):
            return NewtonResult(False, it, history, 0, -1, "residual not finite", jacobi_steps)
        if rho <= options.tolerance:
            return NewtonResult(True, it, history, jacobi_steps=jacobi_steps)
        if it > 0 and rho <= 1e3 * options.tolerance and increment <= options.rtol * np.abs(u).max() + options.atol:
            return NewtonResult(True, it, history, jacobi_steps=jacobi_steps)
        if corrections - local_rounds == options.max_iterations:
            break
        use_jacobi = False
        if jacobi is not None and it > 0:
            if last == "full":  # what the sweeps of that iteration's solve promise
                use_jacobi = _jacobi_pays(rho, getattr(solver, "contraction", math.inf), options.tolerance)
            else:
                contraction = rho / history[-2]
                if last == "local":  # each costs a few per cent of a global step
                    use_jacobi = contraction <= LOCAL_STALL and local_rounds < LOCAL_MAX_ROUNDS
                else:
                    use_jacobi = _jacobi_pays(rho, contraction, options.tolerance)
                if not use_jacobi:
                    jacobi = local = None  # they contract too slowly: full iterations from here on
        corrections += 1
        if use_jacobi and local is not None:
            t0 = time.perf_counter()
            done = local(u, LOCAL_FRACTION * options.tolerance)
            if done is not None:
                evaluated, increment = done[:2], done[2]
                timers.residual += time.perf_counter() - t0
                timers.local_steps += 1
                timers.jacobi_steps += 1
                jacobi_steps += 1
                local_rounds += 1
                last = "local"
                continue
        last = "jacobi" if use_jacobi else "full"
        t0 = t1 = t2 = time.perf_counter()
        if use_jacobi:
            du = jacobi(problem.R)
            timers.jacobi_steps += 1
            jacobi_steps += 1
        else:
            if solver.assembled:
                problem.jacobian(problem.data)
                t1 = time.perf_counter()
                solver.factorize(problem.data)
            else:
                problem.linearize()
                t1 = time.perf_counter()
            t2 = time.perf_counter()
            # forcing term ∝ ρ (Eisenstat–Walker): the linear error stays below Newton's own
            # quadratic term, so an early, far-from-converged step is not solved to round-off;
            # and no sweep is spent once the one before leaves a linear error that a converged
            # step could not tell from zero
            du = solver.solve(problem.R, LINEAR_FRACTION * max(options.tolerance, rho * rho) * scale,
                              LINEAR_FRACTION * options.tolerance * scale)
        t3 = time.perf_counter()
        timers.assembly += t1 - t0
        timers.factorization += t2 - t1
        timers.solve += t3 - t2
        timers.linear_solves += 1
        u -= du
        increment = float(np.abs(du).max())
        if not math.isfinite(increment):
            return NewtonResult(False, corrections, history, 0, -1, "Newton correction not finite", jacobi_steps)
    return NewtonResult(False, corrections, history, 0, -1,
                        f"no convergence in {options.max_iterations} iterations", jacobi_steps)
