"""What a constitutive model is: scalar functions of one spring plus its parameter names.

A model is a free energy per spring ``F(l, θ)`` and the functions derived from it. Each function is
a Numba ``@njit`` scalar function with the signature ``f(l, s, l0, P, e)`` where ``l`` is the
spring length, ``s`` is the temperature θ or the entropy η (as the name says), ``l0`` the rest
length, ``P`` the ``(k, m)`` float64 array of per-spring parameters in the order of
``Model.parameters`` and ``e`` the spring's column of ``P`` (so ``P[0, e]`` is the first parameter of
the spring). ``e`` is the spring index, except when every spring has the same parameters: then the
explicit kernels pass a ``(k, 1)`` array and ``e = 0`` so that the parameters are read once, not
per spring. Use ``e`` only to index ``P``.
The kernels call these functions; they never name a model, so a user-defined model (see
``examples/custom_model.py``) runs in every integrator without editing any kernel.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

from ..errors import InputError, UnknownNameError


@dataclass(frozen=True, eq=False)
class Model:
    """A thermo-elastic spring law.

    Attributes
    ----------
    name: registry name.
    parameters: names of the per-spring parameters (rest length excluded; it belongs to the net).
    defaults: default values for some parameters.
    positive: parameters that must be > 0.
    free_energy: F(l, θ, l0, P, e).
    tension: T = ∂F/∂l (l, θ, l0, P, e).
    entropy: Γ = −∂F/∂θ (l, θ, l0, P, e).
    temperature: θ(l, η, l0, P, e), the inverse of Γ in θ.
    internal_energy: U(l, η, l0, P, e) = F + ηθ.
    d2F_dl2, d2F_dl_dtheta, d2F_dtheta2: second derivatives of F at (l, θ), for Newton.
    temperature_can_vanish: True when θ(l, η) may become ≤ 0 (a state the run must stop at).
    entropy_log_affine: True when Γ(l, θ) = a(l) + C ln θ with C a per-spring constant (model
        "hencky"): HO4's per-spring thermal equations then have a closed-form solution, which its
        kernels use instead of Newton corrections (and T = F_l is then affine in θ, which they
        use too). Leave False unless it holds exactly.
    reference_temperature: name of the parameter that is the reference temperature (used by a
        purely mechanical run, where every spring stays at it).
    energy_quotient: optional, (l, l1, η, θ, T, l0, P, e) -> (Q, ∂Q/∂l1) with Q = [U(l1, η) −
        U(l, η)] / (l1 − l), the divided difference EM2's discrete gradient is made of, given
        also θ = θ(l, η) and T = T(l, θ) (the kernels have them: a closed form need not recompute
        them); in closed form and accurate to a few ulps of T's terms for every l1, with nothing
        cancelling as l1 → l (where Q → T and ∂Q/∂l1 → half the adiabatic stiffness). Without
        it EM2 takes the quotient of two U values where l1 and l differ by more than 3 %, and a
        5-point Gauss–Lobatto rule on T within (four tension evaluations per spring and residual).
    strain, tension_at_strain: optional pair, ``strain(l, l0)`` the part of T(l, θ) that depends
        on the length alone and costs most (Hencky: L = ln(l/l0)), and
        ``tension_at_strain(L, l, θ, l0, P, e)`` T from it, equal bit for bit to
        ``tension(l, θ, l0, P, e)`` when ``L = strain(l, l0)``. With conduction the explicit
        kernel keeps L from the spring pass and, after the sweeps changed θ at fixed lengths,
        evaluates T without computing L again. Without them T is evaluated from l.
    """

    name: str
    parameters: tuple[str, ...]
    free_energy: Callable
    tension: Callable
    entropy: Callable
    temperature: Callable
    internal_energy: Callable
    d2F_dl2: Callable
    d2F_dl_dtheta: Callable
    d2F_dtheta2: Callable
    defaults: Mapping[str, float] = field(default_factory=dict)
    positive: tuple[str, ...] = ()
    temperature_can_vanish: bool = False
    entropy_log_affine: bool = False
    reference_temperature: str = "theta0"
    description: str = ""
    energy_quotient: Callable | None = None
    strain: Callable | None = None
    tension_at_strain: Callable | None = None

    def parameter_array(self, values: Mapping[str, object], n_springs: int) -> np.ndarray:
        """Per-spring parameters as a ``(k, m)`` float64 array (scalars are broadcast).

        Raises :class:`InputError` naming the parameter and the first offending spring for
        missing, unknown, non-finite or (where required) non-positive values.
        """
        unknown = set(values) - set(self.parameters)
        if unknown:
            raise InputError(
                f"model {self.name!r} has no parameter(s) {', '.join(sorted(unknown))}; "
                f"its parameters are {', '.join(self.parameters)}"
            )
        P = np.empty((len(self.parameters), n_springs), dtype=np.float64)
        for i, name in enumerate(self.parameters):
            if name in values:
                value = values[name]
            elif name in self.defaults:
                value = self.defaults[name]
            else:
                raise InputError(f"model {self.name!r}: parameter {name!r} is missing (no default)")
            try:
                arr = np.asarray(value, dtype=np.float64)
            except (TypeError, ValueError):
                raise InputError(f"model {self.name!r}: parameter {name!r} is not a number: {value!r}")
            if arr.ndim == 0:
                P[i] = arr
            elif arr.shape == (n_springs,):
                P[i] = arr
            else:
                raise InputError(
                    f"model {self.name!r}: parameter {name!r} must be a scalar or one value per "
                    f"spring ({n_springs}), got shape {arr.shape}"
                )
            bad = ~np.isfinite(P[i])
            if bad.any():
                e = int(np.flatnonzero(bad)[0])
                raise InputError(f"model {self.name!r}: parameter {name!r} of spring {e} is not finite ({P[i, e]})")
            if name in self.positive:
                bad = P[i] <= 0
                if bad.any():
                    e = int(np.flatnonzero(bad)[0])
                    raise InputError(
                        f"model {self.name!r}: parameter {name!r} must be > 0, spring {e} has {P[i, e]}"
                    )
        return P

    def parameter_index(self, name: str) -> int:
        return self.parameters.index(name)


_REGISTRY: dict[str, Model] = {}


def register_model(model: Model) -> Model:
    """Make ``model`` available by name (``Simulation(model=name)``, scene files)."""
    _REGISTRY[model.name] = model
    return model


def get_model(model: "Model | str") -> Model:
    """The model itself, or the registered model of that name."""
    if isinstance(model, Model):
        return model
    try:
        return _REGISTRY[str(model).lower()]
    except KeyError:
        raise UnknownNameError("model", str(model), _REGISTRY) from None


def available_models() -> list[str]:
    return sorted(_REGISTRY)
