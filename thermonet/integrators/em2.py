"""EM2, the energy–momentum (discrete-gradient midpoint) integrator (spec-heat §4; Gonzalez 1996,
Simo & Tarnow 1992): implicit in x¹ only, second order, symmetric.

    x¹ = x⁰ + h M⁻¹ (p⁰ + p¹)/2,   p¹ = p⁰ + h m g − h Σ_e ∇̄U_e,   η¹ = η,   Φ¹ = Φ⁰ + h θ(l̄, η)

with the discrete gradient ∇̄U_e = ∓s_e d̄_e, s_e = [U(l¹, η) − U(l⁰, η)] / [(l¹ − l⁰) l̄]
(kernels in :mod:`thermonet.kernels.em2`). Total energy is conserved exactly (to the Newton
tolerance) at any step, so EM2 has no stability limit: far above the explicit limit the fast
modes lose accuracy (their phase), not stability. Linear and angular momentum and every spring's
entropy are kept exactly. Φ is a diagnostic here (θ at the mean length).
"""

from __future__ import annotations

import math

import numpy as np

from ..kernels.em2 import EM2Work
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
        return EM2Stepper(self, system, newton_options(options), parallel)


class EM2Stepper(ImplicitStepper):
    """EM2 bound to a system: 3 unknowns (the displacement) per free node."""

    block = 3
    scheme = "em2"

    def make_work(self, start) -> EM2Work:
        # the start kernel writes the acceleration at x⁰ here; predict() makes the guess from it
        self.accel = self.prediction = np.zeros(self.pattern.size)
        return EM2Work.allocate(start)

    def predictor_coefficients(self, h: float) -> np.ndarray:
        """The start kernel's output is the acceleration a (the predictor is EM2's own)."""
        return np.array([[0.0, 1.0, 0.0, 0.0]])

    def predict(self, u: np.ndarray) -> None:
        """The midpoint step of each node on its own springs' stiffness (kernels.em2)."""
        self.kernels.predict(self._step_start, self._topology, self._springs, self._nodes, self._work,
                             self.accel, u)

    def residual(self, u: np.ndarray):
        status, spring, rmax, smax = self.kernels.residual(self._step_start, self._topology, self._springs,
                                                           self._nodes, self._work, u, self._residuals)
        self.norms = (rmax, smax)
        return status, spring

    def linearize(self) -> None:
        self.kernels.linearize(self._work, self.h)

    def apply_inverse_inertia(self, v):
        """(h/m) v per free node."""
        return (np.asarray(v).reshape(-1, 3) * (self.h / self.block_mass)[:, None]).ravel()

    def jacobian(self, data: np.ndarray) -> None:
        self.kernels.jacobian(self._topology, self._springs, self._nodes, self._work, self._places, self.h, data)

    def finish(self, phi0, new):
        return self.kernels.finish(self._step_start, self._topology, self._springs, self._nodes,
                                   self._work, self.u, phi0, plain(new))


EM2_INTEGRATOR = register_integrator(EM2())
