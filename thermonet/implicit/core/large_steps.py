"""EM2 far above the explicit limit: the Newton path chosen by the step ("auto" for a stepper
with ``chooses_by_step``), and continuation in the step, which solves a step's own equations
where Newton from the predictor stalls (a stepper with ``continuation``). Both act on an
:class:`~thermonet.implicit.core.stepper.ImplicitStepper` (its methods of the same names call
them).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...solvers import make_linear_solver
from .newton import NewtonResult, newton
from .compiled_path import choose_by_step


def choose_path(stepper, state, h: float) -> None:
    """"auto" by the step: at a new h, estimate ω_max at ``state`` and take the path
    :func:`choose_by_step` names (the compiled sweeps, or the sparse path with SuperLU and
    kept factorizations), each made once and kept for a later return to its h."""
    if stepper.path_choice is not None and stepper.path_choice.h == h:
        return
    from ...stability import max_frequency

    # the path the stepper was made with ("auto" by the size: the sweeps, or on a small net
    # the dense LU) serves the steps near the limit
    compiled, solver = stepper._paths.setdefault("made", (stepper.compiled, stepper.solver))
    omega = max_frequency(stepper.system, state.positions, state.entropy).omega_max
    quiet = unrest(stepper.system, state.positions, state.momenta, state.entropy, h)
    choice = choose_by_step(h, omega, stepper.pattern.size, unrest=quiet)
    if choice.linear_solver == "sweeps":
        made = compiled.linear_solver if compiled is not None else solver.name
        if made != "sweeps":
            choice = dataclasses.replace(choice, path="compiled" if compiled is not None else "sparse",
                                         linear_solver=made, reason=choice.reason + f" (here: {made})")
        stepper._paths.setdefault(choice.linear_solver, (compiled, solver))
    elif choice.linear_solver not in stepper._paths:
        if stepper.data.size != stepper.pattern.nnz:
            stepper.data = np.zeros(stepper.pattern.nnz)
        solver = make_linear_solver(choice.linear_solver, stepper.pattern, stepper)
        stepper._paths[choice.linear_solver] = (None, stepper.wrap_solver(solver))
    stepper.compiled, stepper.solver = stepper._paths[choice.linear_solver]
    stepper.path_choice = choice


def unrest(system, x: np.ndarray, p: np.ndarray, eta: np.ndarray | None, h: float) -> float:
    """How far the state (x, p, η; (n, 3), (n, 3), (m,)) is from a quiet one, as a strain: the
    larger of the springs' and gravity's out-of-balance force on a free node over the largest
    force per unit strain of a spring (κ_e l0_e, κ_e its adiabatic stiffness), and the largest
    relative displacement of a spring's ends over a step h at their velocities, |v_b − v_a| h / l0_e.
    Force loads are not counted (a part held by them counts as out of balance). inf where a
    stiffness is not finite."""
    from ...stability import spring_stiffness

    axial, geometric, n_vec = spring_stiffness(system, x, eta)
    edges, l0 = system.edges, system.rest_lengths
    scale = float(np.max(np.abs(axial) * l0, initial=0.0))
    if not (np.isfinite(axial).all() and np.isfinite(geometric).all() and np.isfinite(scale)) or scale <= 0.0:
        return math.inf
    length = np.linalg.norm(x[edges[:, 1]] - x[edges[:, 0]], axis=1)
    pull = (geometric * length)[:, None] * n_vec  # tension T n, pulling a towards b
    force = np.zeros_like(x)
    np.add.at(force, edges[:, 0], pull)
    np.subtract.at(force, edges[:, 1], pull)
    if system.gravity is not None:
        force += system.masses[:, None] * system.gravity[None, :]
    free = ~system.anchored
    imbalance = float(np.max(np.linalg.norm(force[free], axis=1), initial=0.0)) / scale
    v = p * system.inv_mass[:, None]
    motion = float(np.max(np.linalg.norm(v[edges[:, 1]] - v[edges[:, 0]], axis=1) * h / l0, initial=0.0))
    return max(imbalance, motion)


def continued(stepper, x, p, eta, h: float, failed: NewtonResult) -> NewtonResult:
    """The step's own equations (step h from x⁰, p⁰) solved by continuation in the step: the
    equations of steps τ from the same start, τ rising from 0 to h, each solved from the
    extrapolation of the solutions u(τ) before it (u(0) = 0; the first from the scheme's
    predictor at τ, the next linear, then quadratic through the last three), the
    intermediate ones to CONTINUATION_TOLERANCE. τ starts at h/2 and doubles its increment
    after each solved stage; a failed stage halves it, down to h·CONTINUATION_MIN_FRACTION,
    and at most CONTINUATION_MAX_SOLVES stages are tried. Where u(τ) has no fold on the way,
    this reaches a root that the predictor at h missed. The result is one step of h (not
    substeps), converged to the step's own tolerance, in ``u``; the Newton record is that of
    the last stage with the iterations of all (the failed first try's included)."""
    iterations, jacobi = failed.iterations, failed.jacobi_steps
    loose = dataclasses.replace(stepper.options,
                                tolerance=max(stepper.options.tolerance, stepper.CONTINUATION_TOLERANCE))
    result = failed
    solved = [(0.0, np.zeros_like(stepper.u))]
    # the first stage: h/2, or twice the first stage that the last continued step of this h
    # could solve
    first = min(0.5, 2.0 * stepper._hard[1]) if stepper._hard is not None and stepper._hard[0] == h else 0.5
    tau, dtau = 0.0, first * h
    stages = failures = 0
    for _ in range(stepper.CONTINUATION_MAX_SOLVES):
        if dtau < stepper.CONTINUATION_MIN_FRACTION * h:
            break
        last = tau + dtau >= h * (1.0 - 1e-9)
        if last:
            dtau = h - tau  # (so that a failure halves the stage actually tried)
        t = h if last else tau + dtau
        stepper.begin(x, p, eta, t)  # (the last stage: the step itself, h exactly)
        stepper.predict(stepper.u)
        if len(solved) > 1:
            stepper.u[:] = _extrapolate(solved[-3:], t)
        result = newton(stepper, stepper.u, stepper.options if last else loose, stepper.solver, stepper.timers,
                        stall=True)
        iterations += result.iterations
        jacobi += result.jacobi_steps
        if result.converged:
            stages += 1
            if last:
                stepper.totals["continued_steps"] += 1
                # a hard step (more than two stages, or a failed one): the next step of this h
                # goes straight to continuation, from this one's first solved stage
                hard = stepper.CONTINUATION_REMEMBERS and (stages > 2 or failures)
                stepper._hard = (h, solved[1][0] / h if len(solved) > 1 else 1.0) if hard else None
                return dataclasses.replace(result, iterations=iterations, jacobi_steps=jacobi)
            solved.append((t, stepper.u.copy()))
            tau, dtau = t, 2.0 * dtau
        else:
            failures += 1
            dtau *= 0.5
    stepper._hard = None
    stepper.begin(x, p, eta, h)  # (the failure's report reads the step's start)
    return dataclasses.replace(result, iterations=iterations, jacobi_steps=jacobi)


def _extrapolate(points, t: float) -> np.ndarray:
    """The Lagrange polynomial through ``points`` [(τ, u(τ)), …] (2 or 3 of them) at t."""
    out = np.zeros_like(points[0][1])
    for i, (ti, ui) in enumerate(points):
        w = 1.0
        for j, (tj, _) in enumerate(points):
            if j != i:
                w *= (t - tj) / (ti - tj)
        out += w * ui
    return out
