"""Numba templates for the implicit integrators' step equations (spec §2.1 GTR-α, §2.2 HO4):
the mechanical residuals, the values of their exact sparse Jacobian, and the update that
turns converged unknowns into the next state.

The unknowns are per free node: the displacement over the step ``d = x¹ − x⁰`` for GTR-α
(block of 3), and ``d^½ = x^½ − x⁰, d¹ = x¹ − x⁰`` for HO4 (block of 6). Working with
displacements, not positions, keeps the inertial terms ``M d / h`` free of the cancellation
``M (x¹ − x⁰) / h`` would suffer at small h. Block k of the unknown vector ``u`` belongs to the
node ``a`` with ``free_index[a] == k``; anchored nodes have ``free_index == −1`` and no unknowns.

The thermal unknowns (θ̄ for GTR-α; θ⁰, θ¹ — equivalently Φ^½, Φ¹ — for HO4) enter only the
equations of their own spring, so each residual evaluation solves them exactly (to round-off)
per spring given the spring's lengths, and the Jacobian carries their derivatives with respect
to those lengths (implicit function theorem). This condensation is exact: the converged step
satisfies every equation of the monolithic system.

Residual rows are in momentum units. Next to the residual ``R`` a kernel fills ``Rabs``, the sum
of the magnitudes of the terms of each row, so the Newton test can judge ``|R|`` against the size
of what cancelled in it (its round-off floor is then a few ulps).

Per-spring Jacobian blocks are scattered into a CSR value array: for spring e = (a, b) the
``spring_base[e, q]`` (q = aa, ab, ba, bb) is the data index of the block's (0, 0) entry and
``spring_stride[e, q]`` the distance between its rows; −1 where an end is anchored. Nodal mass
blocks use ``node_base``/``node_stride``. Status codes returned by residual and finish kernels:
0 fine, 1 a spring collapsed (length ≤ 0 or not finite), 2 no positive finite temperature solves
the spring's thermal equations, 3 a non-finite momentum or entropy; with the spring's index.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .specialize import model_fingerprint, model_namespace, specialize

# Bound per model by specialize(); listed so the templates read as ordinary code.
entropy = temperature = tension = d2F_dl2 = d2F_dl_dtheta = d2F_dtheta2 = None
gtr_thermal = ho4_thermal = None

_CACHE: dict = {}
_OPTIONS = dict(cache=True, error_model="numpy", boundscheck=False)

#: relative change of a temperature at which a per-spring Newton solve has reached round-off
THETA_ROUNDOFF = 8 * 2.220446049250313e-16
#: a per-spring solve whose last relative correction exceeds this did not converge
THETA_FAILED = 1e-10
LOCAL_ITERATIONS = 60

OK, COLLAPSED, NO_TEMPERATURE, NOT_FINITE = 0, 1, 2, 3
STATUS_TEXT = {
    COLLAPSED: "spring collapsed (length not positive or not finite)",
    NO_TEMPERATURE: "no positive finite temperature solves the spring's thermal equations",
    NOT_FINITE: "non-finite momentum or entropy after the step",
}


class ImplicitKernels:
    """The compiled kernels of one scheme for one model (attributes: the kernel functions)."""

    def __init__(self, **kernels):
        self.__dict__.update(kernels)


def implicit_kernels(model, scheme: str) -> ImplicitKernels:
    """Kernels for ``scheme`` ("gtr" or "ho4") compiled for ``model`` (cached on disk)."""
    key = (scheme, model_fingerprint(model))
    if key not in _CACHE:
        tag = f"{model.name}_{key[1]}"
        ns = model_namespace(model)
        start = specialize(_start, tag, ns, **_OPTIONS)
        if scheme == "gtr":
            ns["gtr_thermal"] = specialize(_gtr_thermal, tag, ns, **_OPTIONS)
            _CACHE[key] = ImplicitKernels(
                start=start,
                residual=specialize(_gtr_residual, tag, ns, **_OPTIONS),
                jacobian=specialize(_gtr_jacobian, tag, ns, **_OPTIONS),
                finish=specialize(_gtr_finish, tag, ns, **_OPTIONS),
            )
        elif scheme == "ho4":
            ns["ho4_thermal"] = specialize(_ho4_thermal, tag, ns, **_OPTIONS)
            _CACHE[key] = ImplicitKernels(
                start=start,
                residual=specialize(_ho4_residual, tag, ns, **_OPTIONS),
                jacobian=specialize(_ho4_jacobian, tag, ns, **_OPTIONS),
                finish=specialize(_ho4_finish, tag, ns, **_OPTIONS),
            )
        else:
            raise ValueError(f"unknown implicit scheme {scheme!r}")
    return _CACHE[key]


# ---------------------------------------------------------------------------------------------
# shared

# The per-spring thermal solves are Newton's method in ln θ (the θ-Newton correction δθ applied
# as θ ← θ exp(−δθ/θ)): temperatures stay positive without step halving, and for an entropy
# that is affine in ln θ (model "hencky") it is exact in one step.
MAX_LOG_STEP = 20.0


@njit(cache=True, inline="always")
def _log_step(s):
    """Newton correction of ln θ, bounded so exp() cannot overflow on a wild iterate."""
    if s > MAX_LOG_STEP:
        return MAX_LOG_STEP
    if s < -MAX_LOG_STEP:
        return -MAX_LOG_STEP
    return s


def _start(x0, eta, l0, P, edges, len0, dir0, f0):
    """Lengths len0 (m,) and unit vectors dir0 (m, 3) at x0 (n, 3), and the spring forces
    f0 (n, 3) at (x0, θ(l0, η)), the explicit force a predictor uses. Returns (status, spring)."""
    f0[:, :] = 0.0
    for e in range(edges.shape[0]):
        a = edges[e, 0]
        b = edges[e, 1]
        dx = x0[b, 0] - x0[a, 0]
        dy = x0[b, 1] - x0[a, 1]
        dz = x0[b, 2] - x0[a, 2]
        l = math.sqrt(dx * dx + dy * dy + dz * dz)
        if not (l > 0.0 and l < math.inf):
            return 1, e
        len0[e] = l
        dir0[e, 0] = dx / l
        dir0[e, 1] = dy / l
        dir0[e, 2] = dz / l
        th = temperature(l, eta[e], l0[e], P, e)
        if not (th > 0.0 and th < math.inf):
            return 2, e
        T = tension(l, th, l0[e], P, e)
        for i in range(3):
            v = T * dir0[e, i]
            f0[a, i] += v
            f0[b, i] -= v
    return 0, -1


# ---------------------------------------------------------------------------------------------
# GTR-α (spec §2.1): unknown d = x¹ − x⁰ per free node; θ̄ condensed per spring.
#   R_c = m_c d_c / h − α h f_c(x⁰, θ̄) − p_c                                         (48a)
#   α Γ(l⁰, θ̄) + (1 − α) Γ(l¹, θ̄) = η                                     per spring (48c)


def _gtr_thermal(la, lb, eta, l0, P, e, alpha):
    """θ̄ with α Γ(la, θ̄) + (1 − α) Γ(lb, θ̄) = η, its derivative dθ̄/dlb, and success.

    Newton in ln θ from θ(α la + (1 − α) lb, η), which is the answer itself when α is 0 or 1."""
    beta = 1.0 - alpha
    th = temperature(alpha * la + beta * lb, eta, l0, P, e)
    if not (th > 0.0 and th < math.inf):
        return th, 0.0, False
    change = 0.0
    for _ in range(LOCAL_ITERATIONS):
        G = alpha * entropy(la, th, l0, P, e) + beta * entropy(lb, th, l0, P, e) - eta
        Gt = -(alpha * d2F_dtheta2(la, th, l0, P, e) + beta * d2F_dtheta2(lb, th, l0, P, e))
        step = _log_step(G / (Gt * th))
        th = th * math.exp(-step)
        change = abs(step)
        if change <= THETA_ROUNDOFF:
            break
    if not (th > 0.0 and th < math.inf and change <= THETA_FAILED):
        return th, 0.0, False
    Gt = -(alpha * d2F_dtheta2(la, th, l0, P, e) + beta * d2F_dtheta2(lb, th, l0, P, e))
    return th, beta * d2F_dl_dtheta(lb, th, l0, P, e) / Gt, True


def _gtr_residual(x0, u, p, eta, l0, P, edges, free_index, masses, alpha, h, gravity, with_gravity,
                  len0, dir0, len1, dir1, theta, dtheta, R, Rabs):
    """R, Rabs (3 n_free,) at unknowns u (3 n_free,); fills len1 (m,), dir1 (m, 3), θ̄ and
    dθ̄/dl¹ (m,) for the Jacobian and the finish. Returns (status, spring)."""
    for a in range(x0.shape[0]):
        k = free_index[a]
        if k < 0:
            continue
        w = masses[a] / h
        for i in range(3):
            inertia = w * u[3 * k + i]
            g = alpha * h * masses[a] * gravity[i] if with_gravity else 0.0
            R[3 * k + i] = inertia - p[a, i] - g
            Rabs[3 * k + i] = abs(inertia) + abs(p[a, i]) + abs(g)
    for e in range(edges.shape[0]):
        a = edges[e, 0]
        b = edges[e, 1]
        ka = free_index[a]
        kb = free_index[b]
        dx = x0[b, 0] - x0[a, 0]
        dy = x0[b, 1] - x0[a, 1]
        dz = x0[b, 2] - x0[a, 2]
        if kb >= 0:
            dx += u[3 * kb]
            dy += u[3 * kb + 1]
            dz += u[3 * kb + 2]
        if ka >= 0:
            dx -= u[3 * ka]
            dy -= u[3 * ka + 1]
            dz -= u[3 * ka + 2]
        l1 = math.sqrt(dx * dx + dy * dy + dz * dz)
        if not (l1 > 0.0 and l1 < math.inf):
            return 1, e
        len1[e] = l1
        dir1[e, 0] = dx / l1
        dir1[e, 1] = dy / l1
        dir1[e, 2] = dz / l1
        th, dth, ok = gtr_thermal(len0[e], l1, eta[e], l0[e], P, e, alpha)
        if not ok:
            return 2, e
        theta[e] = th
        dtheta[e] = dth
        c = alpha * h * tension(len0[e], th, l0[e], P, e)
        for i in range(3):
            v = c * dir0[e, i]
            if ka >= 0:
                R[3 * ka + i] -= v
                Rabs[3 * ka + i] += abs(v)
            if kb >= 0:
                R[3 * kb + i] += v
                Rabs[3 * kb + i] += abs(v)
    return 0, -1


def _gtr_jacobian(free_index, masses, alpha, h, l0, P, edges, len0, dir0, dir1, theta, dtheta,
                  node_base, node_stride, spring_base, spring_stride, data):
    """Values of ∂R/∂u at the last residual's point into the CSR value array ``data``.

    ∂R_c/∂d_g = δ_cg m_c/h I + α h s_c s_g F_lθ(l⁰, θ̄) (dθ̄/dl¹) n⁰ n¹ᵀ, s_a = +1, s_b = −1."""
    data[:] = 0.0
    for a in range(free_index.shape[0]):
        k = free_index[a]
        if k < 0:
            continue
        w = masses[a] / h
        for i in range(3):
            data[node_base[k] + i * node_stride[k] + i] += w
    B = np.zeros((3, 3))
    for e in range(edges.shape[0]):
        c = alpha * h * d2F_dl_dtheta(len0[e], theta[e], l0[e], P, e) * dtheta[e]
        if c == 0.0:
            continue
        for i in range(3):
            for j in range(3):
                B[i, j] = c * dir0[e, i] * dir1[e, j]
        for q in range(4):
            base = spring_base[e, q]
            if base < 0:
                continue
            sign = 1.0 if (q == 0 or q == 3) else -1.0
            stride = spring_stride[e, q]
            for i in range(3):
                for j in range(3):
                    data[base + i * stride + j] += sign * B[i, j]


def _gtr_finish(x0, u, p, phi, eta, l0, P, edges, free_index, masses, alpha, h, gravity, with_gravity,
                len0, dir0, len1, dir1, theta, x_new, p_new, phi_new, eta_new):
    """The next state from converged unknowns: x¹ = x⁰ + d; Φ¹ = Φ⁰ + h θ̄;
    η¹ = α Γ(l⁰, θ̄) + (1 − α) Γ(l¹, θ̄) measured (48d); and
    p¹ = p⁰ + h [α f(x⁰, θ̄) + (1 − α) f(x¹, θ̄)], which is (48b) given (48a) and, forces being
    central pairs, conserves linear momentum to round-off whatever the solver residual.
    Returns (status, spring)."""
    for a in range(x0.shape[0]):
        k = free_index[a]
        for i in range(3):
            if k < 0:
                x_new[a, i] = x0[a, i]
                p_new[a, i] = p[a, i]
            else:
                x_new[a, i] = x0[a, i] + u[3 * k + i]
                p_new[a, i] = p[a, i] + (h * masses[a] * gravity[i] if with_gravity else 0.0)
    for e in range(edges.shape[0]):
        a = edges[e, 0]
        b = edges[e, 1]
        th = theta[e]
        phi_new[e] = phi[e] + h * th
        eta1 = alpha * entropy(len0[e], th, l0[e], P, e) + (1.0 - alpha) * entropy(len1[e], th, l0[e], P, e)
        eta_new[e] = eta1
        if not (abs(eta1) < math.inf):
            return 3, e
        th1 = temperature(len1[e], eta1, l0[e], P, e)
        if not (th1 > 0.0 and th1 < math.inf):
            return 2, e
        c0 = alpha * h * tension(len0[e], th, l0[e], P, e)
        c1 = (1.0 - alpha) * h * tension(len1[e], th, l0[e], P, e)
        free_a = free_index[a] >= 0
        free_b = free_index[b] >= 0
        for i in range(3):
            v = c0 * dir0[e, i] + c1 * dir1[e, i]
            if free_a:
                p_new[a, i] += v
            if free_b:
                p_new[b, i] -= v
    for a in range(x0.shape[0]):
        for i in range(3):
            if not (abs(p_new[a, i]) < math.inf):
                return 3, -1
    return 0, -1


# ---------------------------------------------------------------------------------------------
# HO4 (spec §2.2): unknowns d^½, d¹ per free node; θ⁰, θ¹ condensed per spring (θ^½ = mean).
#   R1_c = m_c (8 d^½ − d¹)_c / (3h) − (h/6) f⁰_c − p_c                                 (58a)
#   R2_c = m_c (d¹ − 2 d^½)_c / h − (h/4) f^½_c                              (57a) × h/4
#   Γ⁰ = Γ¹,  (3Γ⁰ + 4Γ^½ − Γ¹)/6 = η                                 per spring (57b), (58c)


def _ho4_thermal(la, lh, lb, eta, l0, P, e):
    """θ⁰, θ¹ solving Γ(la, θ⁰) = Γ(lb, θ¹) and (3Γ(la, θ⁰) + 4Γ(lh, θ^½) − Γ(lb, θ¹))/6 = η,
    θ^½ = (θ⁰ + θ¹)/2, by a 2×2 Newton in ln θ from θ(la, η), θ(lb, η); then the derivatives
    dθ⁰/dl^½, dθ⁰/dl¹, dθ¹/dl^½, dθ¹/dl¹ and success."""
    t0 = temperature(la, eta, l0, P, e)
    t1 = temperature(lb, eta, l0, P, e)
    if not (t0 > 0.0 and t0 < math.inf and t1 > 0.0 and t1 < math.inf):
        return t0, t1, 0.0, 0.0, 0.0, 0.0, False
    change = 0.0
    for _ in range(LOCAL_ITERATIONS):
        th = 0.5 * (t0 + t1)
        G0 = entropy(la, t0, l0, P, e)
        Gh = entropy(lh, th, l0, P, e)
        G1 = entropy(lb, t1, l0, P, e)
        g0 = -d2F_dtheta2(la, t0, l0, P, e)
        gh = -d2F_dtheta2(lh, th, l0, P, e)
        g1 = -d2F_dtheta2(lb, t1, l0, P, e)
        r1 = G0 - G1
        r2 = (3.0 * G0 + 4.0 * Gh - G1) / 6.0 - eta
        J00 = g0
        J01 = -g1
        J10 = (3.0 * g0 + 2.0 * gh) / 6.0
        J11 = (2.0 * gh - g1) / 6.0
        det = J00 * J11 - J01 * J10
        s0 = _log_step((J11 * r1 - J01 * r2) / (det * t0))
        s1 = _log_step((J00 * r2 - J10 * r1) / (det * t1))
        t0 = t0 * math.exp(-s0)
        t1 = t1 * math.exp(-s1)
        change = max(abs(s0), abs(s1))
        if change <= THETA_ROUNDOFF:
            break
    if not (t0 > 0.0 and t0 < math.inf and t1 > 0.0 and t1 < math.inf and change <= THETA_FAILED):
        return t0, t1, 0.0, 0.0, 0.0, 0.0, False
    th = 0.5 * (t0 + t1)
    g0 = -d2F_dtheta2(la, t0, l0, P, e)
    gh = -d2F_dtheta2(lh, th, l0, P, e)
    g1 = -d2F_dtheta2(lb, t1, l0, P, e)
    J00 = g0
    J01 = -g1
    J10 = (3.0 * g0 + 2.0 * gh) / 6.0
    J11 = (2.0 * gh - g1) / 6.0
    det = J00 * J11 - J01 * J10
    # ∂(G1, G2)/∂l^½ = (0, 4Γ_l(lh, θ^½)/6); ∂(G1, G2)/∂l¹ = (−Γ_l(lb, θ¹), −Γ_l(lb, θ¹)/6); Γ_l = −F_lθ
    qh = -4.0 * d2F_dl_dtheta(lh, th, l0, P, e) / 6.0
    w1 = d2F_dl_dtheta(lb, t1, l0, P, e)
    q1a = w1
    q1b = w1 / 6.0
    d0h = -(-J01 * qh) / det
    d1h = -(J00 * qh) / det
    d01 = -(J11 * q1a - J01 * q1b) / det
    d11 = -(J00 * q1b - J10 * q1a) / det
    return t0, t1, d0h, d01, d1h, d11, True


def _ho4_residual(x0, u, p, eta, l0, P, edges, free_index, masses, h, gravity, with_gravity,
                  len0, dir0, lenh, dirh, len1, dir1, th0, th1, dth, R, Rabs):
    """R, Rabs (6 n_free,) at unknowns u (6 n_free,); fills lengths/unit vectors at x^½ and x¹,
    θ⁰, θ¹ (m,) and dth (m, 4) = dθ⁰/dl^½, dθ⁰/dl¹, dθ¹/dl^½, dθ¹/dl¹. Returns (status, spring)."""
    for a in range(x0.shape[0]):
        k = free_index[a]
        if k < 0:
            continue
        w = masses[a] / h
        for i in range(3):
            dh = u[6 * k + i]
            d1 = u[6 * k + 3 + i]
            g0 = h / 6.0 * masses[a] * gravity[i] if with_gravity else 0.0
            gh = h / 4.0 * masses[a] * gravity[i] if with_gravity else 0.0
            i1 = w * (8.0 * dh - d1) / 3.0
            i2 = w * (d1 - 2.0 * dh)
            R[6 * k + i] = i1 - p[a, i] - g0
            Rabs[6 * k + i] = abs(i1) + abs(p[a, i]) + abs(g0)
            R[6 * k + 3 + i] = i2 - gh
            Rabs[6 * k + 3 + i] = abs(i2) + abs(gh)
    for e in range(edges.shape[0]):
        a = edges[e, 0]
        b = edges[e, 1]
        ka = free_index[a]
        kb = free_index[b]
        for stage in range(2):
            dx = x0[b, 0] - x0[a, 0]
            dy = x0[b, 1] - x0[a, 1]
            dz = x0[b, 2] - x0[a, 2]
            off = 3 * stage
            if kb >= 0:
                dx += u[6 * kb + off]
                dy += u[6 * kb + off + 1]
                dz += u[6 * kb + off + 2]
            if ka >= 0:
                dx -= u[6 * ka + off]
                dy -= u[6 * ka + off + 1]
                dz -= u[6 * ka + off + 2]
            l = math.sqrt(dx * dx + dy * dy + dz * dz)
            if not (l > 0.0 and l < math.inf):
                return 1, e
            if stage == 0:
                lenh[e] = l
                dirh[e, 0] = dx / l
                dirh[e, 1] = dy / l
                dirh[e, 2] = dz / l
            else:
                len1[e] = l
                dir1[e, 0] = dx / l
                dir1[e, 1] = dy / l
                dir1[e, 2] = dz / l
        t0, t1, d0h, d01, d1h, d11, ok = ho4_thermal(len0[e], lenh[e], len1[e], eta[e], l0[e], P, e)
        if not ok:
            return 2, e
        th0[e] = t0
        th1[e] = t1
        dth[e, 0] = d0h
        dth[e, 1] = d01
        dth[e, 2] = d1h
        dth[e, 3] = d11
        c0 = h / 6.0 * tension(len0[e], t0, l0[e], P, e)
        ch = h / 4.0 * tension(lenh[e], 0.5 * (t0 + t1), l0[e], P, e)
        for i in range(3):
            v0 = c0 * dir0[e, i]
            vh = ch * dirh[e, i]
            if ka >= 0:
                R[6 * ka + i] -= v0
                Rabs[6 * ka + i] += abs(v0)
                R[6 * ka + 3 + i] -= vh
                Rabs[6 * ka + 3 + i] += abs(vh)
            if kb >= 0:
                R[6 * kb + i] += v0
                Rabs[6 * kb + i] += abs(v0)
                R[6 * kb + 3 + i] += vh
                Rabs[6 * kb + 3 + i] += abs(vh)
    return 0, -1


def _ho4_jacobian(free_index, masses, h, l0, P, edges, len0, dir0, lenh, dirh, dir1, th0, th1, dth,
                  node_base, node_stride, spring_base, spring_stride, data):
    """Values of ∂R/∂u at the last residual's point into the CSR value array ``data``.

    Node block (rows R1, R2; columns d^½, d¹): m/h [[8/3, −1/3], [−2, 1]] ⊗ I. Spring block,
    added with sign s_c s_g (s_a = +1, s_b = −1):
      ∂R1/∂x^σ = h/6 F_lθ(l⁰, θ⁰) dθ⁰/dl^σ n⁰ n^σᵀ
      ∂R2/∂x^½ = h/4 [(F_ll + F_lθ dθ^½/dl^½) n^½ n^½ᵀ + T/l (I − n^½ n^½ᵀ)] at (l^½, θ^½)
      ∂R2/∂x¹  = h/4 F_lθ(l^½, θ^½) dθ^½/dl¹ n^½ n¹ᵀ."""
    data[:] = 0.0
    for a in range(free_index.shape[0]):
        k = free_index[a]
        if k < 0:
            continue
        w = masses[a] / h
        base = node_base[k]
        st = node_stride[k]
        for i in range(3):
            data[base + i * st + i] += 8.0 / 3.0 * w
            data[base + i * st + 3 + i] += -w / 3.0
            data[base + (3 + i) * st + i] += -2.0 * w
            data[base + (3 + i) * st + 3 + i] += w
    B = np.zeros((6, 6))
    for e in range(edges.shape[0]):
        t0 = th0[e]
        th = 0.5 * (t0 + th1[e])
        lh = lenh[e]
        c0 = h / 6.0 * d2F_dl_dtheta(len0[e], t0, l0[e], P, e)
        flt = d2F_dl_dtheta(lh, th, l0[e], P, e)
        dthh_h = 0.5 * (dth[e, 0] + dth[e, 2])
        dthh_1 = 0.5 * (dth[e, 1] + dth[e, 3])
        axial = h / 4.0 * (d2F_dl2(lh, th, l0[e], P, e) + flt * dthh_h)
        lateral = h / 4.0 * tension(lh, th, l0[e], P, e) / lh
        c21 = h / 4.0 * flt * dthh_1
        for i in range(3):
            for j in range(3):
                B[i, j] = c0 * dth[e, 0] * dir0[e, i] * dirh[e, j]
                B[i, 3 + j] = c0 * dth[e, 1] * dir0[e, i] * dir1[e, j]
                nn = dirh[e, i] * dirh[e, j]
                B[3 + i, j] = (axial - lateral) * nn + (lateral if i == j else 0.0)
                B[3 + i, 3 + j] = c21 * dirh[e, i] * dir1[e, j]
        for q in range(4):
            base = spring_base[e, q]
            if base < 0:
                continue
            sign = 1.0 if (q == 0 or q == 3) else -1.0
            stride = spring_stride[e, q]
            for i in range(6):
                for j in range(6):
                    data[base + i * stride + j] += sign * B[i, j]


def _ho4_finish(x0, u, p, phi, eta, l0, P, edges, free_index, masses, h, gravity, with_gravity,
                len0, dir0, lenh, dirh, len1, dir1, th0, th1, x_new, p_new, phi_new, eta_new):
    """The next state from converged unknowns: x¹ = x⁰ + d¹; Φ¹ = Φ⁰ + h (θ⁰ + θ¹)/2;
    η¹ = (−Γ⁰ + 4Γ^½ + 3Γ¹)/6 measured (58d); and p¹ = p⁰ + h (f⁰ + 4 f^½ + f¹)/6, which is
    (58b) given (58a) and (57a) and conserves linear momentum to round-off whatever the solver
    residual. Returns (status, spring)."""
    for a in range(x0.shape[0]):
        k = free_index[a]
        for i in range(3):
            if k < 0:
                x_new[a, i] = x0[a, i]
                p_new[a, i] = p[a, i]
            else:
                x_new[a, i] = x0[a, i] + u[6 * k + 3 + i]
                p_new[a, i] = p[a, i] + (h * masses[a] * gravity[i] if with_gravity else 0.0)
    for e in range(edges.shape[0]):
        a = edges[e, 0]
        b = edges[e, 1]
        t0 = th0[e]
        t1 = th1[e]
        th = 0.5 * (t0 + t1)
        phi_new[e] = phi[e] + h * th
        G0 = entropy(len0[e], t0, l0[e], P, e)
        Gh = entropy(lenh[e], th, l0[e], P, e)
        G1 = entropy(len1[e], t1, l0[e], P, e)
        eta1 = (-G0 + 4.0 * Gh + 3.0 * G1) / 6.0
        eta_new[e] = eta1
        if not (abs(eta1) < math.inf):
            return 3, e
        th_end = temperature(len1[e], eta1, l0[e], P, e)
        if not (th_end > 0.0 and th_end < math.inf):
            return 2, e
        c0 = h / 6.0 * tension(len0[e], t0, l0[e], P, e)
        ch = 4.0 * h / 6.0 * tension(lenh[e], th, l0[e], P, e)
        c1 = h / 6.0 * tension(len1[e], t1, l0[e], P, e)
        free_a = free_index[a] >= 0
        free_b = free_index[b] >= 0
        for i in range(3):
            v = c0 * dir0[e, i] + ch * dirh[e, i] + c1 * dir1[e, i]
            if free_a:
                p_new[a, i] += v
            if free_b:
                p_new[b, i] -= v
    for a in range(x0.shape[0]):
        for i in range(3):
            if not (abs(p_new[a, i]) < math.inf):
                return 3, -1
    return 0, -1
