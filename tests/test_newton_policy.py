"""Newton's one policy (thermonet/implicit/core/newton_policy.py), which the Python and the
compiled drivers both call: its rules on scalars, run as plain Python (``py_func``: no compiler
involved; the drivers' tests run the compiled functions)."""

import math

import numpy as np

from thermonet.implicit.core import newton_policy as policy

convergence = policy.convergence.py_func
next_jacobi = policy.next_jacobi.py_func
stalled = policy.stalled.py_func
linear_targets = policy.linear_targets.py_func


def _with_plain_helpers(monkeypatch):
    # the policy's functions call each other by global name: the plain ones here
    for name in ("floor_stall", "_max_abs", "jacobi_pays"):
        monkeypatch.setattr(policy, name, getattr(policy, name).py_func)


def test_convergence_below_the_tolerance_at_the_floor_and_at_the_unknowns_round_off(monkeypatch):
    _with_plain_helpers(monkeypatch)
    tol = (1e-12, 1e-14, 0.0)  # tolerance, rtol, atol
    u = np.array([1.0, -2.0])
    assert convergence(3, 1e-13, 1.0, 0.0, 1e-6, 1e-3, math.inf, u, *tol)[0] == policy.BELOW_TOLERANCE
    # max |R| at its floor, reduced less than 2× by the last correction: converged there
    verdict, floored, _ = convergence(2, 1e-9, 1e-20, 1e-19, 1.5e-9, 0.0, 1.0, u, *tol)
    assert verdict == policy.AT_FLOOR and floored
    # at the floor but still falling fast: not yet
    assert convergence(2, 1e-10, 1e-20, 1e-19, 1e-8, 1e-7, 1.0, u, *tol)[:2] == (policy.NOT_YET, True)
    # a correction at the unknowns' round-off near the tolerance
    assert convergence(2, 1e-10, 1.0, 0.0, 1e-8, 1e-4, 1e-14, u, *tol) == (policy.NOT_YET, False, True)
    assert not convergence(2, 1e-8, 1.0, 0.0, 1e-6, 1e-4, 1e-14, u, *tol)[2]  # ρ above 1e3 × tol
    assert not convergence(0, 1e-10, 1.0, 0.0, 0.0, 0.0, 0.0, u, *tol)[2]  # no correction yet


def test_jacobi_steps_follow_the_promised_contraction_and_stop_for_good(monkeypatch):
    _with_plain_helpers(monkeypatch)
    r = policy.jacobi_rule()
    rule = (r.range, r.max_steps, r.local_stall, r.local_max_rounds)
    tol = 1e-12
    # after a full iteration: taken where two steps at the sweeps' contraction reach the tolerance
    assert next_jacobi(policy.FULL, 1e-10, 1e-6, 0.05, 0, tol, *rule) == (True, True)
    assert next_jacobi(policy.FULL, 1e-10, 1e-6, 0.5, 0, tol, *rule) == (False, True)
    assert next_jacobi(policy.FULL, 1e-7, 1e-5, 1e-6, 0, tol, *rule)[0] is False  # above JACOBI_RANGE × tol
    # after a Jacobi step, its own contraction decides; once it does not pay, never again
    assert next_jacobi(policy.JACOBI, 1e-11, 1e-10, math.inf, 0, tol, *rule) == (True, True)
    assert next_jacobi(policy.JACOBI, 9e-11, 1e-10, math.inf, 0, tol, *rule) == (False, False)
    # local steps go on while each halves the residual, at most LOCAL_MAX_ROUNDS of them
    assert next_jacobi(policy.LOCAL, 4e-11, 1e-10, math.inf, 1, tol, *rule) == (True, True)
    assert next_jacobi(policy.LOCAL, 6e-11, 1e-10, math.inf, 1, tol, *rule) == (False, False)
    assert next_jacobi(policy.LOCAL, 4e-11, 1e-10, math.inf, policy.LOCAL_MAX_ROUNDS, tol, *rule)[0] is False


def test_the_stall_window_and_the_linear_targets():
    w = policy.STALL_WINDOW
    assert stalled(w + 1, 0.6, 1.0) and not stalled(w + 1, 0.4, 1.0) and not stalled(w, 0.6, 1.0)
    assert not stalled(w + 1, 1e-4, 1.5e-4)  # below STALL_ABOVE: a kept factorization's slow fall
    target, settled = linear_targets(0.5, 2.0, 1e-12, policy.LINEAR_FRACTION)
    assert target == policy.LINEAR_FRACTION * 0.25 * 2.0 and settled == policy.LINEAR_FRACTION * 1e-12 * 2.0
