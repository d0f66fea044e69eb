"""Newton's policy, one definition for both drivers: when a step has converged (the tolerance,
the correction at the unknowns' round-off, a residual at its rounding floor), when it has
stalled, when a Jacobi step (global or local) replaces a full iteration, and how accurately a
full iteration's linear solve must be made. The Python driver (:func:`.newton.newton`) and the
compiled one (:mod:`.compiled_newton`) call these ``@njit`` functions with the same scalars, so
both take the same decisions, bit for bit. What only the Python driver has (kept
factorizations: modified Newton) stays there; the damping of a full correction is the scheme's
kernel (EM2's ``damp``), called by both drivers after full iterations only.
"""

from __future__ import annotations

from typing import NamedTuple

from numba import njit

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
#: iterate (matrix-free solves only).
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
#: At the residual's rounding floor, a correction whose reduction of the scaled residual is this
#: many times weaker than the reduction of the correction before it has met the floor: a kept
#: factorization on a slowly loaded part contracts 3e-6 per correction (1e-1 → 3e-7), and the
#: next correction's 30× (→ 1e-8, under the floor) is the rounding's, which one more correction
#: would only confirm (a third solve per step at 100× CO2's stable step on the steel part)
FLOOR_STALL_FACTOR = 10.0
#: a scaled residual at most this many times the tolerance, with a correction at the unknowns'
#: round-off (rtol ‖u‖∞ + atol), is converged: the unknowns cannot get closer
NEAR_TOLERANCE = 1e3
#: A stalling solve (where the caller asks for the test: ``newton(..., stall=True)``) gives up once the scaled residual, still
#: above STALL_ABOVE, has fallen less than STALL_FACTOR× over the last STALL_WINDOW iterations (the
#: caller has a better way on: EM2's continuation in the step)
STALL_WINDOW = 6
STALL_FACTOR = 2.0
#: (the same value as the Python driver's REUSE_BELOW: near the root a slow fall is the kept
#: factorization's linear contraction, not a stall)
STALL_ABOVE = 1e-3

#: the kinds of the last correction, which decide what the next one may be
FULL, JACOBI, LOCAL, KEPT = 0, 1, 2, 3
#: what :func:`convergence` finds: not yet, below the tolerance, at the residual's rounding floor
NOT_YET, BELOW_TOLERANCE, AT_FLOOR = 0, 1, 2


class JacobiRule(NamedTuple):
    """When a Jacobi step replaces a full iteration (the constants above; max_steps a float,
    the exponent both drivers have always used)."""

    range: float
    max_steps: float
    local_fraction: float
    local_stall: float
    local_max_rounds: int


def jacobi_rule() -> JacobiRule:
    """The rule from this module's constants (read at each call: a test may change them)."""
    return JacobiRule(float(JACOBI_RANGE), float(JACOBI_MAX_STEPS), float(LOCAL_FRACTION), float(LOCAL_STALL),
                      int(LOCAL_MAX_ROUNDS))


# The functions below take scalars (and the unknowns' array), not records: the Python driver
# calls them at every iteration, and Numba types a record argument in Python at every call
# (≈ 1–4 µs a record, several times the decision itself).


@njit(cache=True)
def floor_stall(previous, before):
    """The reduction of the last correction (ρ / ``previous``) above which a residual at the
    rounding floor is converged: 0.5, or FLOOR_STALL_FACTOR times the reduction of the
    correction before (``previous`` / ``before``; ``before`` 0: none) where that is smaller (a
    linear contraction does not weaken tenfold from one correction to the next with the same
    matrix; a quadratic one strengthens)."""
    if before > 0.0:
        return min(0.5, FLOOR_STALL_FACTOR * previous / before)
    return 0.5


@njit(cache=True)
def _max_abs(u):
    """max |u| over u (size,) (0 for an empty one)."""
    big = 0.0
    for i in range(u.shape[0]):
        big = max(big, abs(u[i]))
    return big


@njit(cache=True)
def convergence(it, rho, rmax, floor, previous, before, increment, u, tolerance, rtol, atol):
    """Newton's convergence test after ``it`` corrections, at the scaled residual ``rho`` (max
    |R| = ``rmax``; ``previous``, ``before``: the scaled residuals one and two evaluations back, 0
    where there are none), the last correction's max |du| ``increment``, the unknowns u (size,);
    the tolerances of NewtonOptions.

    Returns (verdict, floored, small): verdict BELOW_TOLERANCE (ρ ≤ tolerance) or AT_FLOOR (max
    |R| at or below ``floor``, the rounding of the residual's own terms, and no longer falling:
    :func:`floor_stall`), else NOT_YET; floored: max |R| at or below the floor after a correction;
    small: a correction at the unknowns' round-off with ρ ≤ NEAR_TOLERANCE × tolerance (converged
    unless the caller's correction converges only linearly)."""
    if rho <= tolerance:
        return BELOW_TOLERANCE, False, False
    floored = it > 0 and rmax <= floor
    if floored and rho > floor_stall(previous, before) * previous:
        return AT_FLOOR, True, False
    small = it > 0 and rho <= NEAR_TOLERANCE * tolerance and increment <= rtol * _max_abs(u) + atol
    return NOT_YET, floored, small


@njit(cache=True)
def stalled(n, rho, window_rho):
    """Whether a solve whose history has ``n`` scaled residuals, the last ``rho`` and the one
    STALL_WINDOW before it ``window_rho``, has stalled (where the caller asks for the test)."""
    return n > STALL_WINDOW and rho > STALL_ABOVE and rho * STALL_FACTOR > window_rho


@njit(cache=True)
def jacobi_pays(rho, contraction, tolerance, jacobi_range, max_steps):
    """Whether at most ``max_steps`` Jacobi steps, each reducing the scaled residual ``rho`` by
    ``contraction``, reach ``tolerance`` (and ρ is within ``jacobi_range`` of it)."""
    return (rho <= jacobi_range * tolerance and contraction < 1.0
            and rho * contraction ** max_steps <= tolerance)


@njit(cache=True)
def next_jacobi(last, rho, previous, promised, local_rounds, tolerance, jacobi_range, max_steps, local_stall,
                local_max_rounds):
    """Whether the next correction is a Jacobi step, after a correction of kind ``last`` (FULL,
    JACOBI, LOCAL, KEPT) that took the scaled residual from ``previous`` to ``rho``; ``promised``:
    the contraction per sweep of the last full iteration's linear solve (inf: unknown); the rest a
    :class:`JacobiRule`'s fields. Returns (jacobi, still): ``still`` False once Jacobi steps
    contract too slowly (full iterations from then on)."""
    if last == FULL:  # what the sweeps of that iteration's solve promise
        return jacobi_pays(rho, promised, tolerance, jacobi_range, max_steps), True
    contraction = rho / previous
    if last == LOCAL:  # each costs a few per cent of a global step
        use = contraction <= local_stall and local_rounds < local_max_rounds
    else:
        use = jacobi_pays(rho, contraction, tolerance, jacobi_range, max_steps)
    return use, use


@njit(cache=True)
def linear_targets(rho, scale, tolerance, fraction):
    """A full iteration's linear solve: (target, settled), the max |R − J du| to reach and the
    one below which a solve whose residual is estimated to go is done. Forcing term ∝ ρ
    (Eisenstat–Walker): the linear error stays below Newton's own quadratic term, so an early,
    far-from-converged step is not solved to round-off; and no sweep is spent once the one before
    leaves a linear error that a converged step could not tell from zero."""
    return fraction * max(tolerance, rho * rho) * scale, fraction * tolerance * scale
