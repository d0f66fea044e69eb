"""The compiled Newton path of an implicit stepper: whole steps, many per call, in one compiled
driver (:mod:`thermonet.implicit.core.compiled_newton`); and the choice between it and the sparse path
(:func:`thermonet.implicit.core.newton.newton`, one Python call per kernel, SuperLU, GMRES or
matrix-free sweeps).

``newton_path`` (a stepper option): "compiled", "compiled-dense", "sparse", or "auto" (default):
compiled where the scheme offers it and ``linear_solver`` is left at "auto", sparse otherwise.
The compiled path's linear solves are the inertia-preconditioned matrix-free sweeps (faster than
a dense LU at every size measured, the paper's chain included: benchmarks/README.md, "Implicit
integrators"); a dense LU where the scheme has no sweeps (up to DENSE_MAX_UNKNOWNS unknowns), with
"auto" up to AUTO_DENSE_MAX_UNKNOWNS, or with "compiled-dense" (exact Newton steps; no sweeps to
stall).

A scheme meant for steps far above the explicit limit (EM2: ``chooses_by_step``) makes the
"auto" choice from the step instead (:func:`choose_by_step`): the sweeps are preconditioned by
the inertia (m/h) alone, so the sweeps a linear solve needs grow with h·ω_max (a step's cost
grows about ∝ h·ω_max on a tetrahedral part, and faster where Newton then needs more
iterations); a factorized solve costs the same at any step. Above SWEEPS_MAX_HW, and at every
step on small nets, the sparse path with SuperLU and kept factorizations
(``linear_solver="splu-reuse"``, modified Newton) runs instead.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ...errors import InputError
from ...kernels.records import StateArrays
from .records import Residuals, plain
from .compiled_newton import NO_CONVERGENCE, REASONS, STALLED, Control, DriverOut, SweepLimits, newton_steps_kernel
from ...solvers.matrix_free import MatrixFree
from . import newton_policy as policy
from .newton import NewtonResult

#: a scheme without matrix-free sweeps takes the compiled path (dense LU) up to this many
#: unknowns (B per free node); the LU's size³/3 multiply-adds cost more than SuperLU above
DENSE_MAX_UNKNOWNS = 200
#: "auto" solves by the dense LU up to this many unknowns even where sweeps exist: exact Newton
#: steps, which converge where inexact ones need more iterations (steps near the stability
#: limit), at ≈ 1.2–1.6× the sweeps' cost on nets this small (the paper's chain: 9 and 18)
AUTO_DENSE_MAX_UNKNOWNS = 24


#: "auto" for a scheme that chooses by the step (EM2): the compiled path's matrix-free sweeps up
#: to this h·ω_max (ω_max: the largest angular frequency of the net linearized at the run's
#: state, thermonet.stability.max_frequency; CO2's stable step is 2/ω_max), the sparse path with
#: "splu-reuse" above. Measured crossovers (benchmarks/em2_paths.py; benchmarks/README.md, "EM2's
#: solver path"): between h·ω_max = 8 and 16 on 18-neighbour lattices of 540 and 1 944 unknowns,
#: between 10 and 20 on a tetrahedral part of 2 738 springs
SWEEPS_MAX_HW = 10.0
#: … except on nets of more than AUTO_DENSE_MAX_UNKNOWNS and at most SPLU_ALWAYS_MAX_UNKNOWNS unknowns, where
#: SuperLU's factorization is so cheap that "splu-reuse" is faster at every step (measured 1.8×
#: at h·ω_max = 2 on 144 unknowns); below, the compiled path's dense LU (AUTO_DENSE_MAX_UNKNOWNS:
#: no Python call per iteration)
SPLU_ALWAYS_MAX_UNKNOWNS = 200
#: … and on a quiet net of more than AUTO_DENSE_MAX_UNKNOWNS unknowns (out-of-balance force and
#: motion over the step at most QUIET_STRAIN as a strain, :func:`.large_steps.unrest`; a part
#: at rest or loaded slowly), where a factorization carried from step to step with the last step's
#: displacement as predictor needs about two corrections per step and no new factorization:
#: measured on the steel part of benchmarks/em2_paths.py faster than the sweeps at h·ω_max = 2
#: and 6 at 9 270 springs (5 172 unknowns), and 6.6× faster at h·ω_max = 2 at 97 958 springs
#: (47 637 unknowns). A net released out of balance rings (the hot lattice and the bracket:
#: the Jacobian turns with the motion, the last step is a poor guess), and there the sweeps
#: are 3–5× faster at those steps
QUIET_STRAIN = 1e-6


@dataclass(frozen=True)
class PathChoice:
    """What "auto" chose for one step h: ``path`` ("compiled" or "sparse"), ``linear_solver``
    ("sweeps" or "splu-reuse"), h·ω_max and the reason, one line for the run summary."""

    h: float
    h_omega: float
    path: str
    linear_solver: str
    reason: str


def choose_by_step(h: float, omega_max: float, size: int, sweeps_max_hw: float = None,
                   unrest: float = math.inf) -> PathChoice:
    """The "auto" path of a scheme that chooses by the step (EM2), for step h on a net of
    ``size`` unknowns whose largest angular frequency is ``omega_max`` and whose state is
    ``unrest`` away from a quiet one (a strain, :func:`.large_steps.unrest`; inf: unknown):
    "sweeps" (the compiled path the stepper was made with: matrix-free sweeps, or the dense LU
    on the smallest nets) or "splu-reuse" (the sparse path, SuperLU with kept factorizations)."""
    limit = SWEEPS_MAX_HW if sweeps_max_hw is None else sweeps_max_hw
    hw = float(h) * float(omega_max)
    where = f"h·ω_max = {hw:.3g}" + (f" ({hw / 2:.3g}× CO2's stable step)" if math.isfinite(hw) else "")
    if not math.isfinite(hw):
        return PathChoice(h, hw, "sparse", "splu-reuse", f"{where}: SuperLU with kept factorizations")
    if AUTO_DENSE_MAX_UNKNOWNS < size <= SPLU_ALWAYS_MAX_UNKNOWNS:
        return PathChoice(h, hw, "sparse", "splu-reuse",
                          f"{where}, {size} unknowns (≤ {SPLU_ALWAYS_MAX_UNKNOWNS}): SuperLU with kept "
                          f"factorizations is the cheapest at any step on a net this small")
    if hw <= limit and unrest <= QUIET_STRAIN and size > AUTO_DENSE_MAX_UNKNOWNS:
        return PathChoice(h, hw, "sparse", "splu-reuse",
                          f"{where}, a quiet net (out of balance and motion {unrest:.2g} ≤ {QUIET_STRAIN:g} as "
                          f"a strain): a factorization carried from step to step needs about two solves per "
                          f"step ({size} unknowns)")
    if hw <= limit:
        return PathChoice(h, hw, "compiled", "sweeps",
                          f"{where} ≤ {limit:g}: inertia-preconditioned sweeps converge in a few sweeps")
    return PathChoice(h, hw, "sparse", "splu-reuse",
                      f"{where} > {limit:g}: sweeps would need ≈ h·ω_max each; SuperLU with kept "
                      f"factorizations ({size} unknowns)")


def offers_compiled(kernels) -> bool:
    """Whether a scheme's kernels include the compiled path's (compiled_residual, …)."""
    return all(hasattr(kernels, k) for k in ("compiled_residual", "compiled_jacobian", "compiled_finish"))


def offers_sweeps(kernels) -> bool:
    """Whether they include the matrix-free ones too (compiled_linearize, sweep)."""
    return hasattr(kernels, "compiled_linearize") and hasattr(kernels, "sweep")


def use_compiled(options, size: int, kernels, name: str) -> bool:
    """The choice of ``options.newton_path`` for a net of ``size`` unknowns."""
    path = options.newton_path
    if path == "sparse":
        return False
    if path == "compiled-dense":
        if not offers_compiled(kernels):
            raise InputError(f"{name}: newton_path='compiled-dense' is not available for this scheme")
        return True
    usable = offers_compiled(kernels) and (offers_sweeps(kernels) or size <= DENSE_MAX_UNKNOWNS)
    if path == "compiled":
        if not usable:
            raise InputError(f"{name}: newton_path='compiled' is not available for this scheme at {size} unknowns")
        return True
    return usable and options.linear_solver == "auto"


class CompiledNewton:
    """The compiled driver bound to one stepper (its records, kernels, pattern and options) and
    the driver's buffers: the CSR values, the dense matrix and its pivots (dense solves), the
    correction and linear residual, the next state, per-step iteration counts and final
    residuals, the failure's history and info."""

    def __init__(self, stepper):
        system = stepper.system
        _, uniform = system.kernel_parameters
        pattern = stepper.pattern
        size = pattern.size
        path = stepper.options.newton_path
        self.sweeps = sweeps = (path != "compiled-dense" and offers_sweeps(stepper.kernels)
                                and not (path == "auto" and size <= AUTO_DENSE_MAX_UNKNOWNS))
        self.linear_solver = "sweeps" if sweeps else "dense"
        self.driver = newton_steps_kernel(system.model, stepper.scheme, stepper.kernels, uniform, stepper.rate,
                                          sweeps, stepper.kernels_parallel)
        n, m = system.n_nodes, system.n_springs
        self.stepper = stepper
        self._new = StateArrays(np.empty((n, 3)), np.empty((n, 3)), np.empty(m), np.empty(m))
        self._linear = None
        dense = 0 if sweeps else size
        self._buffers = (pattern.indptr, pattern.indices, np.zeros(pattern.nnz if dense else 0),
                         np.zeros((dense, dense)), np.zeros(dense, dtype=np.int64), np.zeros(size), np.zeros(size))
        opts = stepper.options
        # the policy's rules as the Python driver reads them; no stall window here (a failed
        # step goes back to the stepper, whose sparse path has it)
        self._rules = dict(tolerance=float(opts.tolerance), rtol=float(opts.rtol),
                           max_iterations=int(opts.max_iterations), linear_fraction=float(policy.LINEAR_FRACTION),
                           jacobi=policy.jacobi_rule(), stall=False,
                           sweeps=SweepLimits(int(MatrixFree.MAX_SWEEPS), float(MatrixFree.STALL)))
        self._history = np.zeros(int(opts.max_iterations) + 2)
        self._info = np.zeros(5, dtype=np.int64)
        self._atol = np.zeros(1)
        self._out = None
        self._coef = (None, None)

    def run(self, x, p, phi, eta, h: float, n_steps: int):
        """Up to n_steps steps from (x, p, Φ, η), committed in place step by step. Returns (steps
        done, iterations (done,), final scaled residuals (done,), the failure or None): a
        failure of step ``done`` is (reason, NewtonResult or None, status, spring, stalled),
        ``stalled``: the sweeps stalled (the sparse path should make that step)."""
        s = self.stepper
        if self._coef[0] != h:
            self._coef = (h, s.predictor_coefficients(h))
        if self._out is None or self._out.iterations.shape[0] < n_steps:
            self._out = DriverOut(np.zeros(n_steps, dtype=np.int64), np.zeros(n_steps), self._history, self._info,
                                  self._atol)
        if self._linear is None:
            # R and the per-node peaks (HO4's local Jacobi steps) shared with the stepper; no
            # Rabs: the driver reads only its maximum, and its stores were 48 bytes per node of
            # every residual's memory traffic
            residuals = Residuals(s.residuals.R, np.empty(0), s.residuals.peak)
            self._linear = self._buffers + (s.u, plain(residuals), tuple(self._new))
        records = (s._topology, s._springs, s._nodes, s._work, s._places)
        # Newton's atol: the stepper's, or (a scheme with atol_rounding, EM2) the driver's per step
        atol = float(s.options.atol)
        self._atol[0] = atol
        control = Control(rounding=float(s.atol_rounding()), n_steps=int(n_steps), **self._rules)
        done = self.driver((x, p, phi, eta, float(h), self._coef[1]), records, s.compiled_extra(), self._linear,
                           control, self._out)
        if self._atol[0] != atol:
            s.options = dataclasses.replace(s.options, atol=float(self._atol[0]))
        iterations, finals = self._out.iterations[:done], self._out.finals[:done]
        s.warm = False
        if done == n_steps:
            return done, iterations, finals, None
        _, reason, status, spring, nh = (int(v) for v in self._info)
        its = int(self._out.iterations[done]) if nh else 0
        history = [float(r) for r in self._history[:nh]]
        text = f"no convergence in {s.options.max_iterations} iterations" if reason == NO_CONVERGENCE else REASONS[reason]
        result = NewtonResult(False, its, history, status, spring, text) if nh else None
        return done, iterations, finals, (text, result, status, spring, reason == STALLED)

    def attempt(self, x, p, phi, eta, h: float):
        """One step from copies of (x, p, Φ, η): ((the new state's buffers, the NewtonResult),
        None), or (None, the failure of :meth:`run`)."""
        xs, ps, phis, etas = x.copy(), p.copy(), phi.copy(), eta.copy()
        done, iterations, finals, failure = self.run(xs, ps, phis, etas, h, 1)
        if failure is not None:
            return None, failure
        return (StateArrays(xs, ps, phis, etas), NewtonResult(True, int(iterations[0]), [float(finals[0])])), None
