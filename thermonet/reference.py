"""A plain NumPy reference implementation of the physics and the explicit integrators.

Everything here is written directly from the paper's equations (Mata & Lew 2011) with vectorized
per-spring arithmetic and a ``np.bincount`` scatter, in the user's numbering, with no Numba and
no shared code with the kernels: the model laws are NumPy formulas of their own (the paper's (31) and (26)),
not the engine's scalar functions. It is the yardstick the kernels are tested against, the
right-hand side of Hamilton's equations for a tight SciPy reference solution, and the NumPy
baseline the benchmarks time.

A :class:`ReferenceNet` holds what does not change; a step maps a :class:`ReferenceState` to a
new one (inputs are never modified).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

from .explicit.splitting import YOSHIDA4, YOSHIDA6A

# ---------------------------------------------------------------------------------------------
# constitutive laws, as NumPy formulas (Mata & Lew 2011, (31) and (26)). Every function takes (m,) arrays
# and a mapping of (m,) parameter arrays and returns (m,).


class HenckyLaw:
    """docs/theory.md §1.2, with L = ln(l/l0)."""

    parameters = ("c", "beta", "C0", "theta0")

    @staticmethod
    def free_energy(l, theta, l0, P):
        L = np.log(l / l0)
        th0 = P["theta0"]
        return 0.5 * P["c"] * L**2 - P["beta"] * (theta - th0) * L + P["C0"] * (theta - th0 - theta * np.log(theta / th0))

    @staticmethod
    def tension(l, theta, l0, P):
        return (P["c"] * np.log(l / l0) - P["beta"] * (theta - P["theta0"])) / l

    @staticmethod
    def entropy(l, theta, l0, P):
        return P["beta"] * np.log(l / l0) + P["C0"] * np.log(theta / P["theta0"])

    @staticmethod
    def temperature(l, eta, l0, P):
        return P["theta0"] * np.exp((eta - P["beta"] * np.log(l / l0)) / P["C0"])

    @staticmethod
    def internal_energy(l, eta, l0, P):
        L = np.log(l / l0)
        theta = P["theta0"] * np.exp((eta - P["beta"] * L) / P["C0"])
        return 0.5 * P["c"] * L**2 + P["beta"] * P["theta0"] * L + P["C0"] * (theta - P["theta0"])

    @staticmethod
    def d2F_dl2(l, theta, l0, P):
        L = np.log(l / l0)
        return (P["c"] - P["c"] * L + P["beta"] * (theta - P["theta0"])) / l**2

    @staticmethod
    def d2F_dl_dtheta(l, theta, l0, P):
        return -P["beta"] / l

    @staticmethod
    def d2F_dtheta2(l, theta, l0, P):
        return -P["C0"] / theta


class QuadraticLaw:
    """docs/theory.md §1.3, with d = l − l0."""

    parameters = ("E", "beta", "C0", "theta0", "eta0")

    @staticmethod
    def free_energy(l, theta, l0, P):
        d, dth = l - l0, theta - P["theta0"]
        return 0.5 * P["E"] / l0 * d**2 - P["beta"] * dth * d - 0.5 * P["C0"] / P["theta0"] * dth**2 - dth * P["eta0"]

    @staticmethod
    def tension(l, theta, l0, P):
        return P["E"] / l0 * (l - l0) - P["beta"] * (theta - P["theta0"])

    @staticmethod
    def entropy(l, theta, l0, P):
        return P["C0"] / P["theta0"] * (theta - P["theta0"]) + P["beta"] * (l - l0) + P["eta0"]

    @staticmethod
    def temperature(l, eta, l0, P):
        return P["theta0"] + P["theta0"] / P["C0"] * (eta - P["eta0"] - P["beta"] * (l - l0))

    @staticmethod
    def internal_energy(l, eta, l0, P):
        d = l - l0
        r = eta - P["eta0"] - P["beta"] * d
        return 0.5 * P["E"] / l0 * d**2 + 0.5 * P["theta0"] / P["C0"] * r**2 + eta * P["theta0"]

    @staticmethod
    def d2F_dl2(l, theta, l0, P):
        return P["E"] / l0 * np.ones_like(l)

    @staticmethod
    def d2F_dl_dtheta(l, theta, l0, P):
        return -P["beta"] * np.ones_like(l)

    @staticmethod
    def d2F_dtheta2(l, theta, l0, P):
        return -P["C0"] / P["theta0"] * np.ones_like(l)


LAWS = {"hencky": HenckyLaw, "quadratic": QuadraticLaw}


# ---------------------------------------------------------------------------------------------
# the net and the state


@dataclass(frozen=True)
class ReferenceNet:
    """A spring net with its constitutive law, in the user's numbering.

    edges: (m, 2) int, node indices of each spring. rest_lengths: (m,). masses: (n,).
    anchored: (n,) bool. law: one of :data:`LAWS` (or any object with the same functions).
    parameters: name -> (m,) float64 per-spring parameters.
    """

    edges: np.ndarray
    rest_lengths: np.ndarray
    masses: np.ndarray
    anchored: np.ndarray
    law: type
    parameters: Mapping[str, np.ndarray]

    @classmethod
    def build(cls, net, model: str, parameters: Mapping[str, object] | None = None) -> "ReferenceNet":
        """From a :class:`thermonet.Net`, a model name and its parameters (scalars or (m,);
        missing ones take the models' default values)."""
        law = LAWS[model]
        defaults = {"c": 100.0, "E": 100.0, "beta": 0.2, "C0": 5.0, "theta0": 300.0, "eta0": 0.0}
        values = {**defaults, **(parameters or {})}
        m = net.n_springs
        P = {k: np.broadcast_to(np.asarray(values[k], dtype=np.float64), (m,)).copy() for k in law.parameters}
        return cls(np.asarray(net.edges), np.asarray(net.rest_lengths, dtype=np.float64),
                   np.asarray(net.masses, dtype=np.float64), np.asarray(net.anchored, dtype=bool), law, P)

    @property
    def free(self) -> np.ndarray:
        return ~self.anchored

    # -- per-spring fields -------------------------------------------------------------------
    def spring_vectors(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """d = x_b − x_a (m, 3) and l = |d| (m,) at positions x (n, 3)."""
        d = x[self.edges[:, 1]] - x[self.edges[:, 0]]
        return d, np.sqrt(np.einsum("ij,ij->i", d, d))

    def lengths(self, x: np.ndarray) -> np.ndarray:
        return self.spring_vectors(x)[1]

    def entropies(self, x: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """(m,) η = Γ(l(x), θ) = −∂F/∂θ: the initial entropies (Mata & Lew 2011, (11))."""
        return self.law.entropy(self.lengths(x), theta, self.rest_lengths, self.parameters)

    def temperatures(self, x: np.ndarray, eta: np.ndarray) -> np.ndarray:
        """(m,) θ(l(x), η)."""
        return self.law.temperature(self.lengths(x), eta, self.rest_lengths, self.parameters)

    def tensions(self, x: np.ndarray, eta: np.ndarray) -> np.ndarray:
        """(m,) T(l, θ(l, η)) at positions x."""
        l = self.lengths(x)
        theta = self.law.temperature(l, eta, self.rest_lengths, self.parameters)
        return self.law.tension(l, theta, self.rest_lengths, self.parameters)

    # -- node forces and temperatures together: one "force evaluation" ----------------------
    def forces_and_temperatures(self, x: np.ndarray, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """f_η(x) (n, 3), zero on anchored nodes, and θ(l(x), η) (m,).

        Spring e = (a, b) pulls a by +T n and b by −T n, n = (x_b − x_a)/l.
        """
        d, l = self.spring_vectors(x)
        theta = self.law.temperature(l, eta, self.rest_lengths, self.parameters)
        pull = (self.law.tension(l, theta, self.rest_lengths, self.parameters) / l)[:, None] * d
        n = len(x)
        a, b = self.edges[:, 0], self.edges[:, 1]
        f = np.empty((n, 3))
        for k in range(3):
            f[:, k] = np.bincount(a, pull[:, k], minlength=n) - np.bincount(b, pull[:, k], minlength=n)
        f[self.anchored] = 0.0
        return f, theta

    def forces(self, x: np.ndarray, eta: np.ndarray) -> np.ndarray:
        """f_η(x) = −∇_x Σ U(l_e, η_e), (n, 3), zero on anchored nodes."""
        return self.forces_and_temperatures(x, eta)[0]

    # -- conserved quantities ------------------------------------------------------------------
    def energy(self, x: np.ndarray, p: np.ndarray, eta: np.ndarray) -> float:
        """H = Σ |p|²/2m + Σ U(l, η) (Mata & Lew 2011, (17)), free nodes only."""
        free = self.free
        kinetic = 0.5 * np.sum(np.einsum("ij,ij->i", p[free], p[free]) / self.masses[free])
        internal = np.sum(self.law.internal_energy(self.lengths(x), eta, self.rest_lengths, self.parameters))
        return float(kinetic + internal)

    def linear_momentum(self, p: np.ndarray) -> np.ndarray:
        return p[self.free].sum(axis=0)

    def angular_momentum(self, x: np.ndarray, p: np.ndarray, about=(0.0, 0.0, 0.0)) -> np.ndarray:
        return np.cross(x[self.free] - np.asarray(about), p[self.free]).sum(axis=0)


@dataclass(frozen=True)
class ReferenceState:
    """x, p: (n, 3); phi (Φ), eta (η): (m,)."""

    x: np.ndarray
    p: np.ndarray
    phi: np.ndarray
    eta: np.ndarray


# ---------------------------------------------------------------------------------------------
# one step of each explicit integrator, formula by formula from the paper's (51), (52), (64)–(66), (41)–(44)


def _velocity(net: ReferenceNet, p: np.ndarray) -> np.ndarray:
    v = p / net.masses[:, None]
    v[net.anchored] = 0.0
    return v


def gtr0_step(net: ReferenceNet, s: ReferenceState, h: float) -> ReferenceState:
    """GTR-0, paper (51): x¹ = x⁰ + h M⁻¹p⁰; θ̄ = θ(l(x¹), η); Φ¹ = Φ⁰ + hθ̄; p¹ = p⁰ + h f(x¹, θ̄)."""
    x1 = s.x + h * _velocity(net, s.p)
    f1, theta_bar = net.forces_and_temperatures(x1, s.eta)
    return ReferenceState(x1, s.p + h * f1, s.phi + h * theta_bar, s.eta)


def gtr1_step(net: ReferenceNet, s: ReferenceState, h: float) -> ReferenceState:
    """GTR-1, paper (52): θ̄ = θ(l(x⁰), η); Φ¹ = Φ⁰ + hθ̄; p¹ = p⁰ + h f(x⁰, θ̄); x¹ = x⁰ + h M⁻¹p¹."""
    f0, theta_bar = net.forces_and_temperatures(s.x, s.eta)
    p1 = s.p + h * f0
    return ReferenceState(s.x + h * _velocity(net, p1), p1, s.phi + h * theta_bar, s.eta)


def co2_step(net: ReferenceNet, s: ReferenceState, h: float) -> ReferenceState:
    """CO2 = F01, paper (64)/(66): GTR-1 half step, then GTR-0 half step (kick–drift–kick)."""
    f0, theta0 = net.forces_and_temperatures(s.x, s.eta)
    phi_half = s.phi + 0.5 * h * theta0
    p_half = s.p + 0.5 * h * f0
    x1 = s.x + h * _velocity(net, p_half)
    f1, theta1 = net.forces_and_temperatures(x1, s.eta)
    return ReferenceState(x1, p_half + 0.5 * h * f1, phi_half + 0.5 * h * theta1, s.eta)


def f10_step(net: ReferenceNet, s: ReferenceState, h: float) -> ReferenceState:
    """F10, paper (65): GTR-0 half step, then GTR-1 half step (drift–kick–drift). Both half
    steps evaluate force and temperature at the same midpoint positions."""
    x_half = s.x + 0.5 * h * _velocity(net, s.p)
    f_half, theta_half = net.forces_and_temperatures(x_half, s.eta)
    # GTR-0 half step ends at the midpoint with p += h/2 f, Φ += h/2 θ; GTR-1 starts there.
    p_quarter = s.p + 0.5 * h * f_half
    phi_half = s.phi + 0.5 * h * theta_half
    p1 = p_quarter + 0.5 * h * f_half
    return ReferenceState(x_half + 0.5 * h * _velocity(net, p1), p1, phi_half + 0.5 * h * theta_half, s.eta)


def nm2_step(net: ReferenceNet, s: ReferenceState, h: float) -> ReferenceState:
    """NM2, §4.2: velocity Verlet in its Newmark form on H(x, p; η) with η a parameter,
    x¹ = x⁰ + h v⁰ + h²/2 a⁰, v¹ = v⁰ + h/2 (a⁰ + a¹). Φ is not tracked (returned unchanged)."""
    v0 = _velocity(net, s.p)
    a0 = _velocity(net, net.forces(s.x, s.eta))
    x1 = s.x + h * v0 + 0.5 * h * h * a0
    a1 = _velocity(net, net.forces(x1, s.eta))
    v1 = v0 + 0.5 * h * (a0 + a1)
    return ReferenceState(x1, v1 * net.masses[:, None], s.phi, s.eta)


def composition_step(gammas) -> Callable[[ReferenceNet, ReferenceState, float], ReferenceState]:
    """The symmetric composition CO2(γ₁h) ∘ … ∘ CO2(γ_s h)."""
    gammas = tuple(float(g) for g in gammas)

    def step(net: ReferenceNet, s: ReferenceState, h: float) -> ReferenceState:
        for g in gammas:
            s = co2_step(net, s, g * h)
        return s

    step.__doc__ = f"composition of CO2 with coefficients {gammas}"
    return step


def splitting_step(kicks, drifts) -> Callable[[ReferenceNet, ReferenceState, float], ReferenceState]:
    """Any kick/drift table ``K(k_0) D(d_0) K(k_1) … D(d_{S−1}) K(k_S)`` (kicks: (S+1,), drifts:
    (S,), fractions of h), written from the paper's (64)–(66) two sub-steps: a kick of c·h sets
    p += c h f_η(x), Φ += c h θ(l(x), η); a drift of d·h sets x += d h M⁻¹p. Zero kicks are
    skipped (they change nothing). For the optimized tables (BM4, BM6, BM6A, OMF4), checked against
    the kernels, which read the same table."""
    kicks = tuple(float(k) for k in kicks)
    drifts = tuple(float(d) for d in drifts)
    assert len(kicks) == len(drifts) + 1

    def step(net: ReferenceNet, s: ReferenceState, h: float) -> ReferenceState:
        x, p, phi = s.x.copy(), s.p.copy(), s.phi.copy()
        for i, c in enumerate(kicks):
            if c != 0.0:
                f, theta = net.forces_and_temperatures(x, s.eta)
                p = p + c * h * f
                phi = phi + c * h * theta
            if i < len(drifts):
                x = x + drifts[i] * h * _velocity(net, p)
        return ReferenceState(x, p, phi, s.eta)

    step.__doc__ = f"kick/drift splitting with kicks {kicks} and drifts {drifts}"
    return step


def _yoshida():
    return YOSHIDA4, YOSHIDA6A


def steps() -> dict[str, Callable[[ReferenceNet, ReferenceState, float], ReferenceState]]:
    """Reference step functions by integrator name."""
    y4, y6 = _yoshida()
    return {
        "gtr-0": gtr0_step, "gtr-1": gtr1_step, "co2": co2_step, "f01": co2_step, "f10": f10_step,
        "nm2": nm2_step, "co4": composition_step(y4), "co6": composition_step(y6),
    }


def run(net: ReferenceNet, state: ReferenceState, step, h: float, n_steps: int) -> ReferenceState:
    """``n_steps`` steps of ``step`` (a function from :func:`steps` or its name)."""
    if isinstance(step, str):
        step = steps()[step]
    for _ in range(n_steps):
        state = step(net, state, h)
    return state


# ---------------------------------------------------------------------------------------------
# Hamilton's equations (Mata & Lew 2011, (18)) for SciPy's solve_ivp


class HamiltonRHS:
    """ẋ = M⁻¹p, ṗ = f_η(x), Φ̇ = θ(l(x), η), η̇ = 0, for the free nodes.

    The ODE state is y = [x_free (3k), p_free (3k), Φ (m)] with k free nodes (row-major); anchored
    nodes keep the positions of ``x_anchor`` (n, 3).
    """

    def __init__(self, net: ReferenceNet, x_anchor: np.ndarray, eta: np.ndarray):
        self.net = net
        self.eta = np.asarray(eta, dtype=np.float64)
        self.x_full = np.array(x_anchor, dtype=np.float64)
        self.free = net.free
        self.k = int(self.free.sum())
        self.inv_mass = 1.0 / net.masses[self.free]

    def pack(self, x: np.ndarray, p: np.ndarray, phi: np.ndarray) -> np.ndarray:
        return np.concatenate([x[self.free].ravel(), p[self.free].ravel(), phi])

    def unpack(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x (n, 3), p (n, 3), Φ (m,)) from y; anchors at their fixed positions, zero momentum."""
        k3 = 3 * self.k
        x = self.x_full.copy()
        x[self.free] = y[:k3].reshape(-1, 3)
        p = np.zeros_like(x)
        p[self.free] = y[k3:2 * k3].reshape(-1, 3)
        return x, p, y[2 * k3:].copy()

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        k3 = 3 * self.k
        x = self.x_full.copy()
        x[self.free] = y[:k3].reshape(-1, 3)
        p_free = y[k3:2 * k3].reshape(-1, 3)
        f, theta = self.net.forces_and_temperatures(x, self.eta)
        return np.concatenate([(p_free * self.inv_mass[:, None]).ravel(), f[self.free].ravel(), theta])


def hamilton_solution(net: ReferenceNet, state: ReferenceState, t_end: float, rtol: float = 1e-13,
                      atol: float = 1e-13, method: str = "DOP853") -> ReferenceState:
    """The state at ``t_end`` from Hamilton's equations, integrated by ``solve_ivp``."""
    from scipy.integrate import solve_ivp

    rhs = HamiltonRHS(net, state.x, state.eta)
    sol = solve_ivp(rhs, (0.0, t_end), rhs.pack(state.x, state.p, state.phi), method=method, rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f"solve_ivp failed: {sol.message}")
    x, p, phi = rhs.unpack(sol.y[:, -1])
    return ReferenceState(x, p, phi, state.eta.copy())


__all__ = [
    "HenckyLaw", "QuadraticLaw", "LAWS", "ReferenceNet", "ReferenceState", "gtr0_step", "gtr1_step",
    "co2_step", "f10_step", "nm2_step", "composition_step", "splitting_step", "steps", "run", "HamiltonRHS",
    "hamilton_solution",
]
