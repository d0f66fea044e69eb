"""Whole implicit steps in one compiled call: the start kernel, Newton's iteration (residual,
Jacobian, dense LU with partial pivoting, update, convergence test) and the finish, for many
steps per call, generic over a scheme's compiled kernels. For small nets, where Python's share of
a step (one call per kernel, SuperLU's set-up) would cost far more than the arithmetic.

The driver template :func:`_newton_steps` calls four kernels by global name, bound per scheme
and model by :func:`newton_steps_kernel`:

    scheme_start(step, topo, spring, node, start, coef, u) -> (status, spring)
        the start kernel of :mod:`thermonet.implicit.core.schemes` (predictor into u)
    scheme_residual(step, topo, spring, node, work, extra, u, warm, res) -> (status, spring, max |R|, max Rabs)
    scheme_jacobian(topo, spring, node, work, places, extra, h, data)       CSR values into data
    scheme_finish(step, topo, spring, node, work, extra, u, phi, new) -> (status, spring)

and, where the scheme has them (else no-ops), ``scheme_predict(step, topo, spring, node, work,
extra, u)``, the scheme's own predictor from the start kernel's output in u (in place),
``scheme_local(step, topo, spring, node, work, extra, u, res, warm, threshold) -> (done,
status, spring, max |R|, max Rabs, max |change of u|)``, a local Jacobi step (HO4:
:func:`thermonet.implicit.core.local_jacobi._local_jacobi`; not done where too many nodes are above the threshold), and
``scheme_damp(step, topo, spring, node, work, extra, res, (max |R|, max Rabs), (u, du,
trial)) -> (evaluated, max |R|, max Rabs)``, which shortens a full iteration's correction du in
place (a damped Newton step; ``res``, the work record and ``trial`` may be overwritten). When it
returns ``evaluated``, ``res`` and the work record hold the residual at the corrected u, whose
norms it returns, and the driver does not evaluate it again.

``extra`` is a tuple of whatever else the scheme's kernels take (GTR-α: (α,); HO4: its two
empty index lists), made once by the stepper (``ImplicitStepper.compiled_extra``). A scheme
offers the compiled path by returning ``compiled_residual``, ``compiled_jacobian`` and
``compiled_finish`` (these signatures, serial) from its ``build``.

The iteration is :func:`thermonet.implicit.core.newton.newton`'s: both drivers decide by the same
functions of :mod:`.newton_policy` (scaled residual ≤ tolerance; or a correction at the round-off
floor with the scaled residual ≤ 1e3 tolerance; Jacobi and local steps; at most
``max_iterations`` linear solves), so both paths converge to the same solution within the
tolerance. The matrix is the scheme's CSR values scattered into a dense
(size, size) array, whose LU costs ~ size³/3 multiply-adds: the path pays only for a few
hundred unknowns (the automatic choice, ``implicit/core/compiled_path.py``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from . import newton_policy as policy
from .newton_policy import (AT_FLOOR, BELOW_TOLERANCE, FULL, JACOBI, LOCAL, STALL_WINDOW, JacobiRule, convergence,
                            linear_targets, next_jacobi, stalled)
from .records import StartWork
from .schemes import INLINE, OPTIONS
from ...kernels.copies import _copy_rows as _copy_rows_template, _copy_values
from ...kernels.specialize import function_fingerprint, model_fingerprint, specialize

# Bound per scheme and model by newton_steps_kernel(); listed so the template reads as ordinary code.
scheme_start = scheme_residual = scheme_jacobian = scheme_finish = scheme_linearize = scheme_sweep = None
scheme_predict = scheme_damp = scheme_local = None
#: the linear solves: inertia-preconditioned matrix-free sweeps (True) or dense LU (False)
SWEEPS = False

#: why a step failed (``info[1]``), as the Python path words it (ImplicitStepper, core.newton)
CONVERGED, START, NON_PHYSICAL, NOT_FINITE_RESIDUAL, NO_CONVERGENCE, NOT_FINITE_CORRECTION, FINISH, STALLED = range(8)
REASONS = {
    START: "invalid state at the start of the step",
    NON_PHYSICAL: "non-physical iterate",
    NOT_FINITE_RESIDUAL: "residual not finite",
    NOT_FINITE_CORRECTION: "Newton correction not finite",
    FINISH: "non-physical state after the step",
    STALLED: "matrix-free sweeps stalled",
}

#: the fields of ``out.info`` (int64): the step that failed, why, the kernel's status and spring,
#: the length of the failed step's scaled-residual history
INFO_STEP, INFO_REASON, INFO_STATUS, INFO_SPRING, INFO_LENGTH = range(5)
#: the start work's field whose last row holds the committed step's h (StartWork.history)
_NODAL = StartWork._fields.index("nodal")


class SweepLimits(NamedTuple):
    """A matrix-free solve's sweeps: at most ``max_sweeps``; stalled where one leaves more than
    ``stall`` times the linear residual of the one before (MatrixFree.MAX_SWEEPS, STALL)."""

    max_sweeps: int
    stall: float


class Control(NamedTuple):
    """What the driver is told for one call: Newton's ``tolerance`` and ``rtol``; ``rounding``
    (> 0: at each step's start atol becomes rounding × max |x| unless within a factor 2 of that
    already, EM2's atol at the positions' round-off, EM2Stepper.begin); ``max_iterations`` per
    step; ``n_steps``; the policy's ``linear_fraction`` and ``jacobi`` rule (:mod:`.newton_policy`),
    ``stall`` whether its stall window applies; the ``sweeps``' limits."""

    tolerance: float
    rtol: float
    rounding: float
    max_iterations: int
    n_steps: int
    linear_fraction: float
    jacobi: JacobiRule
    stall: bool
    sweeps: SweepLimits


class DriverOut(NamedTuple):
    """The driver's outputs: iterations (n_steps,) int64 and finals (n_steps,), per committed
    step its linear solves and last scaled residual; history (max_iterations + 2,) the scaled
    residuals of a failed step; info (5,) int64 (INFO_*); atol (1,) Newton's absolute increment
    tolerance, read and (rounding) updated."""

    iterations: np.ndarray
    finals: np.ndarray
    history: np.ndarray
    info: np.ndarray
    atol: np.ndarray


#: the policy's functions, whose code goes into the driver's cache name with the scheme's
_POLICY = (policy.floor_stall, policy._max_abs, convergence, stalled, policy.jacobi_pays, next_jacobi,
           linear_targets)

_DRIVERS: dict = {}
#: the commit's copy of x and p, the explicit kernels' row copy (its prange runs serially here)
_copy_rows = njit(inline="always", error_model="numpy", boundscheck=False)(_copy_rows_template)


def newton_steps_kernel(model, scheme: str, kernels, uniform: bool, rate: int, sweeps: bool, parallel: bool):
    """The compiled driver for ``scheme`` and ``model`` around ``kernels`` (ImplicitKernels with
    the compiled_* entries, threaded or not as ``parallel`` says), its linear solves dense
    (``sweeps`` False) or matrix-free; cached on disk."""
    key = (scheme, model_fingerprint(model), bool(uniform), int(rate), bool(sweeps), bool(parallel))
    if key not in _DRIVERS:
        ns = dict(scheme_start=kernels.start, scheme_residual=kernels.compiled_residual,
                  scheme_jacobian=kernels.compiled_jacobian, scheme_finish=kernels.compiled_finish,
                  scheme_linearize=getattr(kernels, "compiled_linearize", _no_linearize),
                  scheme_sweep=getattr(kernels, "sweep", _no_sweep),
                  scheme_predict=getattr(kernels, "compiled_predict", _no_predict),
                  scheme_damp=getattr(kernels, "compiled_damp", _no_damp),
                  scheme_local=getattr(kernels, "compiled_local", _no_local), SWEEPS=bool(sweeps))
        # Numba's disk cache of the driver holds its callees' machine code but checks only this
        # file: the callees' code (the scheme's kernels, recursively) goes into the name
        code = function_fingerprint(*(ns[k] for k in ("scheme_start", "scheme_residual", "scheme_jacobian",
                                                       "scheme_finish", "scheme_linearize", "scheme_sweep",
                                                       "scheme_predict", "scheme_damp", "scheme_local")),
                                    *_POLICY)
        tag = (f"{scheme}_{model.name}_{key[1]}_{code}{'_uniform' if uniform else ''}_rate{int(rate)}"
               f"_{'sweeps' if sweeps else 'dense'}_{'par' if parallel else 'ser'}")
        ns["_solve_sweeps"] = specialize(_solve_sweeps, tag, ns, **INLINE)
        _DRIVERS[key] = specialize(_newton_steps, tag, ns, **OPTIONS)
    return _DRIVERS[key]


@njit(cache=True)
def _no_linearize(spring, work, extra, h):
    """Stands in for a scheme without matrix-free kernels (dense driver only)."""


@njit(cache=True)
def _no_sweep(topo, node, work, h, du, R, r, update, first):
    """Stands in for a scheme without matrix-free kernels (dense driver only)."""
    return 0.0


@njit(cache=True, inline="always")
def _no_predict(step, topo, spring, node, work, extra, u):
    """Stands in for a scheme whose predictor is the start kernel's."""


@njit(cache=True, inline="always")
def _no_damp(step, topo, spring, node, work, extra, res, norms, vectors):
    """Stands in for a scheme that takes every Newton correction whole."""
    return False, 0.0, 0.0


@njit(cache=True, inline="always")
def _no_local(step, topo, spring, node, work, extra, u, res, warm, threshold):
    """Stands in for a scheme without local Jacobi steps (every Jacobi step is global)."""
    return False, 0, -1, 0.0, 0.0, 0.0


@njit(cache=True, error_model="numpy", boundscheck=False)
def csr_to_dense(indptr, indices, data, A):
    """A (size, size) = the CSR matrix (indptr, indices, data)."""
    A[:] = 0.0
    for row in range(A.shape[0]):
        for j in range(indptr[row], indptr[row + 1]):
            A[row, indices[j]] = data[j]


@njit(cache=True, error_model="numpy", boundscheck=False)
def lu_factor(A, piv):
    """LU with partial pivoting of A (size, size) in place (L unit lower, U upper), row
    exchanges in piv (size,) int64; False on a zero pivot."""
    n = A.shape[0]
    for k in range(n):
        big = abs(A[k, k])
        q = k
        for i in range(k + 1, n):
            if abs(A[i, k]) > big:
                big = abs(A[i, k])
                q = i
        piv[k] = q
        if not big > 0.0:
            return False
        if q != k:
            for j in range(n):
                t = A[k, j]
                A[k, j] = A[q, j]
                A[q, j] = t
        inv = 1.0 / A[k, k]
        for i in range(k + 1, n):
            f = A[i, k] * inv
            A[i, k] = f
            if f != 0.0:
                for j in range(k + 1, n):
                    A[i, j] -= f * A[k, j]
    return True


@njit(cache=True, error_model="numpy", boundscheck=False)
def lu_solve(A, piv, b):
    """Solve with :func:`lu_factor`'s factors, b (size,) overwritten by the solution."""
    n = A.shape[0]
    for k in range(n):
        q = piv[k]
        if q != k:
            t = b[k]
            b[k] = b[q]
            b[q] = t
    for i in range(n):
        s = b[i]
        for j in range(i):
            s -= A[i, j] * b[j]
        b[i] = s
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= A[i, j] * b[j]
        b[i] = s / A[i, i]


def _solve_sweeps(topo, node, work, h, du, R, r, target, settled, sweeps):
    """MatrixFree.solve's sweeps (solvers/matrix_free.py): du with max |R − J du| ≤ target, or
    until the residual left is estimated below ``settled``; ``sweeps``: SweepLimits.
    Returns the largest contraction of a sweep (inf: unknown), or −1 when the sweeps stalled
    (the sparse path's GMRES fallback is then needed)."""
    max_sweeps = sweeps.max_sweeps
    stall = sweeps.stall
    previous = math.inf
    worst = -1.0
    for k in range(max_sweeps):
        rmax = scheme_sweep(topo, node, work, h, du, R, r, True, k == 0)
        if k > 0:
            c = rmax / previous
            worst = c if worst < 0.0 else max(worst, c)
        if rmax <= target or (k > 0 and rmax * worst <= settled):
            return math.inf if worst < 0.0 else worst
        if not (rmax < math.inf) or rmax > stall * previous:
            return -1.0
        previous = rmax
    return -1.0


@njit(cache=True, inline="always")
def _max_abs(x):
    """max |x| over the array x (n, 3) (0 for an empty one)."""
    big = 0.0
    for a in range(x.shape[0]):
        for i in range(3):
            big = max(big, abs(x[a, i]))
    return big


def _newton_steps(state, records, extra, linear, control, out):
    """Up to ``n_steps`` steps of h, each committed into the state on success.

    state: (x (n, 3), p (n, 3), phi (m,), eta (m,), h, coef (B/3, 4 or 6) the predictor's
        coefficients), x, p, phi, eta overwritten step by step.
    records: (topo, spring, node, work, places) as plain tuples.
    linear: (indptr, indices, data (nnz,), A (size, size), piv (size,) int64, du (size,),
        r (size,), u (size,), res (R, Rabs, peak: Rabs and peak may be empty, the residual
        kernels then skip them), new (StateArrays buffers)); with SWEEPS data,
        A and piv are not read (may be empty); r is scratch (the damping's trial point).
    control: :class:`Control`.
    out: :class:`DriverOut`; for a failed step info = (step, reason, status, spring, length of
        its scaled residual history), its linear solves in iterations[step].
    Returns the number of steps committed (< n_steps: step info[INFO_STEP] failed, the state is
    at it).

    Every decision of the iteration is :mod:`.newton_policy`'s, as in the Python driver. With
    SWEEPS the linear solves are inertia-preconditioned sweeps and a full iteration may be
    followed by Jacobi steps (local ones where the scheme has them); sweeps that stall end the
    call with reason STALLED. The rounding floor and the stall window are not this driver's
    (floor 0, no window: ``control.stall`` is False), so they never decide here.
    """
    x, p, phi, eta, h, coef = state
    topo, spring, node, work, places = records
    indptr, indices, data, A, piv, du, r, u, res, new = linear
    tolerance = control.tolerance
    rtol = control.rtol
    rounding = control.rounding
    max_iterations = control.max_iterations
    n_steps = control.n_steps
    fraction = control.linear_fraction
    rule = control.jacobi
    stall = control.stall
    sweeps = control.sweeps
    iterations = out.iterations
    finals = out.finals
    history = out.history
    info = out.info
    tol = out.atol
    R = res[0]
    x_new, p_new, phi_new, eta_new = new
    size = u.shape[0]
    for k in range(n_steps):
        step = (x, p, eta, h)
        info[INFO_STEP] = k
        info[INFO_STATUS] = 0
        info[INFO_SPRING] = -1
        info[INFO_LENGTH] = 0
        if rounding > 0.0:
            floor = rounding * _max_abs(x)
            if not (0.5 * tol[0] <= floor <= 2.0 * tol[0]):
                tol[0] = floor
        atol = tol[0]
        status, bad = scheme_start(step, topo, spring, node, work[0], coef, u)
        if status != 0:
            info[INFO_REASON] = START
            info[INFO_STATUS] = status
            info[INFO_SPRING] = bad
            return k
        scheme_predict(step, topo, spring, node, work, extra, u)
        # (np.bool_: a plain False would be typed as the literal False at the loop's first call,
        # and Numba would compile the scheme's residual a second time for it)
        warm = np.bool_(False)
        corrections = 0
        jacobi_steps = 0
        increment = math.inf
        nh = 0
        reason = CONVERGED
        use_jacobi_ever = SWEEPS
        last = FULL  # the kind of the last correction (newton_policy)
        local_rounds = 0
        pending, pending_bad = 0, -1  # the status of a residual brought up to date by a local step
        contraction = math.inf
        evaluated = False
        rmax = scale = 0.0
        while True:
            if evaluated:  # the damping's trial point or a local step: its residual is in res
                status, bad = pending, pending_bad
                pending, pending_bad = 0, -1
                evaluated = False
            else:
                status, bad, rmax, scale = scheme_residual(step, topo, spring, node, work, extra, u, warm, res)
            warm = status == 0
            if status != 0:
                reason = NON_PHYSICAL
                info[INFO_STATUS] = status
                info[INFO_SPRING] = bad
                break
            rho = rmax / scale if scale > 0.0 else 0.0
            history[nh] = rho
            nh += 1
            if not (abs(rho) < math.inf):
                reason = NOT_FINITE_RESIDUAL
                break
            verdict, floored, small = convergence(corrections, rho, rmax, 0.0,
                                                  history[nh - 2] if nh > 1 else 0.0,
                                                  history[nh - 3] if nh > 2 else 0.0,
                                                  increment, u, tolerance, rtol, atol)
            if verdict == BELOW_TOLERANCE or verdict == AT_FLOOR or small:
                break
            if corrections - local_rounds == max_iterations:
                reason = NO_CONVERGENCE
                break
            if stall and stalled(nh, rho, history[nh - 1 - STALL_WINDOW] if nh > STALL_WINDOW else 0.0):
                reason = NO_CONVERGENCE
                break
            use_jacobi = False
            if use_jacobi_ever and corrections > 0:
                use_jacobi, use_jacobi_ever = next_jacobi(last, rho, history[nh - 2], contraction, local_rounds,
                                                          tolerance, rule.range, rule.max_steps, rule.local_stall,
                                                          rule.local_max_rounds)
            corrections += 1
            if SWEEPS and use_jacobi:
                done, pending, pending_bad, lmax, lscale, change = scheme_local(
                    step, topo, spring, node, work, extra, u, res, warm, rule.local_fraction * tolerance * scale)
                if done:
                    evaluated = True
                    rmax = lmax
                    scale = lscale
                    increment = change
                    jacobi_steps += 1
                    local_rounds += 1
                    last = LOCAL
                    continue
            if SWEEPS:
                if use_jacobi:
                    # (np.bool_: the type of the other call's ``first``, so one compiled sweep serves both)
                    scheme_sweep(topo, node, work, h, du, R, r, True, np.bool_(True))
                    jacobi_steps += 1
                    last = JACOBI
                else:
                    scheme_linearize(spring, work, extra, h)
                    target, settled = linear_targets(rho, scale, tolerance, fraction)
                    contraction = _solve_sweeps(topo, node, work, h, du, R, r, target, settled, sweeps)
                    if contraction < 0.0:
                        reason = STALLED
                        break
                    last = FULL
            else:
                scheme_jacobian(topo, spring, node, work, places, extra, h, data)
                csr_to_dense(indptr, indices, data, A)
                for i in range(size):
                    du[i] = R[i]
                if lu_factor(A, piv):
                    lu_solve(A, piv, du)
                else:
                    du[:] = math.nan
            if not use_jacobi:
                evaluated, trial_max, trial_scale = scheme_damp(step, topo, spring, node, work, extra, res,
                                                                (rmax, scale), (u, du, r))
                if evaluated:
                    rmax = trial_max
                    scale = trial_scale
            increment = 0.0
            finite = True
            for i in range(size):
                u[i] = r[i] if evaluated else u[i] - du[i]  # r: the damping's trial point
                d = abs(du[i])
                finite &= d < math.inf
                increment = max(increment, d)
            if not finite:
                reason = NOT_FINITE_CORRECTION
                break
        iterations[k] = corrections - jacobi_steps
        info[INFO_LENGTH] = nh
        if reason != CONVERGED:
            info[INFO_REASON] = reason
            return k
        status, bad = scheme_finish(step, topo, spring, node, work, extra, u, phi, new)
        if status != 0:
            info[INFO_REASON] = FINISH
            info[INFO_STATUS] = status
            info[INFO_SPRING] = bad
            return k
        # loops, not slice assignments (those need the runtime for their overlap check)
        _copy_rows(x_new, x)
        _copy_rows(p_new, p)
        _copy_values(phi_new, phi)
        _copy_values(eta_new, eta)
        nodal = work[0][_NODAL]
        if nodal.shape[0] > x.shape[0]:  # StartWork.history: u holds this committed step's solution
            nodal[x.shape[0], 0] = h
        finals[k] = history[nh - 1]
    return n_steps
