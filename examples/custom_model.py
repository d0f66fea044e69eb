"""A user-defined constitutive model, run without touching any thermonet kernel.

The law: the paper's Hencky spring (Mata & Lew 2011, (31)) whose stiffness softens as it heats,
c(θ) = c (1 − a (θ − θ0)/θ0). With L = ln(l/l0) and Δθ = θ − θ0:

    F(l, θ) = c(θ)/2 L² − β Δθ L + C0 (Δθ − θ ln(θ/θ0))
    T       = ∂F/∂l  = (c(θ) L − β Δθ) / l
    Γ       = −∂F/∂θ = a c/(2 θ0) L² + β L + C0 ln(θ/θ0)
    θ(l, η) = θ0 exp((η − β L − a c/(2 θ0) L²) / C0)      (Γ is monotone in θ, so this inverts it)
    U       = F + η θ

Each function is a Numba ``@njit`` scalar function ``f(l, s, l0, P, e)``: length, temperature or
entropy, rest length, the (k, m) parameter array (rows in the order of ``parameters``) and the
spring index. Run it with ``python examples/custom_model.py``.
"""

import math

import numpy as np
from numba import njit

import thermonet as tn

C, SOFTENING, BETA, C0, THETA0 = range(5)


@njit
def stiffness(theta, P, e):
    return P[C, e] * (1.0 - P[SOFTENING, e] * (theta - P[THETA0, e]) / P[THETA0, e])


@njit
def free_energy(l, theta, l0, P, e):
    L = math.log(l / l0)
    dtheta = theta - P[THETA0, e]
    return (0.5 * stiffness(theta, P, e) * L * L - P[BETA, e] * dtheta * L
            + P[C0, e] * (dtheta - theta * math.log(theta / P[THETA0, e])))


@njit
def tension(l, theta, l0, P, e):
    L = math.log(l / l0)
    return (stiffness(theta, P, e) * L - P[BETA, e] * (theta - P[THETA0, e])) / l


@njit
def entropy(l, theta, l0, P, e):
    L = math.log(l / l0)
    return (0.5 * P[SOFTENING, e] * P[C, e] / P[THETA0, e] * L * L + P[BETA, e] * L
            + P[C0, e] * math.log(theta / P[THETA0, e]))


@njit
def temperature(l, eta, l0, P, e):
    L = math.log(l / l0)
    latent = 0.5 * P[SOFTENING, e] * P[C, e] / P[THETA0, e] * L * L + P[BETA, e] * L
    return P[THETA0, e] * math.exp((eta - latent) / P[C0, e])


@njit
def internal_energy(l, eta, l0, P, e):
    theta = temperature(l, eta, l0, P, e)
    return free_energy(l, theta, l0, P, e) + eta * theta


@njit
def d2F_dl2(l, theta, l0, P, e):
    L = math.log(l / l0)
    c = stiffness(theta, P, e)
    return (c - c * L + P[BETA, e] * (theta - P[THETA0, e])) / (l * l)


@njit
def d2F_dl_dtheta(l, theta, l0, P, e):
    dc_dtheta = -P[C, e] * P[SOFTENING, e] / P[THETA0, e]
    return (dc_dtheta * math.log(l / l0) - P[BETA, e]) / l


@njit
def d2F_dtheta2(l, theta, l0, P, e):
    return -P[C0, e] / theta


SOFTENING_HENCKY = tn.Model(
    name="softening-hencky",
    parameters=("c", "softening", "beta", "C0", "theta0"),
    free_energy=free_energy, tension=tension, entropy=entropy, temperature=temperature,
    internal_energy=internal_energy, d2F_dl2=d2F_dl2, d2F_dl_dtheta=d2F_dl_dtheta, d2F_dtheta2=d2F_dtheta2,
    defaults={"c": 100.0, "softening": 0.05, "beta": 0.2, "C0": 5.0, "theta0": 300.0},
    positive=("c", "C0", "theta0"),
    description="Hencky spring whose stiffness softens linearly with temperature",
)


def build_simulation(integrator="co2", h=2e-3):
    """A free-floating 3×3×2 lattice of cells (18 neighbours), hot in the middle, shaken."""
    net = tn.lattice((3, 3, 2), neighbours=18, jitter=0.1, seed=3)
    velocities = np.random.default_rng(3).normal(0.0, 0.5, (net.n_nodes, 3))
    midpoints = 0.5 * (net.positions[net.edges[:, 0]] + net.positions[net.edges[:, 1]])
    temperatures = 300.0 + 500.0 * np.exp(-np.sum((midpoints - [1.5, 1.5, 1.0]) ** 2, axis=1))
    return tn.Simulation(net, model=SOFTENING_HENCKY, parameters={"softening": 0.05}, temperatures=temperatures,
                         velocities=velocities, integrator=integrator, h=h)


if __name__ == "__main__":
    sim = build_simulation()
    sim.run(t_end=10.0, diagnostics_every=50)
    print(f"{sim!r}")
    print(f"{'quantity':<10}{'initial':>16}{'max deviation':>16}{'relative':>12}")
    for name, row in sim.conservation_summary().items():
        if not name.startswith("_"):
            print(f"{name:<10}{row['initial']:>16.8g}{row['max_deviation']:>16.3e}{row['relative']:>12.2e}")
    print(f"temperatures now: {sim.temperatures().min():.1f} .. {sim.temperatures().max():.1f}")
