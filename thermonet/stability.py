"""Stable time steps of the explicit integrators.

The step limit of an integrator is ``h_max = c / ω_max`` where ω_max is the largest angular
frequency of the net linearized at the current state and ``c`` the integrator's stability
interval on the harmonic oscillator (its largest h·ω with bounded energy).

- ``c`` of a kick/drift splitting follows exactly from its coefficients: one step of the
  oscillator ẍ = −ω²x is a 2×2 matrix of determinant 1, bounded iff |trace| ≤ 2
  (:func:`splitting_stability_interval`). CO2, GTR-0 and GTR-1 all give 2.
- ω_max² is the largest eigenvalue of M⁻¹K, K the stiffness of the free nodes at fixed
  entropies (adiabatic stiffness): per spring an axial term ``dT/dl|η = F_ll − F_lθ²/F_θθ`` along
  the spring and a geometric term ``T/l`` across it. It is found with a few Lanczos iterations
  (SciPy ``eigsh``) on the symmetric M^{-1/2} K M^{-1/2}; the Gershgorin bound (rigorous, cheap,
  pessimistic) is used when Lanczos does not converge and is always reported alongside.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import ArpackNoConvergence, eigsh

from .diagnostics import spring_fields
from .kernels.springs import map_springs

#: the implicit integrators' stability intervals, measured on a linear spring (h·ω), used when an
#: integrator does not declare ``stability_interval`` itself.
MEASURED_INTERVALS: dict[str, float] = {}


def splitting_stability_interval(kicks, drifts, hw_max: float = 20.0, resolution: int = 20000) -> float:
    """Largest h·ω below which the splitting ``K(k0) D(d0) … K(k_S)`` is stable on ẍ = −ω²x.

    Scans h·ω upward and returns the first point where |trace of the step matrix| exceeds 2,
    refined by bisection.
    """
    kicks = np.asarray(kicks, dtype=np.float64)
    drifts = np.asarray(drifts, dtype=np.float64)

    def trace(hw: float) -> float:
        # unit mass and ω: state (x, p); kick p −= k hw² x... written with q = x, v = p/ω, τ = hω
        M = np.eye(2)
        for i, d in enumerate(drifts):
            M = np.array([[1.0, 0.0], [-kicks[i] * hw, 1.0]]) @ M
            M = np.array([[1.0, d * hw], [0.0, 1.0]]) @ M
        M = np.array([[1.0, 0.0], [-kicks[-1] * hw, 1.0]]) @ M
        return float(np.trace(M))

    grid = np.linspace(0.0, hw_max, resolution)[1:]
    lo = 0.0
    for hw in grid:
        if abs(trace(hw)) > 2.0:
            hi = hw
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                if abs(trace(mid)) > 2.0:
                    hi = mid
                else:
                    lo = mid
            return lo
        lo = hw
    return float("inf")


def stability_interval(integrator) -> float:
    """The integrator's stability interval c (h_max = c / ω_max)."""
    declared = getattr(integrator, "stability_interval", None)
    if declared is not None:
        return float(declared)
    if hasattr(integrator, "kicks") and hasattr(integrator, "drifts"):
        return float(splitting_stability_interval(integrator.kicks, integrator.drifts))
    if integrator.name in MEASURED_INTERVALS:
        return MEASURED_INTERVALS[integrator.name]
    return float("inf")


def stiffness_matrix(system, positions: np.ndarray, entropy: np.ndarray | None) -> sp.csr_matrix:
    """(3n, 3n) adiabatic stiffness K = ∂²H/∂x² at fixed η (internal numbering, all nodes)."""
    fields = spring_fields(system, positions, entropy)
    l, theta, T = fields.length, fields.temperature, fields.tension
    l0, P = system.rest_lengths, system.parameters
    m = system.n_springs
    F_ll = np.empty(m)
    map_springs(system.model, "d2F_dl2")(l, theta, l0, P, F_ll)
    axial = F_ll
    if system.thermal:
        F_lt = np.empty(m)
        F_tt = np.empty(m)
        map_springs(system.model, "d2F_dl_dtheta")(l, theta, l0, P, F_lt)
        map_springs(system.model, "d2F_dtheta2")(l, theta, l0, P, F_tt)
        axial = F_ll - F_lt * F_lt / F_tt
    edges = system.edges
    n_vec = (positions[edges[:, 1]] - positions[edges[:, 0]]) / l[:, None]
    geometric = T / l
    # per-spring 3x3 block k = axial n⊗n + geometric (I − n⊗n); K_aa += k, K_bb += k, K_ab = K_ba −= k
    nn = n_vec[:, :, None] * n_vec[:, None, :]
    block = axial[:, None, None] * nn + geometric[:, None, None] * (np.eye(3)[None] - nn)
    a, b = edges[:, 0].astype(np.int64), edges[:, 1].astype(np.int64)
    rows, cols, vals = [], [], []
    ii, jj = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
    for (u, v, sign) in ((a, a, 1.0), (b, b, 1.0), (a, b, -1.0), (b, a, -1.0)):
        rows.append((3 * u[:, None, None] + ii[None]).ravel())
        cols.append((3 * v[:, None, None] + jj[None]).ravel())
        vals.append((sign * block).ravel())
    n3 = 3 * system.n_nodes
    return sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n3, n3)).tocsr()


@dataclass
class FrequencyEstimate:
    """Largest angular frequency of the linearized net: Lanczos estimate and Gershgorin bound."""

    omega_max: float
    gershgorin_bound: float
    method: str


def max_frequency(system, positions: np.ndarray, entropy: np.ndarray | None) -> FrequencyEstimate:
    """ω_max of the free nodes of ``system`` linearized at ``positions`` (internal numbering)."""
    K = stiffness_matrix(system, positions, entropy)
    free3 = np.repeat(~system.anchored, 3)
    w = 1.0 / np.sqrt(np.repeat(system.masses, 3)[free3])
    A = sp.diags(w) @ K[free3][:, free3] @ sp.diags(w)
    A = 0.5 * (A + A.T)
    gersh = float(np.max(np.abs(A).sum(axis=1))) if A.shape[0] else 0.0
    if A.shape[0] == 0:
        return FrequencyEstimate(0.0, 0.0, "no free nodes")
    if A.shape[0] <= 200:
        lam = float(np.linalg.eigvalsh(A.toarray()).max())
        method = "dense eigenvalues"
    else:
        try:
            lam = float(eigsh(A, k=1, which="LA", tol=1e-4, maxiter=2000, return_eigenvectors=False)[0])
            method = "Lanczos (scipy eigsh)"
        except ArpackNoConvergence:
            lam = gersh
            method = "Gershgorin bound (Lanczos did not converge)"
    return FrequencyEstimate(float(np.sqrt(max(lam, 0.0))), float(np.sqrt(gersh)), method)


def stable_step(sim, integrator=None) -> dict:
    """The stable step limit of ``integrator`` (default: the simulation's) at the current state.

    Returns a dict with omega_max, gershgorin_bound (an upper bound on ω_max), interval (c),
    h_max = c / ω_max and the estimate's method.
    """
    from .integrators import get_integrator

    integ = sim.integrator if integrator is None else get_integrator(integrator)
    s = sim._host_state()
    est = max_frequency(sim.system, s.positions, s.entropy)
    c = stability_interval(integ)
    h_max = float(c / est.omega_max) if est.omega_max > 0 else float("inf")
    return {
        "integrator": integ.name,
        "omega_max": est.omega_max,
        "gershgorin_bound": est.gershgorin_bound,
        "interval": c,
        "h_max": h_max,
        "method": est.method,
    }
