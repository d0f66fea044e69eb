"""HO4's per-spring thermal solve (docs/theory.md §2.2): given a spring's lengths l⁰, l^½, l¹ and entropy η,
the end temperatures θ⁰, θ¹ (θ^½ their mean) solving

    Γ⁰ = Γ¹,  (3Γ⁰ + 4Γ^½ − Γ¹)/6 = η                                       (57b), (58c)

and their derivatives with respect to l^½ and l¹ (the condensed unknowns' share of the Jacobian):
the scalar solve (iterated to convergence), the vectorized one (a fixed number of corrections),
and, for an entropy affine in ln θ (``Model.entropy_log_affine``, model "hencky"), the closed
form (:func:`_ho4_thermal_exact`: no corrections, no seeds). Numba templates, compiled per model
by :func:`thermonet.implicit.ho4.kernels.build`.
"""

from __future__ import annotations

import math

from ...kernels.fastmath import exp as exp_
from ..core.schemes import LOCAL_ITERATIONS, LOG_AFFINE, MAX_LOG_STEP, SIXTH, THETA_STOP, _admissible, _usable

# Bound per model by specialize(); listed so the templates read as ordinary code.
entropy = temperature = d2F_dl_dtheta = d2F_dtheta2 = None
ho4_derivatives = ho4_correct = ho4_thermal_closed = ho4_thermal_exact = None


def _ho4_derivatives(la, lh, lb, l0, P, e, t0, t1):
    """dθ⁰/dl^½, dθ⁰/dl¹, dθ¹/dl^½, dθ¹/dl¹ at a solution (θ⁰, θ¹) of (57b), (58c)."""
    th = 0.5 * (t0 + t1)
    g0 = -d2F_dtheta2(la, t0, l0, P, e)
    gh = -d2F_dtheta2(lh, th, l0, P, e)
    g1 = -d2F_dtheta2(lb, t1, l0, P, e)
    # implicit derivatives of the 2×2 system (57b), (58c) in (θ⁰, θ¹), with Γ_l = −F_lθ:
    # ∂(G1, G2)/∂l^½ = (0, 4Γ_l(lh, θ^½)/6); ∂(G1, G2)/∂l¹ = (−Γ_l(lb, θ¹), −Γ_l(lb, θ¹)/6)
    J00 = g0
    J01 = -g1
    J10 = (3.0 * g0 + 2.0 * gh) * SIXTH
    J11 = (2.0 * gh - g1) * SIXTH
    inv_det = 1.0 / (J00 * J11 - J01 * J10)
    qh = -4.0 * SIXTH * d2F_dl_dtheta(lh, th, l0, P, e)
    w1 = d2F_dl_dtheta(lb, t1, l0, P, e)
    q1a = w1
    q1b = w1 * SIXTH
    d0h = J01 * qh * inv_det
    d1h = -(J00 * qh) * inv_det
    d01 = -(J11 * q1a - J01 * q1b) * inv_det
    d11 = -(J00 * q1b - J10 * q1a) * inv_det
    return d0h, d01, d1h, d11


def _ho4_thermal(la, lh, lb, eta, l0, P, e, guess, warm):
    """θ⁰, θ¹ solving Γ(la, θ⁰) = Γ(lb, θ¹) and (3Γ(la, θ⁰) + 4Γ(lh, θ^½) − Γ(lb, θ¹))/6 = η,
    θ^½ = (θ⁰ + θ¹)/2; returns (G, θ⁰, θ¹, dθ⁰/dl^½, dθ⁰/dl¹, dθ¹/dl^½, dθ¹/dl¹, success 1 or 0).

    The unknown is the common value G = Γ⁰ = Γ¹ (so θ⁰ = θ(la, G), θ¹ = θ(lb, G) satisfy (57b)
    exactly), and (58c) becomes the scalar equation (2G + 4Γ(lh, θ^½))/6 = η, solved by Newton
    from ``guess`` when ``warm``, else from G = η. For an entropy affine in ln θ (model "hencky")
    Γ(lh, θ^½) − G does not depend on G, so one correction is exact. The scalar solve: iterates
    to convergence."""
    G = guess if (warm and abs(guess) < math.inf) else eta
    t0 = temperature(la, G, l0, P, e)
    t1 = temperature(lb, G, l0, P, e)
    if not (_usable(t0) and _usable(t1)):
        return G, t0, t1, 0.0, 0.0, 0.0, 0.0, 0
    done = False
    for _ in range(LOCAL_ITERATIONS):
        G, s0, s1, big = ho4_correct(la, lh, lb, eta, l0, P, e, G, t0, t1)
        if big <= THETA_STOP:
            # dθ = −dG/Γ_θ to second order (the neglected term is ~ big², below round-off)
            t0 *= 1.0 - s0 + 0.5 * s0 * s0
            t1 *= 1.0 - s1 + 0.5 * s1 * s1
            done = True
            break
        t0 = temperature(la, G, l0, P, e)
        t1 = temperature(lb, G, l0, P, e)
    if not (done and _usable(t0) and _usable(t1)):
        return G, t0, t1, 0.0, 0.0, 0.0, 0.0, 0
    d0h, d01, d1h, d11 = ho4_derivatives(la, lh, lb, l0, P, e, t0, t1)
    return G, t0, t1, d0h, d01, d1h, d11, 1


def _ho4_correct(la, lh, lb, eta, l0, P, e, G, t0, t1):
    """One Newton correction of the scalar equation of :func:`_ho4_thermal` (branch-free):
    (new G, the changes of ln θ⁰ and ln θ¹ it causes, the larger of their magnitudes).
    Written with few divisions: they are most of a vectorized solve's cost."""
    th = 0.5 * (t0 + t1)
    r = (2.0 * G + 4.0 * entropy(lh, th, l0, P, e)) * SIXTH - eta
    g0 = -d2F_dtheta2(la, t0, l0, P, e)  # Γ_θ, so dθ/dG = 1/Γ_θ
    gh = -d2F_dtheta2(lh, th, l0, P, e)
    g1 = -d2F_dtheta2(lb, t1, l0, P, e)
    q0 = 1.0 / (g0 * t0)
    q1 = 1.0 / (g1 * t1)
    dG = 6.0 * r / (2.0 + 2.0 * gh * (q0 * t0 + q1 * t1))
    # the change of ln θ⁰ and ln θ¹ this causes, bounded so exp() cannot overflow
    s0 = dG * q0
    s1 = dG * q1
    big = max(abs(s0), abs(s1))
    dG = dG * (MAX_LOG_STEP / big) if big > MAX_LOG_STEP else dG
    return G - dG, s0, s1, big


def _ho4_thermal_closed(A, B, C, lh, eta, l0, P, e):
    """The solution of :func:`_ho4_thermal`'s equations in closed form, for an entropy affine in
    ln θ, Γ(l, θ) = a(l) + C ln θ (LOG_AFFINE), from A = θ(l⁰, η) and B = θ(l¹, η): then
    θ(l, G) = θ(l, η) exp((G − η)/C) and Γ(l, s θ) = Γ(l, θ) + C ln s, so with S = Γ(l^½,
    (A + B)/2), Γ(l^½, θ^½) = S + G − η and (58c) reads (2G + 4(S + G − η))/6 = η: G = η +
    2(η − S)/3, θ⁰ = A E, θ¹ = B E with E = exp((G − η)/C). Returns (G, θ⁰, θ¹)."""
    G = eta + (2.0 / 3.0) * (eta - entropy(lh, 0.5 * (A + B), l0, P, e))
    E = exp_((G - eta) / C)
    return G, A * E, B * E


def _ho4_thermal_exact(la, lh, lb, eta, l0, P, e):
    """:func:`_ho4_thermal`'s returns from :func:`_ho4_thermal_closed` (LOG_AFFINE), A, B and
    C = −A F_θθ(l⁰, A) computed here (the residual kernel reads A and C from the start kernel's
    ``keep``); success unless a temperature is not admissible."""
    A = temperature(la, eta, l0, P, e)
    B = temperature(lb, eta, l0, P, e)
    G, t0, t1 = ho4_thermal_closed(A, B, -A * d2F_dtheta2(la, A, l0, P, e), lh, eta, l0, P, e)
    ok = 1 if _admissible(t0) & _admissible(t1) else 0
    d0h, d01, d1h, d11 = ho4_derivatives(la, lh, lb, l0, P, e, t0, t1)
    return G, t0, t1, d0h, d01, d1h, d11, ok


def _ho4_thermal_vector(la, lh, lb, eta, l0, P, e, guess, warm):
    """The vectorized loop's solve of :func:`_ho4_thermal`: in closed form where the model
    allows (:func:`_ho4_thermal_exact`), else VECTOR_CORRECTIONS corrections from the same start,
    the last applied to θ to second order as there; success when the last is below THETA_STOP.
    Same returns."""
    if LOG_AFFINE:
        return ho4_thermal_exact(la, lh, lb, eta, l0, P, e)
    G = guess if (warm & (abs(guess) < math.inf)) else eta
    t0 = temperature(la, G, l0, P, e)
    t1 = temperature(lb, G, l0, P, e)
    G, s0, s1, big = ho4_correct(la, lh, lb, eta, l0, P, e, G, t0, t1)
    t0 = temperature(la, G, l0, P, e)
    t1 = temperature(lb, G, l0, P, e)
    G, s0, s1, big = ho4_correct(la, lh, lb, eta, l0, P, e, G, t0, t1)
    t0 *= 1.0 - s0 + 0.5 * s0 * s0
    t1 *= 1.0 - s1 + 0.5 * s1 * s1
    ok = 1 if (big <= THETA_STOP) & _admissible(t0) & _admissible(t1) else 0
    d0h, d01, d1h, d11 = ho4_derivatives(la, lh, lb, l0, P, e, t0, t1)
    return G, t0, t1, d0h, d01, d1h, d11, ok



def _ho4_temperature_derivatives(dth, e, la, lh, lb, l0, P, pe, t0, t1):
    """dθ⁰/dl^½, dθ⁰/dl¹, dθ¹/dl^½, dθ¹/dl¹ of spring e at the last residual's point: computed
    again where the residual does not store them (LOG_AFFINE), else read from dth (4, m)."""
    if LOG_AFFINE:
        return ho4_derivatives(la, lh, lb, l0, P, pe, t0, t1)
    return dth[0, e], dth[1, e], dth[2, e], dth[3, e]

