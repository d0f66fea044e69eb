"""GTR-α, the generalized trapezoidal rule (spec §2.1, paper (45)–(48)), for any α in [0, 1].

One step finds x¹ and the mean temperature θ̄ = (Φ¹ − Φ⁰)/h of every spring from

    p^k = M (x¹ − x⁰)/h − α h f(x⁰, θ̄)                       (48a)
    η^k = α Γ(l(x⁰), θ̄) + (1 − α) Γ(l(x¹), θ̄)     per spring (48c)

by Newton's method on the displacements d = x¹ − x⁰, θ̄ condensed per spring (exact: (48c)
involves one spring's θ̄ only). Then Φ¹ = Φ⁰ + h θ̄, the entropy is *measured* by (48d) on the
converged unknowns, and p¹ from (48b). Second order at α = ½ (``gtr-1/2``), first order
otherwise; α = 0 and 1 reproduce the explicit ``gtr-0`` and ``gtr-1`` to round-off.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .base import Integrator, register_integrator
from .implicit import ImplicitStepper, newton_options


class GTRAlpha(Integrator):
    """The implicit GTR-α integrator with parameter ``alpha`` in [0, 1]."""

    explicit = False

    def __init__(self, alpha: float = 0.5):
        try:
            alpha = float(alpha)
        except (TypeError, ValueError):
            raise InputError(f"gtr-alpha: alpha must be a number in [0, 1], got {alpha!r}") from None
        if not 0.0 <= alpha <= 1.0:
            raise InputError(f"gtr-alpha: alpha must be in [0, 1], got {alpha}")
        self.alpha = alpha
        self.order = 2 if alpha == 0.5 else 1
        self.name = "gtr-1/2" if alpha == 0.5 else f"gtr-alpha({alpha:g})"
        self.description = (f"generalized trapezoidal rule, α = {alpha:g}, implicit in (x¹, θ̄), "
                            f"order {self.order}, paper (48)")

    def make_stepper(self, system, parallel: bool = False, **options) -> "GTRAlphaStepper":
        return GTRAlphaStepper(self, system, newton_options(options), parallel)


class GTRAlphaStepper(ImplicitStepper):
    """GTR-α bound to a system: 3 unknowns (the displacement) per free node."""

    block = 3
    scheme = "gtr"

    def _allocate(self, n: int, m: int) -> None:
        self.alpha = self.integrator.alpha
        self.len1 = np.empty(m)
        self.dir1 = np.empty((3, m))
        self.theta = np.empty(m)
        self.dtheta = np.empty(m)
        self.jc = np.empty(m)

    def predictor_coefficients(self, h: float) -> np.ndarray:
        """d = h M⁻¹ (p + α h f(x⁰, θ(l⁰, η))) = h v + α h² a: (48a) with θ̄ frozen at the start
        temperature, CO2's drift at α = ½ and the exact step at α = 0 or 1."""
        return np.array([[h, self.alpha * h * h, 0.0, 0.0]])

    def residual(self, u: np.ndarray):
        s = self.system
        status, spring, rmax, smax = self.kernels.residual(
            self.x0, u, self.p0, self.eta0, s.rest_lengths, self.P, self.edges_u, self.free_index, *self.incidence,
            s.masses, self.alpha, self.h, self.gravity, self.with_gravity, self.len0, self.dir0, self.len1,
            self.dir1, self.theta, self.dtheta, self.warm, self.fs, self.guess, self.code, self.R, self.Rabs,
        )
        self.norms = (rmax, smax)
        self.warm = status == 0
        return status, spring

    def linearize(self) -> None:
        s = self.system
        self.kernels.linearize(self.alpha, self.h, s.rest_lengths, self.P, self.len0, self.theta, self.dtheta,
                               self.jc)

    def sweep(self, du, rhs, r, update, first=False):
        return self.sweeper(du, rhs, r, self.sweep_w, self.jc, self.dir0, self.dir1, self.ends,
                            self.free_index, *self.incidence, self.system.masses, self.h, update, first)

    def apply_inverse_inertia(self, v):
        """(h/m) v per free node."""
        return (np.asarray(v).reshape(-1, 3) * (self.h / self.block_mass)[:, None]).ravel()

    def jacobian(self, data: np.ndarray) -> None:
        s, p = self.system, self.pattern
        self.kernels.jacobian(
            self.free_index, s.masses, self.alpha, self.h, s.rest_lengths, self.P, s.edges, self.len0,
            self.dir0, self.dir1, self.theta, self.dtheta, p.node_base, p.node_stride, p.spring_base,
            p.spring_stride, data,
        )

    def finish(self, phi0, x_new, p_new, phi_new, eta_new):
        s = self.system
        return self.kernels.finish(
            self.x0, self.u, self.p0, phi0, self.eta0, s.rest_lengths, self.P, self.edges_u, self.free_index,
            *self.incidence, s.masses, self.alpha, self.h, self.gravity, self.with_gravity, self.len0, self.dir0,
            self.len1, self.dir1, self.theta, self.fs, self.code, x_new, p_new, phi_new, eta_new,
        )


def gtr_alpha(alpha: float = 0.5) -> GTRAlpha:
    """Factory registered as "gtr-alpha": ``get_integrator("gtr-alpha", alpha=0.3)``."""
    return GTRAlpha(alpha)


GTR_HALF = register_integrator(GTRAlpha(0.5), "gtr-1/2")
register_integrator(GTR_HALF, "gtr-half")
register_integrator(gtr_alpha, "gtr-alpha")
