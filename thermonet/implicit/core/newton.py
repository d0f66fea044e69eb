"""Newton's method on the step equations of an implicit integrator: its options, the iteration
with its convergence test and its finishing Jacobi steps, its record and its timings. The
problem (the stepper) supplies the residual and the linearization; the linear solver
(:mod:`.linear`) the corrections.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ...errors import InputError
from ...solvers.linear import LINEAR_SOLVERS
from . import newton_policy as policy
from .newton_policy import AT_FLOOR, BELOW_TOLERANCE, FULL, JACOBI, KEPT, LOCAL, STALL_WINDOW


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
    newton_path: "compiled" (whole steps, many per call, in one compiled driver:
        thermonet.implicit.core.compiled_newton; matrix-free sweeps), "compiled-dense" (the same with a
        dense LU), "sparse" (this module's iteration with ``linear_solver``), or "auto" (default:
        compiled where the scheme offers it and linear_solver is "auto"; see
        thermonet.implicit.core.compiled_path).
    """

    tolerance: float = 1e-12
    rtol: float = 1e-14
    atol: float = 0.0
    max_iterations: int = 12
    retry: int = 0
    linear_solver: str = "auto"
    newton_path: str = "auto"

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
        if opts.newton_path not in NEWTON_PATHS:
            raise InputError(f"unknown newton_path {opts.newton_path!r}; known: {', '.join(NEWTON_PATHS)}")
        return opts


#: the values of NewtonOptions.newton_path
NEWTON_PATHS = ("auto", "compiled", "compiled-dense", "sparse")
#: Modified Newton (a solver with ``reuses_factorization``, ``linear_solver="splu-reuse"``): a kept
#: factorization made in the same step makes the correction only while the scaled residual is at
#: most REUSE_BELOW (near the root: no line search there, whose halvings a stale matrix's
#: direction would waste), one carried from an earlier step from the step's start; either is
#: dropped once a correction it made reduced the scaled residual by less than REUSE_CONTRACTION
#: (the next iteration assembles and factorizes afresh). A correction with a kept factorization
#: costs a residual and two triangular solves, a small fraction of an assembly and a
#: factorization (benchmarks/em2_paths.py), so a linear contraction of 0.2 per such correction
#: still reaches the tolerance sooner than a quadratic Newton iteration that factorizes.
REUSE_BELOW = policy.STALL_ABOVE

# This driver runs the policy's decisions as plain Python: the same source and the same IEEE
# double arithmetic as the compiled driver's, without the cost of a compiled call from Python
# (typing its arguments), which is larger than the decision (2–4 % of a step on small nets)
_convergence = policy.convergence.py_func
_stalled = policy.stalled.py_func
_next_jacobi = policy.next_jacobi.py_func
_linear_targets = policy.linear_targets.py_func
REUSE_CONTRACTION = 0.2


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
    #: factorizations made and full iterations that solved with a kept one (modified Newton)
    factorizations: int = 0
    reused_factorizations: int = 0

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
    #: of the full iterations, those that solved with a kept factorization (modified Newton)
    reused: int = 0

    @property
    def full_iterations(self) -> int:
        """Iterations that linearized and solved: what ``newton_iterations`` reports."""
        return self.iterations - self.jacobi_steps


def newton(problem, u: np.ndarray, options: NewtonOptions, solver, timers: NewtonTimers,
           stall: bool = False) -> NewtonResult:
    """Solve ``problem.residual(u) = 0`` for ``u`` in place, from the predictor in ``u``.

    problem: ``residual(u) -> (status, spring)`` fills ``problem.R`` and ``problem.Rabs`` (and,
    optionally, ``problem.norms`` = (max |R|, max Rabs)) and whatever the Jacobian needs; an
    optional ``problem.residual_floor``: a max |R| at or below it that the last correction
    reduced less than 2× (or FLOOR_STALL_FACTOR times less than the one before, newton_policy.floor_stall),
    or that a correction with single-precision factors reached (``solver.single_factors``: their
    contraction is the precision's, whatever the residual), is converged whatever its scaled
    value (the rounding of the residual's own terms; EM2's: a net at rest in exact equilibrium
    has a residual of round-off over a scale of round-off);
    ``jacobian(data)`` fills the CSR values at the last residual's point, ``data`` its value
    array (assembled solvers); ``linearize()`` the per-spring coefficients of a matrix-free
    product (:class:`MatrixFree`); optionally ``local_jacobi(u, fraction)``, a Jacobi step on
    the nodes whose residual rows exceed that fraction of max Rabs, which also brings R and
    ``norms`` up to date (None where it declines). The residual is always evaluated last at the
    returned ``u``.

    An optional ``problem.take_evaluated(u)``: (status, spring) where the problem's last
    residual was evaluated at exactly these unknowns (its predictor compared guesses by their
    residuals), so the first evaluation is skipped; None where it was not.

    ``max_iterations`` bounds the full iterations and global Jacobi steps; local Jacobi steps
    are bounded by LOCAL_MAX_ROUNDS. The decisions are :mod:`.newton_policy`'s, the compiled
    driver's too; kept factorizations (modified Newton) are this driver's alone.
    """
    history: list[float] = []
    increment = math.inf
    jacobi = getattr(solver, "jacobi", None)
    local = getattr(problem, "local_jacobi", None) if jacobi is not None else None
    last = FULL  # the kind of the last correction: FULL, JACOBI (global), LOCAL or KEPT
    tolerance, rtol, atol = float(options.tolerance), float(options.rtol), float(options.atol)
    rule = policy.jacobi_rule() if jacobi is not None else None  # (read only where Jacobi steps may be taken)
    floor = float(getattr(problem, "residual_floor", 0.0))
    corrections = 0  # of every kind
    local_rounds = 0
    jacobi_steps = 0
    # (status, spring) of a residual already up to date at u: a local step's, or the predictor's
    taken = getattr(problem, "take_evaluated", None)
    evaluated = taken(u) if taken is not None else None
    reuse = getattr(solver, "reuses_factorization", False)
    h = getattr(problem, "h", None)
    reused = 0
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
            if reuse:
                solver.stale = True
            return NewtonResult(False, it, history, status, spring, "non-physical iterate", jacobi_steps, reused)
        norms = getattr(problem, "norms", None)  # (max |R|, max Rabs), where the kernel had them
        if norms is not None:
            rmax, scale = norms
        else:
            scale = problem.Rabs.max() if problem.Rabs.size else 0.0
            rmax = np.abs(problem.R).max() if problem.R.size else 0.0
        rho = float(rmax / scale) if scale > 0 else 0.0
        history.append(rho)
        kept = last == KEPT
        # a kept factorization worth many solves (solvers.direct: a large 3D net's) is judged
        # by what it costs; a cheap one as ever (REUSE_CONTRACTION, a fresh iteration decides)
        costly = kept and solver.judged_by_cost()
        if kept and not costly and not rho <= REUSE_CONTRACTION * history[-2]:
            solver.stale = True  # the kept factorization no longer pays: factorize at the next iteration
        if not math.isfinite(rho):
            return NewtonResult(False, it, history, 0, -1, "residual not finite", jacobi_steps, reused)
        verdict, floored, small = _convergence(
            it, rho, float(rmax), floor, history[-2] if it > 0 else 0.0, history[-3] if it > 1 else 0.0,
            increment, u, tolerance, rtol, atol)
        if (floored and verdict != BELOW_TOLERANCE and last in (FULL, KEPT)
                and getattr(solver, "single_factors", False)):
            # single-precision factors contract the residual ~1e-4 per correction whatever its
            # size, so a fall that continues at the floor is theirs, not a sign of error left
            # above the rounding: the next correction would only confirm the floor (double
            # factors stop there one correction later too, at a residual no smaller)
            verdict = AT_FLOOR
        if verdict == BELOW_TOLERANCE or verdict == AT_FLOOR:
            # (AT_FLOOR: at the rounding floor of the residual's terms, and no longer falling)
            return NewtonResult(True, it, history, jacobi_steps=jacobi_steps, reused=reused)
        if costly and not floored and not (
                rho <= solver.contraction_limit(history[-2], options.tolerance, REUSE_CONTRACTION) * history[-2]):
            # it converges linearly, and more slowly than pays: refactorize (at the rounding
            # floor a contraction says nothing: the test above ends the iteration next time)
            solver.stale = True
        if small:
            if not kept:
                return NewtonResult(True, it, history, jacobi_steps=jacobi_steps, reused=reused)
            # a kept factorization's correction converges linearly: a small one does not say the
            # root is reached; a fresh Newton iteration (quadratic) decides, or, where a
            # factorization costs many solves, one more kept correction
            if not costly:
                solver.stale = True
        if corrections - local_rounds == options.max_iterations:
            break
        window = STALL_WINDOW
        if stall and _stalled(len(history), rho, history[-1 - window] if len(history) > window else 0.0):
            if reuse:
                solver.stale = True
            return NewtonResult(False, corrections, history, 0, -1,
                                f"stalled (scaled residual {rho:.3g}, {history[-1 - window]:.3g} "
                                f"{window} iterations before)", jacobi_steps, reused)
        use_jacobi = False
        if jacobi is not None and it > 0:
            promised = float(getattr(solver, "contraction", math.inf))
            use_jacobi, still = _next_jacobi(last, rho, history[-2], promised, local_rounds, tolerance, rule.range,
                                                   rule.max_steps, rule.local_stall, rule.local_max_rounds)
            if not still:
                jacobi = local = None  # they contract too slowly: full iterations from here on
        corrections += 1
        if use_jacobi and local is not None:
            t0 = time.perf_counter()
            done = local(u, rule.local_fraction * options.tolerance)
            if done is not None:
                evaluated, increment = done[:2], done[2]
                timers.residual += time.perf_counter() - t0
                timers.local_steps += 1
                timers.jacobi_steps += 1
                jacobi_steps += 1
                local_rounds += 1
                last = LOCAL
                continue
        last = JACOBI if use_jacobi else FULL
        t0 = t1 = t2 = time.perf_counter()
        if use_jacobi:
            du = jacobi(problem.R)
            timers.jacobi_steps += 1
            jacobi_steps += 1
        else:
            if reuse and solver.usable(h, rho, REUSE_BELOW):
                last = KEPT  # modified Newton: the factorization of an earlier iterate
                reused += 1
                timers.reused_factorizations += 1
            elif reuse:
                problem.jacobian(problem.data)
                t1 = time.perf_counter()
                solver.factorize(problem.data, h)
                timers.factorizations += 1
            elif solver.assembled:
                problem.jacobian(problem.data)
                t1 = time.perf_counter()
                solver.factorize(problem.data)
            else:
                problem.linearize()
                t1 = time.perf_counter()
            t2 = time.perf_counter()
            du = solver.solve(problem.R, *_linear_targets(rho, float(scale), tolerance, policy.LINEAR_FRACTION))
        t3 = time.perf_counter()
        timers.assembly += t1 - t0
        timers.factorization += t2 - t1
        timers.solve += t3 - t2
        timers.linear_solves += 1
        u -= du
        increment = float(np.abs(du).max())
        if not math.isfinite(increment):
            return NewtonResult(False, corrections, history, 0, -1, "Newton correction not finite", jacobi_steps,
                                reused)
    if reuse:
        solver.stale = True  # (a failed solve: the next attempt starts from a fresh Jacobian)
    return NewtonResult(False, corrections, history, 0, -1,
                        f"no convergence in {options.max_iterations} iterations", jacobi_steps, reused)
