"""EM2, the energy–momentum (discrete-gradient midpoint) integrator (docs/theory.md §3; Gonzalez 1996,
Simo & Tarnow 1992): implicit in x¹ only, second order, symmetric.

    x¹ = x⁰ + h M⁻¹ (p⁰ + p¹)/2,   p¹ = p⁰ + h m g − h Σ_e ∇̄U_e,   η¹ = η,   Φ¹ = Φ⁰ + h θ(l̄, η)

with the discrete gradient ∇̄U_e = ∓s_e d̄_e, s_e = [U(l¹, η) − U(l⁰, η)] / [(l¹ − l⁰) l̄]
(kernels in :mod:`thermonet.kernels.em2`). Total energy is conserved exactly (to the Newton
tolerance) at any step, so EM2 has no stability limit: far above the explicit limit the fast
modes lose accuracy (their phase), not stability. Linear and angular momentum and every spring's
entropy are kept exactly. Φ is a diagnostic here (θ at the mean length).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..kernels.em2 import LENGTH_LIMIT, LINE_SEARCH_ABOVE, LINE_SEARCH_HALVINGS, EM2Work  # noqa: F401
from ..kernels.implicit_records import plain
from .base import Integrator, register_integrator
from .implicit import ImplicitStepper, newton_options


class EM2(Integrator):
    """The energy–momentum integrator: unconditionally stable (no h_max)."""

    name = "em2"
    order = 2
    explicit = False
    #: no stability limit: the step policy and the run-time guard never refuse its step
    stability_interval = math.inf
    unconditionally_stable = True
    description = "energy–momentum (discrete-gradient midpoint) step at fixed entropy, implicit in x¹, order 2"

    def make_stepper(self, system, parallel: bool = False, **options) -> "EM2Stepper":
        options.setdefault("max_iterations", MAX_ITERATIONS)
        options.setdefault("retry", RETRY)
        stepper = EM2Stepper(self, system, newton_options(options), parallel)
        stepper.rounding_atol = "atol" not in options
        return stepper


#: EM2's default Newton iterations per step (other schemes: 12): far above the explicit limit
#: the corrections are shortened (LENGTH_LIMIT) and take a few more iterations
MAX_ITERATIONS = 30
#: EM2's default retry levels (other schemes: 0): a step whose Newton solve fails is redone as
#: 2, 4, …, 2**RETRY substeps (warned, and in the diagnostics), each keeping the energy exactly.
#: Far above the explicit limit (hω ≳ 10 on nets whose springs turn or stretch a lot per step)
#: a whole step's Newton solve does not always converge from the predictor: measured on the
#: heated plate (scenes/lattice2d.toml) at 7.6× CO2's limit, 8 of 20 steps needed 2–4 substeps
RETRY = 4
#: without a given ``atol``, Newton's absolute increment tolerance is this many ulps of the
#: largest coordinate: a correction below the positions' own rounding is noise (near rest, the
#: forces' rounding, c ε per spring from ln(l/l0), can hold the scaled residual above 1e-12
#: while the displacements are tiny; measured on a chain's slow mode at 1e-4 amplitude)
ATOL_ULPS = 8


class LengthLimited:
    """The stepper's linear solver, its corrections made safe far from the solution (a damped
    Newton step): each correction is first shortened so that no spring's vector changes by more
    than LENGTH_LIMIT times its length, and then, while the scaled residual is above
    LINE_SEARCH_ABOVE, halved until the residual's 2-norm falls (Armijo; the Newton direction
    descends on it). Far above the explicit limit a full Newton correction would stretch a stiff
    spring by thousands of lengths, or through zero; near the solution the correction is taken
    whole and Newton converges quadratically. Everything else is the wrapped solver's."""

    def __init__(self, solver, stepper):
        object.__setattr__(self, "inner", solver)
        object.__setattr__(self, "stepper", stepper)

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def __setattr__(self, name, value):  # statistics (iterations, ...) live in the wrapped solver
        setattr(self.inner, name, value)

    def solve(self, rhs, target: float = 0.0, settled: float = 0.0):
        du = self.inner.solve(rhs, target, settled)
        st = self.stepper
        rmax, smax = st.norms
        # the compiled path's damping kernel (kernels/em2.py), so both paths damp alike
        st.kernels.damp(st._step_start, st._topology, st._springs, st._nodes, st._work, st._residuals,
                        (rmax, smax), (st.u, du, st.trial))
        return du


class EM2Stepper(ImplicitStepper):
    """EM2 bound to a system: 3 unknowns (the displacement) per free node."""

    block = 3
    scheme = "em2"
    #: Newton's atol follows the positions' rounding (ATOL_ULPS; set by EM2.make_stepper)
    rounding_atol = False
    #: a max |R| at or below this that Newton no longer reduces is converged (set by predict)
    residual_floor = 0.0

    #: "auto" follows h·ω_max (integrators/compiled_path.choose_by_step)
    chooses_by_step = True
    #: a failed step's equations are solved by continuation in h before substeps (retry)
    continuation = True

    def __init__(self, integrator, system, options, parallel: bool = False):
        super().__init__(integrator, system, options, parallel)
        self.solver = self.wrap_solver(self.solver)

    def wrap_solver(self, solver):
        return LengthLimited(solver, self)

    def make_work(self, start) -> EM2Work:
        # the start kernel writes the acceleration at x⁰ here; predict() makes the guess from it
        self.accel = self.prediction = np.zeros(self.pattern.size)
        self.trial = np.zeros(self.pattern.size)  # the damped step's trial points
        return EM2Work.allocate(start)

    def atol_rounding(self) -> float:
        return ATOL_ULPS * np.finfo(np.float64).eps if self.rounding_atol else 0.0

    def begin(self, x, p, eta, h: float) -> None:
        super().begin(x, p, eta, h)
        if getattr(self.solver, "reuses_factorization", False):
            # kept factorizations serve the iterations of one step only: a run resumed from a
            # checkpoint (which holds no factorization) then continues bit for bit; measured on
            # the bracket at 10×, 100× and 1e4× CO2's stable step, a factorization kept across
            # steps was never used (a step's predictor is farther from its root than REUSE_BELOW)
            self.solver.stale = True
        if self.rounding_atol:
            floor = self.atol_rounding() * float(np.abs(x).max(initial=0.0))
            if not 0.5 * self.options.atol <= floor <= 2.0 * self.options.atol:
                self.options = dataclasses.replace(self.options, atol=floor)

    def predictor_coefficients(self, h: float) -> np.ndarray:
        """The start kernel's output is the acceleration a (the predictor is EM2's own)."""
        return np.array([[0.0, 1.0, 0.0, 0.0]])

    def predict(self, u: np.ndarray) -> None:
        """The midpoint step of each node on its own springs' stiffness (kernels.em2); and the
        residual's rounding floor (``residual_floor``, read by the Newton iteration): ATOL_ULPS
        ulps of the largest spring force that one ulp of length would make, (h/2) κ_e l⁰_e with κ_e
        the predictor's spring stiffness. A max |R| below it that a Newton correction no longer
        reduces (less than 2×) is the rounding of the force terms: a net at rest in exact
        equilibrium has a max |R| of a few 1e-16 over a max Rabs of the same size, a scaled
        residual of order 1 that no Newton correction can reduce."""
        self.kernels.predict(self._step_start, self._topology, self._springs, self._nodes, self._work,
                             self.accel, u)
        start = self.work.start  # (guess: the predictor's per-spring stiffness κ_e, until the finish)
        self.residual_floor = (ATOL_ULPS * np.finfo(np.float64).eps * 0.5 * self.h
                               * float(np.max(start.guess * start.len0, initial=0.0)))

    def residual(self, u: np.ndarray):
        status, spring, rmax, smax = self.kernels.residual(self._step_start, self._topology, self._springs,
                                                           self._nodes, self._work, u, self._residuals)
        self.norms = (rmax, smax)
        return status, spring

    def linearize(self) -> None:
        self.kernels.linearize(self._springs, self._work, self.h)

    def apply_inverse_inertia(self, v):
        """(h/m) v per free node."""
        return (np.asarray(v).reshape(-1, 3) * (self.h / self.block_mass)[:, None]).ravel()

    def jacobian(self, data: np.ndarray) -> None:
        self.kernels.jacobian(self._topology, self._springs, self._nodes, self._work, self._places, self.h, data)

    def finish(self, phi0, new):
        return self.kernels.finish(self._step_start, self._topology, self._springs, self._nodes,
                                   self._work, self.u, phi0, plain(new))


EM2_INTEGRATOR = register_integrator(EM2())
