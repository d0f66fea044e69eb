"""HO4: quadratic trajectories in x and Φ with Lobatto quadrature (spec §2.2, paper (53)–(59)),
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

import numpy as np

from .base import Integrator, register_integrator
from .implicit import ImplicitStepper, newton_options


class HO4(Integrator):
    """The fourth-order implicit integrator of the paper (§4.4)."""

    name = "ho4"
    order = 4
    explicit = False
    description = "quadratic trajectories + Lobatto quadrature (Lobatto IIIA-IIIB), implicit, paper (58)"

    def make_stepper(self, system, parallel: bool = False, **options) -> "HO4Stepper":
        return HO4Stepper(self, system, newton_options(options))


class HO4Stepper(ImplicitStepper):
    """HO4 bound to a system: 6 unknowns (d^½, d¹) per free node."""

    block = 6
    scheme = "ho4"

    def _allocate(self, n: int, m: int) -> None:
        self.lenh = np.empty(m)
        self.dirh = np.empty((m, 3))
        self.len1 = np.empty(m)
        self.dir1 = np.empty((m, 3))
        self.th0 = np.empty(m)
        self.th1 = np.empty(m)
        self.dth = np.empty((m, 4))

    def predict(self, u: np.ndarray) -> None:
        """d¹ from a CO2 step; d^½ from the quadratic through x⁰ with velocity p/m and x¹."""
        s, h, a = self.system, self.h, self._free_nodes
        force = self.f0[a] + (s.masses[a, None] * self.gravity if self.with_gravity else 0.0)
        v0 = s.inv_mass[a, None] * self.p0[a]
        d1 = h * (v0 + 0.5 * h * s.inv_mass[a, None] * force)
        blocks = u.reshape(-1, 6)
        blocks[self._free_blocks, 3:] = d1
        blocks[self._free_blocks, :3] = 0.25 * d1 + 0.25 * h * v0

    def residual(self, u: np.ndarray):
        s = self.system
        return self.kernels.residual(
            self.x0, u, self.p0, self.eta0, s.rest_lengths, s.parameters, s.edges, self.free_index, s.masses,
            self.h, self.gravity, self.with_gravity, self.len0, self.dir0, self.lenh, self.dirh, self.len1,
            self.dir1, self.th0, self.th1, self.dth, self.R, self.Rabs,
        )

    def jacobian(self, data: np.ndarray) -> None:
        s, p = self.system, self.pattern
        self.kernels.jacobian(
            self.free_index, s.masses, self.h, s.rest_lengths, s.parameters, s.edges, self.len0, self.dir0,
            self.lenh, self.dirh, self.dir1, self.th0, self.th1, self.dth, p.node_base, p.node_stride,
            p.spring_base, p.spring_stride, data,
        )

    def finish(self, phi0, x_new, p_new, phi_new, eta_new):
        s = self.system
        return self.kernels.finish(
            self.x0, self.u, self.p0, phi0, self.eta0, s.rest_lengths, s.parameters, s.edges, self.free_index,
            s.masses, self.h, self.gravity, self.with_gravity, self.len0, self.dir0, self.lenh, self.dirh,
            self.len1, self.dir1, self.th0, self.th1, x_new, p_new, phi_new, eta_new,
        )


HO4_INTEGRATOR = register_integrator(HO4())
