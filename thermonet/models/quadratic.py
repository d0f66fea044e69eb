"""Model "quadratic": the paper's free energy (26), the thermo-elastic pendulum's spring.

    F(l, θ) = E/(2 l0) d² − β (θ − θ0) d − C0/(2 θ0) (θ − θ0)² − (θ − θ0) η0,   d = l − l0

Per-spring parameters, in this order: ``E``, ``beta``, ``C0``, ``theta0``, ``eta0`` (reference
entropy). θ(l, η) is affine in η and can reach zero or below: the run must stop there.
"""

from numba import njit

from .base import Model, register_model

E_, BETA, C0, THETA0, ETA0 = 0, 1, 2, 3, 4


@njit(inline="always", error_model="numpy")
def free_energy(l, theta, l0, P, e):
    d = l - l0
    dth = theta - P[THETA0, e]
    return 0.5 * P[E_, e] / l0 * d * d - P[BETA, e] * dth * d - 0.5 * P[C0, e] / P[THETA0, e] * dth * dth - dth * P[ETA0, e]


@njit(inline="always", error_model="numpy")
def tension(l, theta, l0, P, e):
    return P[E_, e] / l0 * (l - l0) - P[BETA, e] * (theta - P[THETA0, e])


@njit(inline="always", error_model="numpy")
def entropy(l, theta, l0, P, e):
    return P[C0, e] / P[THETA0, e] * (theta - P[THETA0, e]) + P[BETA, e] * (l - l0) + P[ETA0, e]


@njit(inline="always", error_model="numpy")
def temperature(l, eta, l0, P, e):
    th0 = P[THETA0, e]
    return th0 + th0 / P[C0, e] * (eta - P[ETA0, e] - P[BETA, e] * (l - l0))


@njit(inline="always", error_model="numpy")
def internal_energy(l, eta, l0, P, e):
    d = l - l0
    th0 = P[THETA0, e]
    r = eta - P[ETA0, e] - P[BETA, e] * d
    return 0.5 * P[E_, e] / l0 * d * d + 0.5 * th0 / P[C0, e] * r * r + eta * th0


@njit(inline="always", error_model="numpy")
def energy_quotient(l, l1, eta, theta, T, l0, P, e):
    """Q = [U(l1, η) − U(l, η)] / (l1 − l) and ∂Q/∂l1 (EM2's discrete gradient, Model doc): U is
    quadratic in l at fixed η, so Q is U's slope at the mean length (E (l̄ − l0)/l0 − β θ0/C0 r̄,
    r = η − η0 − β (l − l0)), and ∂Q/∂l1 half its constant curvature."""
    th0 = P[THETA0, e]
    b = P[BETA, e]
    dm = 0.5 * (l + l1) - l0
    return (P[E_, e] / l0 * dm - b * th0 / P[C0, e] * (eta - P[ETA0, e] - b * dm),
            0.5 * (P[E_, e] / l0 + b * b * th0 / P[C0, e]))


@njit(inline="always", error_model="numpy")
def d2F_dl2(l, theta, l0, P, e):
    return P[E_, e] / l0


@njit(inline="always", error_model="numpy")
def d2F_dl_dtheta(l, theta, l0, P, e):
    return -P[BETA, e]


@njit(inline="always", error_model="numpy")
def d2F_dtheta2(l, theta, l0, P, e):
    return -P[C0, e] / P[THETA0, e]


QUADRATIC = register_model(
    Model(
        name="quadratic",
        parameters=("E", "beta", "C0", "theta0", "eta0"),
        free_energy=free_energy,
        tension=tension,
        entropy=entropy,
        temperature=temperature,
        internal_energy=internal_energy,
        d2F_dl2=d2F_dl2,
        d2F_dl_dtheta=d2F_dl_dtheta,
        d2F_dtheta2=d2F_dtheta2,
        energy_quotient=energy_quotient,
        defaults={"E": 100.0, "beta": 0.2, "C0": 5.0, "theta0": 300.0, "eta0": 0.0},
        positive=("E", "C0", "theta0"),
        temperature_can_vanish=True,
        description="paper (26): E/(2l0) d² − β(θ−θ0)d − C0/(2θ0)(θ−θ0)² − (θ−θ0)η0, d = l − l0",
    )
)
