"""GTR-α, the generalized trapezoidal rule (docs/theory.md §2.1, paper (45)–(48)), for any α in [0, 1].

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

from ...errors import InputError
from .kernels import GTRWork
from ..core.records import plain
from ...integrators.base import Integrator, register_integrator
from ..core.stepper import ImplicitStepper, newton_options


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

    def make_work(self, start) -> GTRWork:
        self.alpha = self.integrator.alpha
        return GTRWork.allocate(start)

    def predictor_coefficients(self, h: float) -> np.ndarray:
        """d = h M⁻¹ (p + α h f(x⁰, θ(l⁰, η))) = h v + α h² a: (48a) with θ̄ frozen at the start
        temperature, CO2's drift at α = ½ and the exact step at α = 0 or 1."""
        return np.array([[h, self.alpha * h * h, 0.0, 0.0]])

    def compiled_extra(self) -> tuple:
        return (self.alpha,)

    def residual(self, u: np.ndarray):
        status, spring, rmax, smax = self.kernels.residual(self._step_start, self._topology, self._springs,
                                                           self._nodes, self._work, self.alpha, u, self.warm,
                                                           self._residuals)
        self.norms = (rmax, smax)
        self.warm = status == 0
        return status, spring

    def linearize(self) -> None:
        self.kernels.linearize(self._springs, self._work, self.alpha, self.h)

    def apply_inverse_inertia(self, v):
        """(h/m) v per free node."""
        return (np.asarray(v).reshape(-1, 3) * (self.h / self.block_mass)[:, None]).ravel()

    def jacobian(self, data: np.ndarray) -> None:
        self.kernels.jacobian(self._topology, self._springs, self._nodes, self._work,
                              self._places, self.alpha, self.h, data)

    def finish(self, phi0, new):
        return self.kernels.finish(self._step_start, self._topology, self._springs, self._nodes,
                                   self._work, self.alpha, self.u, phi0, plain(new))


def gtr_alpha(alpha: float = 0.5) -> GTRAlpha:
    """Factory registered as "gtr-alpha": ``get_integrator("gtr-alpha", alpha=0.3)``."""
    return GTRAlpha(alpha)


GTR_HALF = register_integrator(GTRAlpha(0.5), "gtr-1/2")
register_integrator(GTR_HALF, "gtr-half")
register_integrator(gtr_alpha, "gtr-alpha")
