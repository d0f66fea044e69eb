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
- Large nets (≥ ``MATFREE_MIN_SPRINGS`` springs) never assemble K: a fixed number
  (``LANCZOS_STEPS``) of plain Lanczos steps with a matrix-free product, and the Gershgorin bound
  from per-spring row sums; both cost a few passes over the springs. A Ritz value never exceeds
  the true λ_max, so this estimate errs towards a larger h_max (the step policy's safety fraction
  covers the little it may miss; see docs/robustness.md).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numba import njit
from scipy.sparse.linalg import ArpackNoConvergence, eigsh

from .diagnostics import spring_fields
from .integrators.base import get_integrator
from .kernels.springs import map_springs

#: the implicit integrators' stability intervals, measured on a linear spring (h·ω), used when an
#: integrator does not declare ``stability_interval`` itself (tests/test_hard_cases.py re-measures
#: them; docs/robustness.md has the table). GTR-α's discrete Euler–Lagrange equations of a purely
#: mechanical spring are central differences for every α, hence 2; HO4's limit is where the trace
#: of its step matrix on the oscillator reaches −2 (2√2 in closed form, measured 2.828).
MEASURED_INTERVALS: dict[str, float] = {"gtr-1/2": 2.0, "gtr-alpha": 2.0, "ho4": 2.8284}

#: from this many springs on, ω_max is estimated without assembling the stiffness matrix
MATFREE_MIN_SPRINGS = 100_000
#: Lanczos steps of the matrix-free estimate
LANCZOS_STEPS = 40


def splitting_stability_interval(kicks, drifts, hw_max: float = 20.0, resolution: int = 20000) -> float:
    """Largest h·ω below which the splitting ``K(k0) D(d0) … K(k_S)`` is stable on ẍ = −ω²x.

    Scans h·ω upward and returns the first point where |trace of the step matrix| exceeds 2,
    refined by bisection. Computed once per coefficients in a process (the scan costs tens of ms
    in Python, and every Simulation's run guards ask).
    """
    return _splitting_interval(tuple(float(k) for k in np.ravel(kicks)), tuple(float(d) for d in np.ravel(drifts)),
                               float(hw_max), int(resolution))


@functools.lru_cache(maxsize=None)
def _splitting_interval(kicks: tuple, drifts: tuple, hw_max: float, resolution: int) -> float:
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
    for key in (integrator.name, integrator.name.split("(")[0]):  # "gtr-alpha(0.3)" -> "gtr-alpha"
        if key in MEASURED_INTERVALS:
            return MEASURED_INTERVALS[key]
    return float("inf")


def spring_stiffness(system, positions: np.ndarray, entropy: np.ndarray | None):
    """Per-spring stiffness parts: axial (m,) = dT/dl at fixed η, geometric (m,) = T/l and unit
    vectors n (m, 3); spring e's 3×3 block is axial n⊗n + geometric (I − n⊗n)."""
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
    return axial, T / l, n_vec


def stiffness_matrix(system, positions: np.ndarray, entropy: np.ndarray | None) -> sp.csr_matrix:
    """(3n, 3n) adiabatic stiffness K = ∂²H/∂x² at fixed η (internal numbering, all nodes)."""
    return _assemble(system, *spring_stiffness(system, positions, entropy))


def _assemble(system, axial, geometric, n_vec) -> sp.csr_matrix:
    edges = system.edges
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
    parts = spring_stiffness(system, positions, entropy)
    bad = ~(np.isfinite(parts[0]) & np.isfinite(parts[1]))
    if bad.any():  # e.g. β²θ/C0 overflowing: no frequency to speak of (reported, not raised)
        e = int(system.layout.spring_order[np.flatnonzero(bad)[0]])
        return FrequencyEstimate(float("inf"), float("inf"), f"non-finite stiffness of spring {e}")
    if system.n_springs >= MATFREE_MIN_SPRINGS:
        return _matfree_frequency(system, *parts)
    K = _assemble(system, *parts)
    free3 = np.repeat(~system.anchored, 3)
    w = 1.0 / np.sqrt(np.repeat(system.masses, 3)[free3])
    A = sp.diags(w) @ K[free3][:, free3] @ sp.diags(w)
    A = 0.5 * (A + A.T)
    if not np.isfinite(A.data).all():  # finite per spring, but their sum at a node overflows
        return FrequencyEstimate(float("inf"), float("inf"), "stiffness overflows the float range")
    gersh = float(np.max(np.abs(A).sum(axis=1))) if A.shape[0] else 0.0
    if A.shape[0] == 0:
        return FrequencyEstimate(0.0, 0.0, "no free nodes")
    if A.shape[0] <= 200:
        lam = float(np.linalg.eigvalsh(A.toarray()).max())
        method = "dense eigenvalues"
    else:
        try:
            v0 = np.random.default_rng(0).standard_normal(A.shape[0])  # seeded: the same estimate every call
            lam = float(eigsh(A, k=1, which="LA", tol=1e-4, maxiter=2000, v0=v0, return_eigenvectors=False)[0])
            method = "Lanczos (scipy eigsh)"
        except ArpackNoConvergence:
            lam = gersh
            method = "Gershgorin bound (Lanczos did not converge)"
    return FrequencyEstimate(float(np.sqrt(max(lam, 0.0))), float(np.sqrt(gersh)), method)


@njit(cache=True)
def _stiffness_product(edges, axial, geometric, n_vec, w, v, out):
    """out += W K W v for (n, 3) v; spring e adds k_e (u_b − u_a) at b and subtracts it at a."""
    for e in range(edges.shape[0]):
        a, b = edges[e, 0], edges[e, 1]
        wa, wb = w[a], w[b]
        d0 = wb * v[b, 0] - wa * v[a, 0]
        d1 = wb * v[b, 1] - wa * v[a, 1]
        d2 = wb * v[b, 2] - wa * v[a, 2]
        n0, n1, n2 = n_vec[e, 0], n_vec[e, 1], n_vec[e, 2]
        s = (axial[e] - geometric[e]) * (n0 * d0 + n1 * d1 + n2 * d2)
        g = geometric[e]
        f0, f1, f2 = g * d0 + s * n0, g * d1 + s * n1, g * d2 + s * n2
        out[b, 0] += wb * f0
        out[b, 1] += wb * f1
        out[b, 2] += wb * f2
        out[a, 0] -= wa * f0
        out[a, 1] -= wa * f1
        out[a, 2] -= wa * f2


@njit(cache=True)
def _gershgorin_rows(edges, axial, geometric, n_vec, w):
    """(n, 3) Gershgorin radii of W K W: row (a, r) sums |k_e[r, s]| (w_a² + w_a w_b) over the
    springs at a (a bound: a node's diagonal block is not summed before taking magnitudes)."""
    out = np.zeros((w.shape[0], 3))
    for e in range(edges.shape[0]):
        a, b = edges[e, 0], edges[e, 1]
        cross = w[a] * w[b]
        sh = axial[e] - geometric[e]
        for r in range(3):
            row = 0.0
            for c in range(3):
                k = sh * n_vec[e, r] * n_vec[e, c] + (geometric[e] if r == c else 0.0)
                row += abs(k)
            out[a, r] += row * (w[a] * w[a] + cross)
            out[b, r] += row * (w[b] * w[b] + cross)
    return out


def _matfree_frequency(system, axial, geometric, n_vec, steps: int = LANCZOS_STEPS) -> FrequencyEstimate:
    """ω_max by ``steps`` plain Lanczos steps on W K W (W = M^{-1/2} on free nodes, 0 on anchored
    ones) applied spring by spring, and the Gershgorin bound from per-spring absolute row sums.
    Memory: a few (n, 3) vectors; no reorthogonalization (only the largest Ritz value is used,
    and it stays inside the spectrum)."""
    edges = system.edges
    w = np.where(system.anchored, 0.0, 1.0 / np.sqrt(system.masses))
    if not w.any():
        return FrequencyEstimate(0.0, 0.0, "no free nodes")
    n = system.n_nodes
    gersh = float(_gershgorin_rows(edges, axial, geometric, n_vec, w).max())

    def apply(v):  # (n, 3) -> W K W v
        out = np.zeros_like(v)
        _stiffness_product(edges, axial, geometric, n_vec, w, v, out)
        return out

    q = np.random.default_rng(0).standard_normal((n, 3)) * (w > 0)[:, None]
    q /= np.linalg.norm(q)
    q_prev = np.zeros_like(q)
    alphas, betas = [], []
    beta = 0.0
    for _ in range(min(steps, 3 * int((w > 0).sum()))):
        r = apply(q) - beta * q_prev
        alpha = float(np.vdot(q, r))
        r -= alpha * q
        alphas.append(alpha)
        beta = float(np.linalg.norm(r))
        if beta <= 1e-12 * max(abs(alpha), 1e-300):
            break
        betas.append(beta)
        q_prev, q = q, r / beta
    k = len(alphas)
    T = np.diag(alphas) + np.diag(betas[: k - 1], 1) + np.diag(betas[: k - 1], -1)
    if not (np.isfinite(gersh) and np.isfinite(alphas).all() and np.isfinite(betas).all()):
        return FrequencyEstimate(float("inf"), float("inf"), "stiffness overflows the float range")
    lam = float(np.linalg.eigvalsh(T).max())
    return FrequencyEstimate(float(np.sqrt(max(lam, 0.0))), float(np.sqrt(gersh)),
                             f"Lanczos ({k} matrix-free steps)")


def wave_frequency(sim, bound_only: bool = False) -> float:
    """ω_W, the fastest frequency of the Green–Naghdi thermal waves at the current temperatures
    (0 without them): linearized at fixed positions, ``Φ̈_e = θ̇_e = −(θ_e / C_e) Σ_f k*_ef (Φ_e − Φ_f)``,
    so ω_W² is the largest eigenvalue of ``D^½ L* D^½``, D = diag(θ/C), L* the k*-Laplacian of
    the spring pairs. Their flow is a third sub-flow of the splitting with its own limit
    h ω_W < c. ``bound_only``: the Gershgorin bound ``√(max_e d_e Σ_f k*_ef (d_e + max d))``,
    d = √(θ/C), instead."""
    heat = sim.system.heat
    if heat is None or not heat.waves or heat.graph.n_pairs == 0:
        return 0.0
    g = heat.graph
    k = g.kappa[:, 1]
    m = len(heat.capacity)
    theta = sim.internal_spring_fields().temperature
    d = np.sqrt(np.maximum(theta, 0.0) / heat.capacity)
    degree = np.bincount(g.first, weights=k, minlength=m) + np.bincount(g.second, weights=k, minlength=m)
    if bound_only or m > 200:
        bound = float(np.max(d * degree * (d + d.max())))
        if bound_only:
            return float(np.sqrt(bound))
    L = sp.coo_matrix((np.concatenate([-k, -k, degree]),
                       (np.concatenate([g.first, g.second, np.arange(m)]),
                        np.concatenate([g.second, g.first, np.arange(m)]))), shape=(m, m)).tocsr()
    A = sp.diags(d) @ L @ sp.diags(d)
    if m <= 200:
        lam = float(np.linalg.eigvalsh(A.toarray()).max())
    else:
        try:
            v0 = np.random.default_rng(0).standard_normal(m)
            lam = float(eigsh(A, k=1, which="LA", tol=1e-4, maxiter=2000, v0=v0, return_eigenvectors=False)[0])
        except ArpackNoConvergence:
            lam = bound
    return float(np.sqrt(max(lam, 0.0)))


def stable_step(sim, integrator=None) -> dict:
    """The stable step limit of ``integrator`` (default: the simulation's) at the current state.

    Returns a dict with omega_max, gershgorin_bound (an upper bound on ω_max), interval (c),
    h_max = c / max(ω_max, ω_W) and the estimate's method; omega_waves: ω_W of the thermal waves
    (:func:`wave_frequency`, 0 without them) and limit: which of the two sets h_max.
    """
    integ = sim.integrator if integrator is None else get_integrator(integrator)

    def estimate():
        s = sim.internal_state()
        return max_frequency(sim.system, s.positions, s.entropy), wave_frequency(sim)

    # (over MPI processes estimated by rank 0 on the whole state, given to every process)
    est, omega_w = sim.on_root(estimate) if hasattr(sim, "on_root") else estimate()
    c = stability_interval(integ)
    omega = max(est.omega_max, omega_w)
    h_max = float(c / omega) if omega > 0 else float("inf")
    return {
        "integrator": integ.name,
        "omega_max": est.omega_max,
        "gershgorin_bound": est.gershgorin_bound,
        "interval": c,
        "h_max": h_max,
        "method": est.method,
        "omega_waves": omega_w,
        "limit": "thermal waves" if omega_w > est.omega_max else "mechanical",
    }
