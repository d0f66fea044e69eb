"""EM2's discrete gradient of one spring (docs/theory.md §3), Q = [U(l¹, η) − U(l⁰, η)]/δ, δ = l¹ − l⁰,
and dQ/dl¹: the model's closed form where it gives one (``Model.energy_quotient``), else the
generic forms below; Numba templates bound per model by :func:`bind_gradient` (for
:mod:`.em2`'s kernels, which inline them, and callable alone for tests).

The quotient Q = ΔU/δ cancels as δ → 0: its rounding is about ε |U| / |δ| (|U| includes the
model's offsets, e.g. C0 θ), a noise in the residual as a function of the unknowns that would
hold Newton above 1e-14 (measured on the paper's chain with the switch at 1e-3). So for
|δ| ≤ SWITCH l̄ the 5-point Gauss–Lobatto rule on T = dU/dl (fixed η) replaces it,

    Q ≈ [T(l⁰) + T(l¹)]/20 + 49/180 [T(l⁰ + ξ δ) + T(l¹ − ξ δ)] + 16/45 T(l̄),  ξ = (1 − √(3/7))/2

which is the midpoint form T(l̄) with the Taylor corrections of ΔU about l̄ up to δ⁶ (exact for
a polynomial T of degree 7; error 7.0e-10 δ⁸ T⁽⁸⁾) and has no cancellation. At SWITCH = 0.03
its error, checked against 40-digit arithmetic for hencky springs (β = 0.2 and 2, l ∈ [0.3, 3]
l0), is below 1e-15 relative to the force, and the quotient's rounding above the switch 30×
smaller than at 1e-3; the energy error of the rule per spring and step, δ × that, is below
U's own rounding.

dQ/dl¹ is (T(l¹) − Q)/δ beyond the switch and the rule's Σ wᵢ ξᵢ k(l⁰ + ξᵢ δ) within it (nodes
ξᵢ ∈ [0, 1], k = dT/dl at fixed η, the adiabatic stiffness). These forms cost four tension
evaluations per spring and residual (T(l¹) and the rule's three interior nodes), and four
stiffness evaluations per linearization; a model's closed form is one expression of the
lengths, given θ and T at l⁰ (hencky's: one ln and one exp).
"""

from __future__ import annotations

import math

from numba import njit

from ..core.schemes import INLINE, OPTIONS
from ..core.start import _adiabatic_stiffness
from ...kernels.specialize import MODEL_FUNCTIONS, specialize

# Bound per model by specialize(); listed so the templates read as ordinary code.
temperature = tension = internal_energy = adiabatic_stiffness = energy_quotient = None
EXACT_QUOTIENT = False
tension_at = em2_value = em2_derivative = lobatto_value = lobatto_derivative = None

#: |l¹ − l⁰| ≤ SWITCH l̄: the discrete gradient by the Gauss–Lobatto rule, not by the quotient ΔU/δ
SWITCH = 0.03
#: the interior nodes and weights of the 5-point Gauss–Lobatto rule on [0, 1] (besides 1/2, 16/45)
LOBATTO_NODE = 0.5 * (1.0 - math.sqrt(3.0 / 7.0))
LOBATTO_WEIGHT = 49.0 / 180.0


def bind_gradient(ns: dict, tag: str) -> dict:
    """Specialize the per-spring functions into the model namespace ``ns`` (inlined by the
    kernels: tension_at, lobatto_value, lobatto_derivative, em2_value, em2_derivative) and return
    those callable alone: ``slope(l, l1, eta, l0, P, e, U0, T0) -> (s, ds/dl1, θ(l1, η))``,
    ``direct`` and ``quadrature`` (the generic forms, ``(Q, dQ/dl1)``)."""
    helpers = (("tension_at", _tension_at), ("lobatto_value", _lobatto_value),
               ("lobatto_derivative", _lobatto_derivative), ("em2_value", _em2_value),
               ("em2_derivative", _em2_derivative))
    for name, template in helpers:
        ns[name] = specialize(template, tag, ns, **INLINE)
    # The functions callable alone call each helper and model function as a function of its own,
    # not inlined: the same arithmetic, and each compiled once (inlined into one another, the
    # generic slope alone took 34 s to compile)
    alone = dict(ns)
    for name in MODEL_FUNCTIONS + ("energy_quotient",):
        f = ns.get(name)
        if f is not None and hasattr(f, "py_func"):
            alone[name] = njit(error_model="numpy")(f.py_func)
    atag = f"{tag}_alone"
    alone["adiabatic_stiffness"] = specialize(_adiabatic_stiffness, atag, alone, **OPTIONS)
    for name, template in helpers:
        alone[name] = specialize(template, atag, alone, **OPTIONS)
    return dict(slope=specialize(_em2_slope, atag, alone, **OPTIONS),
                direct=specialize(_em2_direct, atag, alone, **OPTIONS),
                quadrature=specialize(_em2_quadrature, atag, alone, **OPTIONS))


def _em2_direct(l, l1, eta, l0, P, e, U0, T1):
    """Q = (U(l1, η) − U0)/(l1 − l) and dQ/dl1 = (T1 − Q)/(l1 − l), T1 = T(l1, θ(l1, η))
    (l1 ≠ l)."""
    Q = (internal_energy(l1, eta, l0, P, e) - U0) / (l1 - l)
    return Q, (T1 - Q) / (l1 - l)


def _tension_at(l, eta, l0, P, e):
    """T(l, θ(l, η))."""
    return tension(l, temperature(l, eta, l0, P, e), l0, P, e)


def _lobatto_value(l, l1, eta, l0, P, e, T0, T1):
    """Q = ΔU/δ by the 5-point Gauss–Lobatto rule on T (module doc; T0 = T at l, T1 at l1)."""
    d = l1 - l
    return (0.05 * (T0 + T1) + LOBATTO_WEIGHT * (tension_at(l + LOBATTO_NODE * d, eta, l0, P, e)
                                                 + tension_at(l1 - LOBATTO_NODE * d, eta, l0, P, e))
            + (16.0 / 45.0) * tension_at(l + 0.5 * d, eta, l0, P, e))


def _lobatto_derivative(l, l1, eta, l0, P, e):
    """dQ/dl1 = Σ wᵢ ξᵢ k(l + ξᵢ δ) of the rule (k the adiabatic stiffness)."""
    d = l1 - l
    return (0.05 * adiabatic_stiffness(l1, eta, l0, P, e)
            + LOBATTO_WEIGHT * (LOBATTO_NODE * adiabatic_stiffness(l + LOBATTO_NODE * d, eta, l0, P, e)
                                + (1.0 - LOBATTO_NODE) * adiabatic_stiffness(l1 - LOBATTO_NODE * d, eta, l0, P, e))
            + (8.0 / 45.0) * adiabatic_stiffness(l + 0.5 * d, eta, l0, P, e))


def _em2_quadrature(l, l1, eta, l0, P, e, T0, T1):
    """Q and dQ/dl1 by the rule, without cancellation."""
    return lobatto_value(l, l1, eta, l0, P, e, T0, T1), lobatto_derivative(l, l1, eta, l0, P, e)


def _em2_value(l, l1, eta, l0, P, e, U0, T0, T1):
    """Q = ΔU/δ of one spring (U0, T0 at its start length l, T1 at its end length l1): the
    quotient, or the rule within SWITCH; only the value (what a residual needs)."""
    if abs(l1 - l) > SWITCH * (0.5 * (l + l1)):
        return (internal_energy(l1, eta, l0, P, e) - U0) / (l1 - l)
    return lobatto_value(l, l1, eta, l0, P, e, T0, T1)


def _em2_derivative(l, l1, eta, l0, P, e, Q, T1):
    """dQ/dl1 of one spring given its Q (:func:`_em2_value`) and T1 = T at l1."""
    if abs(l1 - l) > SWITCH * (0.5 * (l + l1)):
        return (T1 - Q) / (l1 - l)
    return lobatto_derivative(l, l1, eta, l0, P, e)


def _em2_slope(l, l1, eta, l0, P, e, U0, T0):
    """The discrete gradient's s = ΔU/(δ l̄), ds/dl1 and θ(l1, η) of one spring from its start
    length l (with U0 = U(l, η), T0 = T(l, θ(l, η))) and its end length l1."""
    th1 = temperature(l1, eta, l0, P, e)
    lm = 0.5 * (l + l1)
    if EXACT_QUOTIENT:
        Q, dQ = energy_quotient(l, l1, eta, temperature(l, eta, l0, P, e), T0, l0, P, e)
    else:
        T1 = tension(l1, th1, l0, P, e)
        Q = em2_value(l, l1, eta, l0, P, e, U0, T0, T1)
        dQ = em2_derivative(l, l1, eta, l0, P, e, Q, T1)
    s = Q / lm
    return s, (dQ - 0.5 * s) / lm, th1
