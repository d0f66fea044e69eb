"""HO4: quadratic trajectories in x and Φ with Lobatto quadrature (docs/theory.md §2.2, paper (53)–(59)),
the 3-stage Lobatto IIIA–IIIB partitioned Runge–Kutta method; fourth order, implicit.

One step finds x^½, x¹ (per free node) and Φ^½, Φ¹ (per spring) from

    p^k = M (8x^½ − 7x⁰ − x¹)/(3h) − (h/6) f⁰                  (58a)
    4M (x⁰ − 2x^½ + x¹)/h² = f^½                                (57a)
    η^k = (3Γ⁰ + 4Γ^½ − Γ¹)/6,   Γ⁰ = Γ¹            per spring (58c), (57b)

by Newton's method on the displacements d^½ = x^½ − x⁰, d¹ = x¹ − x⁰, the two thermal unknowns
of each spring condensed per spring (written as the end temperatures θ⁰, θ¹, which determine
Φ^½ and Φ¹ given Φ⁰: Φ¹ = Φ⁰ + h(θ⁰ + θ¹)/2, Φ^½ = (3Φ⁰ + Φ¹ + hθ⁰)/4). The entropy is then
*measured* by (58d) on the converged unknowns and p¹ follows from (58b).
"""

from __future__ import annotations

import math

import numpy as np

from .kernels import HO4Work
from ..core.records import plain
from ...integrators.base import Integrator, register_integrator
from ..core.stepper import ImplicitStepper, newton_options


class HO4(Integrator):
    """The fourth-order implicit integrator of the paper (§4.4)."""

    name = "ho4"
    order = 4
    explicit = False
    description = "quadratic trajectories + Lobatto quadrature (Lobatto IIIA-IIIB), implicit, paper (58)"

    def make_stepper(self, system, parallel: bool = False, **options) -> "HO4Stepper":
        return HO4Stepper(self, system, newton_options(options), parallel)


class HO4Stepper(ImplicitStepper):
    """HO4 bound to a system: 6 unknowns (d^½, d¹) per free node."""

    block = 6
    scheme = "ho4"
    rate = 2
    _subset_compiled = False

    def make_work(self, start) -> HO4Work:
        return HO4Work.allocate(start)

    def predictor_coefficients(self, h: float) -> np.ndarray:
        """(58a) and (57a) give the unknowns exactly in terms of the acceleration at the midpoint
        stage, a^½ = f^½/m: d^½ = h/2 v + h²/12 a + h²/24 a^½, d¹ = h v + h²/6 a + h²/3 a^½
        (a = f⁰/m). The predictor takes a^½ ≈ a + h/2 ȧ + h²/8 ä along the exact flow (ȧ, ä from
        the start kernel); the residual is then ≈ h/4 m (error of a^½), (58a)'s rows are exact
        up to θ⁰ ≠ θ(l⁰, η). With the ä term the scaled residual of the benchmark lattices is
        about 10× below the third-order Taylor guess's. Columns 4 and 5 are the start kernel's
        extrapolation (implicit/core/start.py): a change Δ of a^½ moves d^½ by h²/24 Δ and
        d¹ by h²/3 Δ, and the previous step's converged unknowns give its stage acceleration
        a^½ = 4 (d¹ − 2 d^½)/h² ((57a) solved for f^½/m), one order more of a^½ (measured on
        the benchmark lattice at h = 0.01: one Newton correction then suffices in most steps,
        where the series alone needed a second one in nearly every step)."""
        return np.array([[0.5 * h, h * h / 8.0, h**3 / 48.0, h**4 / 192.0, h * h / 24.0, -8.0 / (h * h)],
                         [h, 0.5 * h * h, h**3 / 6.0, h**4 / 24.0, h * h / 3.0, 4.0 / (h * h)]])

    def compiled_extra(self) -> tuple:
        """The full residual's two empty index lists and the local Jacobi step's scratch
        (implicit/core/local_jacobi._local_jacobi)."""
        return (self._no_index, self._no_index, self.local_scratch())

    def residual(self, u: np.ndarray):
        status, spring, rmax, smax = self._residual(self.kernels.residual, u, self._no_index, self._no_index)
        self.norms = (rmax, smax)
        return status, spring

    def begin(self, x, p, eta, h: float) -> None:
        super().begin(x, p, eta, h)
        # compile (or load) the local Jacobi step now, not at a run's first local step; only a
        # solver that takes Jacobi steps (matrix-free) ever calls it (core.newton)
        if not self._subset_compiled and getattr(self.solver, "jacobi", None) is not None:
            self.kernels.local_jacobi(self._step_start, self._topology, self._springs, self._nodes, self._work,
                                      self.u, self._residuals, False, math.inf, self.local_scratch())  # no node: no-op
            self._subset_compiled = True

    def _residual(self, kernel, u, springs, nodes):
        out = kernel(self._step_start, self._topology, self._springs, self._nodes, self._work,
                     u, self.warm, self._residuals, springs, nodes)
        self.warm = out[0] == 0
        return out

    def linearize(self) -> None:
        self.kernels.linearize(self._springs, self._work, self.h)

    def apply_inverse_inertia(self, v):
        """Per free node, (h/m) ½ [[1, 1/3], [2, 8/3]] applied to (v^½, v¹)."""
        b = np.asarray(v).reshape(-1, 2, 3)
        q = (0.5 * self.h / self.block_mass)[:, None]
        out = np.empty_like(b)
        out[:, 0] = q * (b[:, 0] + b[:, 1] / 3.0)
        out[:, 1] = q * (2.0 * b[:, 0] + 8.0 / 3.0 * b[:, 1])
        return out.ravel()

    def jacobian(self, data: np.ndarray) -> None:
        self.kernels.jacobian(self._topology, self._springs, self._nodes, self._work,
                              self._places, self.h, data)

    def finish(self, phi0, new):
        return self.kernels.finish(self._step_start, self._topology, self._springs, self._nodes,
                                   self._work, self.u, phi0, plain(new))


HO4_INTEGRATOR = register_integrator(HO4())
