"""Model "hencky": the paper's free energy (31), logarithmic (Hencky) strain L = ln(l/l0).

    F(l, θ) = c/2 L² − β (θ − θ0) L + C0 (θ − θ0 − θ ln(θ/θ0))

Per-spring parameters, in this order: ``c`` (elastic modulus), ``beta`` (thermo-mechanical
coupling), ``C0`` (heat capacity), ``theta0`` (reference temperature). θ(l, η) is an exponential,
so temperatures stay positive.

``exp`` and ``log`` are :mod:`thermonet.kernels.fastmath`'s (within about an ulp of libm's):
libm calls keep the explicit kernel's per-spring loop from vectorizing, and they were most of its
cost.
"""

from numba import njit

from ..kernels.fastmath import exp, log
from .base import Model, register_model

C, BETA, C0, THETA0 = 0, 1, 2, 3


@njit(inline="always", error_model="numpy")
def free_energy(l, theta, l0, P, e):
    L = log(l / l0)
    th0 = P[THETA0, e]
    return 0.5 * P[C, e] * L * L - P[BETA, e] * (theta - th0) * L + P[C0, e] * (theta - th0 - theta * log(theta / th0))


@njit(inline="always", error_model="numpy")
def tension(l, theta, l0, P, e):
    L = log(l / l0)
    return (P[C, e] * L - P[BETA, e] * (theta - P[THETA0, e])) / l


@njit(inline="always", error_model="numpy")
def entropy(l, theta, l0, P, e):
    return P[BETA, e] * log(l / l0) + P[C0, e] * log(theta / P[THETA0, e])


@njit(inline="always", error_model="numpy")
def temperature(l, eta, l0, P, e):
    L = log(l / l0)
    return P[THETA0, e] * exp((eta - P[BETA, e] * L) / P[C0, e])


@njit(inline="always", error_model="numpy")
def internal_energy(l, eta, l0, P, e):
    L = log(l / l0)
    th0 = P[THETA0, e]
    theta = th0 * exp((eta - P[BETA, e] * L) / P[C0, e])
    return 0.5 * P[C, e] * L * L + P[BETA, e] * th0 * L + P[C0, e] * (theta - th0)


@njit(inline="always", error_model="numpy")
def d2F_dl2(l, theta, l0, P, e):
    L = log(l / l0)
    c = P[C, e]
    return (c - c * L + P[BETA, e] * (theta - P[THETA0, e])) / (l * l)


@njit(inline="always", error_model="numpy")
def d2F_dl_dtheta(l, theta, l0, P, e):
    return -P[BETA, e] / l


@njit(inline="always", error_model="numpy")
def d2F_dtheta2(l, theta, l0, P, e):
    return -P[C0, e] / theta


HENCKY = register_model(
    Model(
        name="hencky",
        parameters=("c", "beta", "C0", "theta0"),
        free_energy=free_energy,
        tension=tension,
        entropy=entropy,
        temperature=temperature,
        internal_energy=internal_energy,
        d2F_dl2=d2F_dl2,
        d2F_dl_dtheta=d2F_dl_dtheta,
        d2F_dtheta2=d2F_dtheta2,
        defaults={"c": 100.0, "beta": 0.2, "C0": 5.0, "theta0": 300.0},
        positive=("c", "C0", "theta0"),
        temperature_can_vanish=False,
        entropy_log_affine=True,  # Γ = β ln(l/l0) + C0 ln(θ/θ0)
        description="paper (31): c/2 L² − β(θ−θ0)L + C0(θ−θ0−θ ln θ/θ0), L = ln(l/l0)",
    )
)
