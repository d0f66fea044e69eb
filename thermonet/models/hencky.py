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

from ..kernels.fastmath import exp, exprel, log, log_ratio
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
def strain(l, l0):
    return log(l / l0)


@njit(inline="always", error_model="numpy")
def tension_at_strain(L, l, theta, l0, P, e):
    """:func:`tension` with its L = :func:`strain` (l, l0) given: the same operations."""
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
def energy_quotient(l, l1, eta, theta, T, l0, P, e):
    """Q = [U(l1, η) − U(l, η)] / (l1 − l) and ∂Q/∂l1 (EM2's discrete gradient; θ = θ(l, η),
    T = T(l, θ): Model doc), in closed form with nothing cancelling as l1 → l. With u = l1/l,
    D = ln u = (u − 1) G(u) the change of L and x = −β D / C0 (θ(l1, η) = θ eˣ):

        ΔU = D B,  B = l T + c D/2 − β θ (φ(x) − 1),   Q = G(u) B / l,
        ∂Q/∂l1 = [G'(u) B + G(u) (c/2 + β²/C0 θ φ'(x)) / u] / l²

    with G(u) = ln u/(u − 1) and φ(x) = (eˣ − 1)/x and their derivatives from
    :mod:`thermonet.kernels.fastmath` (Q → T and ∂Q/∂l1 → half the adiabatic stiffness as
    l1 → l)."""
    c = P[C, e]
    b = P[BETA, e]
    cv = P[C0, e]
    u = l1 / l
    G, dG = log_ratio(u)
    D = (u - 1.0) * G
    phi, dphi = exprel(-b * D / cv)
    B = l * T + 0.5 * c * D - b * theta * (phi - 1.0)
    return G * B / l, (dG * B + G * (0.5 * c + b * b / cv * theta * dphi) / u) / (l * l)


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
        energy_quotient=energy_quotient,
        strain=strain,
        tension_at_strain=tension_at_strain,
        defaults={"c": 100.0, "beta": 0.2, "C0": 5.0, "theta0": 300.0},
        positive=("c", "C0", "theta0"),
        temperature_can_vanish=False,
        entropy_log_affine=True,  # Γ = β ln(l/l0) + C0 ln(θ/θ0)
        description="paper (31): c/2 L² − β(θ−θ0)L + C0(θ−θ0−θ ln θ/θ0), L = ln(l/l0)",
    )
)
