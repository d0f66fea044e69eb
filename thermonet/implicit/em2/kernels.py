"""EM2's kernels (docs/theory.md §3): the discrete-gradient (energy–momentum) midpoint step at fixed
entropy per spring, as Numba templates compiled per model by :func:`build` (registered as scheme
"em2"). Conventions (records, blocking, status codes): :mod:`thermonet.implicit.core.schemes`.

Unknown d = x¹ − x⁰ per free node (block of 3). With the spring vectors d⁰, d¹ (end minus start
node), l⁰, l¹ their lengths, d̄ = (d⁰ + d¹)/2, l̄ = (l⁰ + l¹)/2 and δ = l¹ − l⁰:

    R_c = m_c d_c / h − p_c − (h/2) m_c g − (h/2) Σ_e ±s_e d̄_e        (+ at a spring's first end)
    s_e = [U(l¹, η) − U(l⁰, η)] / (δ l̄)                                 (the discrete gradient)

so that x¹ − x⁰ = h (p⁰ + p¹)/(2m) with p¹ = p⁰ + h (m g + Σ ±s d̄): since d̄·(d¹ − d⁰) = l̄ δ,
the kinetic energy gains exactly what U loses; the forces are central (along d̄) and opposite,
so linear and angular momentum are kept exactly. η¹ = η; Φ¹ = Φ⁰ + h θ(l̄, η).

Q = ΔU/δ per spring is the model's closed form (``Model.energy_quotient``) or, for a model
without one, the generic forms of :mod:`thermonet.implicit.em2.gradient` (the quotient of two U values, a
Gauss–Lobatto rule on T where that would cancel).

The Jacobian block of spring e (added with sign s_c s_g to block (c, g), s_a = +1, s_b = −1) is

    B_e = (h/2) [ (s/2) I + (ds/dl¹) d̄ n¹ᵀ ],   ds/dl¹ = (dQ/dl¹) / l̄ − s / (2 l̄)

with dQ/dl¹ from the model's closed form, or from the generic forms (:mod:`thermonet.implicit.em2.gradient`). The
work record is :class:`EM2Work`.

Kernels (records: plain tuples of arrays, ``core.records.plain``): ``residual(step, topo,
spring, node, work, u, res) -> (status, spring, max|R|, max Rabs)`` (s from Q alone; it keeps Q,
and T(l¹) for the generic forms), ``linearize(spring, work, h)`` and ``jacobian(topo, spring,
node, work, places, h, data)`` (ds/dl¹ from the lengths and what the residual kept: a residual
not linearized does not pay for it), ``predict(step, topo, spring, node, work, accel, pred)``,
``finish(step, topo, spring, node, work, u, phi, new) -> (status, spring)``, ``sweep(topo, node,
work, h, du, R, r, update, first) -> max|r|``, ``step_scale(topo, work, du, limit) -> factor``,
``damp(step, topo, spring, node, work, res, norms, vectors) -> (evaluated, max|R|, max Rabs)``
(the damped Newton step, both paths) and ``slope(l, l1, eta, l0, P, e, U0, T0) -> (s, ds/dl1,
θ(l1, η))``. A step: the start kernel with predictor coefficients [[0, 1, 0, 0]] (it writes a),
``predict``, then ``residual`` and ``linearize`` or ``jacobian`` per Newton iteration,
``finish``; the compiled Newton path (:mod:`thermonet.implicit.core.compiled_newton`) through the ``compiled_*`` adapters.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import prange

from ..core.schemes import (BLOCK, COLLAPSED, INLINE, NO_TEMPERATURE, NOT_FINITE, OK, OPTIONS, UNIFORM,
                            _admissible, _first_flagged, register_scheme, scatter_spring_block)
from .gradient import SWITCH, bind_gradient
from ..core.records import StartWork
from ..core.node_rows import inertia_blocks3, node_blocks, norm2, residual_rows3, spring_difference3, sweep_rows3
from ...kernels.specialize import specialize, specialize_by_content

# Bound per model by specialize(); listed so the templates read as ordinary code.
temperature = tension = internal_energy = adiabatic_stiffness = energy_quotient = None
EXACT_QUOTIENT = False
CAN_VANISH = True
finish_nodes = em2_derivative = em2_spring_dslope = lobatto_value = lobatto_derivative = None
em2_predict = em2_residual = em2_jacobian = em2_finish = em2_linearize = em2_step_scale = em2_damp = None
em2_predict_springs = em2_residual_springs = em2_finish_springs = em2_linearize_springs = None

#: a Newton correction changes no spring's vector by more than this fraction of its length
LENGTH_LIMIT = 0.5
#: a correction is searched along (halved until the residual falls) while the scaled residual
#: is above this; below it Newton converges quadratically from the whole correction
LINE_SEARCH_ABOVE = 1e-3
LINE_SEARCH_HALVINGS = 12


class EM2Work(NamedTuple):
    """EM2's per-spring arrays for m springs: len1 (m,), dir1 (3, m) the length and unit vector
    at x¹; mean (3, m) the mean spring vector d̄; slope, dslope (m,) s and ds/dl¹; energy0,
    temperature0, tension0 (m,) U, θ and T at l⁰ (fixed over the step; U for the generic forms
    only, θ for a model's ``energy_quotient`` only); jc (2, m) the matrix-free coefficients
    (h s/4, h ds/dl¹ / 2); eta_step (m,) the step's entropies (copied by ``predict``); quotient,
    tension1 (m,) Q = ΔU/δ and T(l¹) of the last residual (ds/dl¹ from them, by ``linearize`` and
    ``jacobian`` only: a residual does not need it; T(l¹) for the generic forms only); and the
    start kernel's record ``start`` (its ``guess`` (m,) holds the predictor's per-spring
    stiffness, and the finish's θ(l̄, η))."""

    start: StartWork
    len1: np.ndarray
    dir1: np.ndarray
    mean: np.ndarray
    slope: np.ndarray
    dslope: np.ndarray
    energy0: np.ndarray
    temperature0: np.ndarray
    tension0: np.ndarray
    jc: np.ndarray
    eta_step: np.ndarray
    quotient: np.ndarray
    tension1: np.ndarray

    @classmethod
    def allocate(cls, start: StartWork) -> "EM2Work":
        m = start.len0.shape[0]
        return cls(start, np.empty(m), np.empty((3, m)), np.empty((3, m)), np.empty(m), np.empty(m),
                   np.empty(m), np.empty(m), np.empty(m), np.empty((2, m)), np.empty(m), np.empty(m), np.empty(m))


def build(ns: dict, tag: str, ptag: str, parallel: bool) -> dict:
    """EM2's kernels for the model namespace ``ns`` (see core.schemes.register_scheme)."""
    alone = bind_gradient(ns, tag)
    ns["em2_spring_dslope"] = specialize(_em2_spring_dslope, tag, ns, **INLINE)
    # (the spring blocks: serial, shared by the serial and the threaded kernels)
    ns["em2_predict_springs"] = specialize_by_content(_em2_predict_springs, tag, ns, **OPTIONS)
    ns["em2_residual_springs"] = specialize_by_content(_em2_residual_springs, tag, ns, **OPTIONS)
    ns["em2_linearize_springs"] = specialize_by_content(_em2_linearize_springs, tag, ns, **OPTIONS)
    ns["em2_finish_springs"] = specialize_by_content(_em2_finish_springs, tag, ns, **OPTIONS)
    kernels = dict(
        predict=specialize(_em2_predict, ptag, ns, parallel=parallel, **OPTIONS),
        residual=specialize(_em2_residual, ptag, ns, parallel=parallel, **OPTIONS),
        linearize=specialize(_em2_linearize, ptag, ns, parallel=parallel, **OPTIONS),
        jacobian=specialize(_em2_jacobian, tag, ns, **OPTIONS),
        finish=specialize(_em2_finish, ptag, ns, parallel=parallel, **OPTIONS),
        sweep=specialize(_em2_sweep, "par" if parallel else "ser", {}, parallel=parallel, **OPTIONS),
        step_scale=specialize(_em2_step_scale, "par" if parallel else "ser", {}, parallel=parallel, **OPTIONS),
    )
    calls = dict(ns, **{f"em2_{k}": v for k, v in kernels.items()})
    kernels["damp"] = calls["em2_damp"] = specialize(_em2_damp, ptag, calls, **OPTIONS)
    return dict(
        kernels,
        # the compiled Newton path's signatures (implicit/core/compiled_newton.py), extra = ()
        compiled_predict=specialize(_em2_compiled_predict, ptag, calls, **INLINE),
        compiled_residual=specialize(_em2_compiled_residual, ptag, calls, **INLINE),
        compiled_jacobian=specialize(_em2_compiled_jacobian, ptag, calls, **INLINE),
        compiled_finish=specialize(_em2_compiled_finish, ptag, calls, **INLINE),
        compiled_linearize=specialize(_em2_compiled_linearize, ptag, calls, **INLINE),
        compiled_damp=specialize(_em2_compiled_damp, ptag, calls, **INLINE),
        **alone,
    )


# ---------------------------------------------------------------------------------------------
# one spring's ds/dl¹ from the work record (the discrete gradient itself: ..em2.gradient)


def _em2_spring_dslope(spring, work, e, pe):
    """ds/dl¹ of spring e at the last residual's point (its Q, T(l¹), s in ``work``)."""
    l0, P = spring
    start, len1, dir1, mean, slope, dslope, energy0, temperature0, tension0, jc, eta_step, quotient, tension1 = work
    l = start[0][e]
    l1 = len1[e]
    if EXACT_QUOTIENT:
        dQ = energy_quotient(l, l1, eta_step[e], temperature0[e], tension0[e], l0[e], P, pe)[1]
    else:
        dQ = em2_derivative(l, l1, eta_step[e], l0[e], P, pe, quotient[e], tension1[e])
    return (dQ - 0.5 * slope[e]) / (0.5 * (l + l1))


# ---------------------------------------------------------------------------------------------
# the step's kernels


def _em2_predict(step, topo, spring, node, work, accel, pred):
    """Per spring, T at l⁰ and U there (the generic forms, ``work.energy0``) or θ (a model's
    closed form, ``temperature0``), and ``tension0``; then the predictor of the
    unknowns into pred (3 n_free,): per free node d = h v + h²/2 a / (1 + h² κ/(4 m)), v = p/m,
    a the acceleration at x⁰ (``accel`` (3 n_free,), from the start kernel), κ = Σ_e
    max(dT/dl|η, 0) + max(T/l, 0) over the node's springs: the acceleration's part damped as in
    the midpoint rule's step on a spring of the node's own stiffness. Third order for small h ω,
    like h v + h²/2 a, and bounded far above the explicit limit (|h²/2 a| ≲ 2 m |a|/κ, the
    static displacement), where h²/2 a is not. The velocity's part is kept whole: a stiff
    cluster moving as a body keeps its slow motion in the guess."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    start = work[0]
    len0, dir0, keep, fs, ws, sweep, nodal, stiff, code = start
    m = edges.shape[0]
    # (the work record rebuilt in the loop: Numba cannot hand a record that holds a record to
    # a parallel loop's body)
    work_arrays = work[1:]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = np.int64(blk) * BLOCK
        em2_predict_springs(eta, spring, (start,) + work_arrays, lo, min(BLOCK, m - lo))
    q = 0.25 * h * h
    for a in prange(x0.shape[0]):
        k = free_index[a]
        if k < 0:
            continue
        kappa = 0.0
        for j in range(inc_ptr[a], inc_ptr[a + 1]):
            kappa += stiff[inc_spring[j]]
        damp = 1.0 / (1.0 + q * kappa * inv_mass[a])
        for i in range(3):
            pred[3 * k + i] = h * inv_mass[a] * p[a, i] + damp * 0.5 * h * h * accel[3 * k + i]


def _em2_predict_springs(eta, spring, work, lo, n):
    """Springs lo … lo + n − 1 of :func:`_em2_predict`'s spring loop (n ≤ BLOCK), a serial
    function called once per block: see thermonet.explicit.cpu._spring_pass."""
    l0, P = spring
    start, len1, dir1, mean, slope, dslope, energy0, temperature0, tension0, jc, eta_step, quotient, tension1 = work
    len0, dir0, keep, fs, ws, sweep, nodal, stiff, code = start
    for i in range(n):
        e = np.uint64(lo + i)
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        l = len0[e]
        th = temperature(l, eta[e], l0[e], P, pe)
        T = tension(l, th, l0[e], P, pe)
        if EXACT_QUOTIENT:
            temperature0[e] = th
        else:
            energy0[e] = internal_energy(l, eta[e], l0[e], P, pe)
        tension0[e] = T
        eta_step[e] = eta[e]
        stiff[e] = max(adiabatic_stiffness(l, eta[e], l0[e], P, pe), 0.0) + max(T / l, 0.0)


def _em2_residual(step, topo, spring, node, work, u, res):
    """R, Rabs (3 n_free,) of ``res`` at unknowns u (3 n_free,) (module doc); fills ``work``'s
    len1, dir1, mean, slope, quotient, tension1 for the Jacobian and the finish, and the start record's fs
    (≥ 3, m) with each spring's (h/2) s d̄. Needs ``work.energy0``, ``tension0`` (predict).
    Returns (status, spring, max |R|, max Rabs)."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    start, len1, dir1, mean, slope, dslope, energy0, temperature0, tension0, jc, eta_step, quotient, tension1 = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    R, Rabs, peak = res
    m = edges.shape[0]
    half = 0.5 * h
    bad = m
    # (the work record rebuilt in the loop: Numba cannot hand a record that holds a record to
    # a parallel loop's body)
    work_arrays = work[1:]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = np.int64(blk) * BLOCK
        bad = min(bad, em2_residual_springs(step, topo, spring, (start,) + work_arrays, u, lo, min(BLOCK, m - lo)))
    if bad < m:
        return code[bad], bad, math.inf, math.inf
    rmax = 0.0
    smax = 0.0
    for blk in prange(node_blocks(x0.shape[0])):
        big, scale = residual_rows3(step, topo, node, fs, u, half, R, Rabs, blk)
        rmax = max(rmax, big)
        smax = max(smax, scale)
    return 0, -1, rmax, smax


def _em2_residual_springs(step, topo, spring, work, u, lo, n):
    """Springs lo … lo + n − 1 of :func:`_em2_residual` (n ≤ BLOCK), a serial function called
    once per block: see thermonet.explicit.cpu._spring_pass. Returns the block's first flagged
    spring (m if none)."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    start, len1, dir1, mean, slope, dslope, energy0, temperature0, tension0, jc, eta_step, quotient, tension1 = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    m = edges.shape[0]
    half = 0.5 * h
    for i in range(n):  # gather: the spring vectors at x⁰ and x¹
        e = np.uint64(lo + i)
        a = edges[e, 0]
        b = edges[e, 1]
        ka = free_index[a]
        kb = free_index[b]
        for j in range(3):
            d0 = x0[b, j] - x0[a, j]
            d1 = d0
            if kb >= 0:
                d1 += u[3 * kb + j]
            if ka >= 0:
                d1 -= u[3 * ka + j]
            fs[j, e] = d1
            mean[j, e] = 0.5 * (d0 + d1)
    for i in range(n):  # per spring, Q in closed form or by the rule (branch-free: vectorized)
        e = np.uint64(lo + i)
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        dx = fs[0, e]
        dy = fs[1, e]
        dz = fs[2, e]
        l1 = math.sqrt(dx * dx + dy * dy + dz * dz)
        len1[e] = l1
        i1 = 1.0 / l1
        dir1[0, e] = dx * i1
        dir1[1, e] = dy * i1
        dir1[2, e] = dz * i1
        lok = (l1 > 0.0) & (l1 < math.inf)
        if EXACT_QUOTIENT:
            quotient[e] = energy_quotient(len0[e], l1, eta[e], temperature0[e], tension0[e], l0[e], P, pe)[0]
            if CAN_VANISH:
                th1 = temperature(l1, eta[e], l0[e], P, pe)
                code[e] = OK if (lok & _admissible(th1)) else (COLLAPSED if not lok else NO_TEMPERATURE)
            else:
                code[e] = OK if lok else COLLAPSED
        else:
            th1 = temperature(l1, eta[e], l0[e], P, pe)
            T1 = tension(l1, th1, l0[e], P, pe)
            quotient[e] = lobatto_value(len0[e], l1, eta[e], l0[e], P, pe, tension0[e], T1)
            tension1[e] = T1
            code[e] = OK if (lok & _admissible(th1)) else (COLLAPSED if not lok else NO_TEMPERATURE)
    for i in range(n):  # s and the impulses (h/2) s d̄ (fewer arrays per loop: vectorized)
        e = np.uint64(lo + i)
        s = quotient[e] / (0.5 * (len0[e] + len1[e]))
        slope[e] = s
        g = half * s
        fs[0, e] = g * mean[0, e]
        fs[1, e] = g * mean[1, e]
        fs[2, e] = g * mean[2, e]
        code[e] = NOT_FINITE if ((code[e] == OK) & (not abs(s) < math.inf)) else code[e]
    for i in range(0 if EXACT_QUOTIENT else n):  # the quotient ΔU/δ instead where |δ| > SWITCH l̄ (scalar)
        e = np.uint64(lo + i)
        l = len0[e]
        l1 = len1[e]
        if not abs(l1 - l) > SWITCH * (0.5 * (l + l1)):
            continue
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        Q = (internal_energy(l1, eta[e], l0[e], P, pe) - energy0[e]) / (l1 - l)
        quotient[e] = Q
        s = Q / (0.5 * (l + l1))
        slope[e] = s
        g = half * s
        fs[0, e] = g * mean[0, e]
        fs[1, e] = g * mean[1, e]
        fs[2, e] = g * mean[2, e]
        if code[e] == OK or code[e] == NOT_FINITE:
            code[e] = OK if abs(s) < math.inf else NOT_FINITE
    return _first_flagged(code, lo, n, m)


def _em2_linearize(spring, work, h):
    """ds/dl¹ (``work.dslope``) and the matrix-free coefficients at the last residual's point:
    jc (2, m) = (h s/4, h (ds/dl¹)/2), spring e's block being jc[0] I + jc[1] d̄ n¹ᵀ; ds/dl¹ as
    :func:`_em2_spring_dslope`, in a vectorized loop (the model's closed form, or the rule) and,
    for the generic forms, a scalar one where |δ| > SWITCH l̄ (as the residual)."""
    start, len1, dir1, mean, slope, dslope, energy0, temperature0, tension0, jc, eta_step, quotient, tension1 = work
    m = len1.shape[0]
    # (the work record rebuilt in the loop: Numba cannot hand a record that holds a record to
    # a parallel loop's body)
    work_arrays = work[1:]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = np.int64(blk) * BLOCK
        em2_linearize_springs(spring, (start,) + work_arrays, h, lo, min(BLOCK, m - lo))


def _em2_linearize_springs(spring, work, h, lo, n):
    """Springs lo … lo + n − 1 of :func:`_em2_linearize` (n ≤ BLOCK), a serial function called
    once per block: see thermonet.explicit.cpu._spring_pass."""
    l0, P = spring
    start, len1, dir1, mean, slope, dslope, energy0, temperature0, tension0, jc, eta_step, quotient, tension1 = work
    len0 = start[0]
    for i in range(n):
        e = np.uint64(lo + i)
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        l = len0[e]
        l1 = len1[e]
        if EXACT_QUOTIENT:
            dQ = energy_quotient(l, l1, eta_step[e], temperature0[e], tension0[e], l0[e], P, pe)[1]
        else:
            dQ = lobatto_derivative(l, l1, eta_step[e], l0[e], P, pe)
        ds = (dQ - 0.5 * slope[e]) / (0.5 * (l + l1))
        dslope[e] = ds
        jc[0, e] = 0.25 * h * slope[e]
        jc[1, e] = 0.5 * h * ds
    for i in range(0 if EXACT_QUOTIENT else n):
        e = np.uint64(lo + i)
        l = len0[e]
        l1 = len1[e]
        if abs(l1 - l) > SWITCH * (0.5 * (l + l1)):
            ds = ((tension1[e] - quotient[e]) / (l1 - l) - 0.5 * slope[e]) / (0.5 * (l + l1))
            dslope[e] = ds
            jc[1, e] = 0.5 * h * ds


def _em2_jacobian(topo, spring, node, work, places, h, data):
    """Values of ∂R/∂u at the last residual's point into the CSR value array ``data`` (nnz,),
    at the places of ``places`` (BlockPlaces): m_c/h I on the diagonal blocks, and each spring's
    B = (h/2) [(s/2) I + (ds/dl¹) d̄ n¹ᵀ] with sign s_c s_g."""
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    start, len1, dir1, mean, slope, dslope, energy0, temperature0, tension0, jc, eta_step, quotient, tension1 = work
    node_base, node_stride, spring_base, spring_stride, B = places
    inertia_blocks3(free_index, masses, h, node_base, node_stride, data)
    for e in range(edges.shape[0]):
        eu = np.uint64(e)
        dslope[eu] = em2_spring_dslope(spring, work, eu, np.uint64(0) if UNIFORM else eu)
        c1 = 0.25 * h * slope[e]
        c2 = 0.5 * h * dslope[e]
        for i in range(3):
            for j in range(3):
                B[i, j] = c2 * mean[i, e] * dir1[j, e] + (c1 if i == j else 0.0)
        scatter_spring_block(data, places, e, B, 3)


def _em2_finish(step, topo, spring, node, work, u, phi, new):
    """The next state from converged unknowns u into ``new`` (StateArrays; phi (m,) the step's
    start): x¹ = x⁰ + d; p¹ = p⁰ + h m g + h Σ ±s d̄ (fs, from the last residual, evaluated at u,
    doubled: exact); η¹ = η; Φ¹ = Φ⁰ + h θ(l̄, η). Returns (status, spring)."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    start, len1, dir1, mean, slope, dslope, energy0, temperature0, tension0, jc, eta_step, quotient, tension1 = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    x_new, p_new, phi_new, eta_new = new
    m = edges.shape[0]
    bad = m
    # (the work record rebuilt in the loop: Numba cannot hand a record that holds a record to
    # a parallel loop's body)
    work_arrays = work[1:]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = np.int64(blk) * BLOCK
        bad = min(bad, em2_finish_springs(step, topo, spring, (start,) + work_arrays, phi, new, lo,
                                          min(BLOCK, m - lo)))
    if bad < m:
        return code[bad], bad
    return finish_nodes(step, topo, node, fs, u, 3, 0, new)


def _em2_finish_springs(step, topo, spring, work, phi, new, lo, n):
    """Springs lo … lo + n − 1 of :func:`_em2_finish` (n ≤ BLOCK), a serial function called once
    per block: see thermonet.explicit.cpu._spring_pass. Returns the block's first flagged spring
    (m if none)."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    start, len1, dir1, mean, slope, dslope, energy0, temperature0, tension0, jc, eta_step, quotient, tension1 = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    x_new, p_new, phi_new, eta_new = new
    m = edges.shape[0]
    for i in range(n):
        e = np.uint64(lo + i)
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        guess[e] = temperature(0.5 * (len0[e] + len1[e]), eta[e], l0[e], P, pe)
    for i in range(n):  # the stores apart (with them, the loop above was scalar)
        e = np.uint64(lo + i)
        th = guess[e]
        phi_new[e] = phi[e] + h * th
        eta_new[e] = eta[e]
        fs[0, e] *= 2.0
        fs[1, e] *= 2.0
        fs[2, e] *= 2.0
        code[e] = OK if _admissible(th) else NO_TEMPERATURE
    return _first_flagged(code, lo, n, m)


def _em2_sweep(topo, node, work, h, du, R, r, update, first):
    """r = R − J du (du, R, r: (3 n_free,)); with ``update``, then du += D⁻¹ r (and r is not
    written). Returns max |r|. ``first``: du is taken as zero. Spring e's block applied to
    v = du_a − du_b: jc[0] v + jc[1] (n¹·v) d̄."""
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    start, len1, dir1, mean, slope, dslope, energy0, temperature0, tension0, jc, eta_step, quotient, tension1 = work
    len0, dir0, keep, fs, ws, w, nodal, guess, code = start
    m = ends.shape[0]
    for e in prange(0 if first else m):
        eu = np.uint64(e)
        ka = ends[eu, 0]
        kb = ends[eu, 1]
        v0, v1, v2 = spring_difference3(du, ka, kb)
        c = jc[1, eu] * (dir1[0, eu] * v0 + dir1[1, eu] * v1 + dir1[2, eu] * v2)
        c1 = jc[0, eu]
        w[eu, 0] = c1 * v0 + c * mean[0, eu]
        w[eu, 1] = c1 * v1 + c * mean[1, eu]
        w[eu, 2] = c1 * v2 + c * mean[2, eu]
    rmax = 0.0
    for blk in prange(node_blocks(free_index.shape[0])):
        rmax = max(rmax, sweep_rows3(topo, node, h, w, du, R, r, blk, update, first))
    return rmax


def _em2_step_scale(topo, work, du, limit):
    """The largest factor ≤ 1 by which a Newton correction du (3 n_free,; applied as u −= du)
    may be scaled so that no spring's vector changes by more than ``limit`` times its length at
    the last residual's point (``work.len1``)."""
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    len1 = work[1]
    m = ends.shape[0]
    scale = 1.0
    for blk in prange((m + BLOCK - 1) // BLOCK):  # (a min: the same result on any threads)
        for e in range(blk * BLOCK, min(m, blk * BLOCK + BLOCK)):
            ka = ends[e, 0]
            kb = ends[e, 1]
            v2 = 0.0
            for i in range(3):
                v = (du[3 * kb + i] if kb >= 0 else 0.0) - (du[3 * ka + i] if ka >= 0 else 0.0)
                v2 += v * v
            reach = limit * len1[e]
            if v2 > reach * reach:
                scale = min(scale, reach / math.sqrt(v2))
    return scale


def _em2_damp(step, topo, spring, node, work, res, norms, vectors):
    """The damped Newton step (implicit/em2/stepper.py, LengthLimited). vectors: (u, du, trial)
    (size,) each: du, a correction to be applied as u −= du, is scaled in place so that no
    spring's vector changes by more than LENGTH_LIMIT times its length (``step_scale``); while
    the scaled residual rmax/smax (norms, at u) is above LINE_SEARCH_ABOVE, then halved until the
    residual's 2-norm falls (Armijo, at most LINE_SEARCH_HALVINGS times; the trial points in
    ``trial``, the residual ``res`` and ``work`` left at the last one). Returns (evaluated, max
    |R|, max Rabs): evaluated when the search accepted its trial point (``res``, ``work``: its)."""
    u, du, trial = vectors
    rmax, smax = norms
    scale = em2_step_scale(topo, work, du, LENGTH_LIMIT)
    evaluated = False
    tmax = tscale = 0.0
    if rmax > LINE_SEARCH_ABOVE * smax:
        R = res[0]
        r0 = norm2(R)
        for _ in range(LINE_SEARCH_HALVINGS):
            for i in range(u.shape[0]):
                trial[i] = u[i] - scale * du[i]
            status, bad, tmax, tscale = em2_residual(step, topo, spring, node, work, trial, res)
            if status == 0 and norm2(R) <= (1.0 - 1e-4 * scale) * r0:
                evaluated = True
                break
            scale *= 0.5
    elif not scale < 1.0:
        return False, 0.0, 0.0
    for i in range(du.shape[0]):
        du[i] *= scale
    return evaluated, tmax, tscale


def _em2_compiled_predict(step, topo, spring, node, work, extra, u):
    em2_predict(step, topo, spring, node, work, u, u)  # in place: each entry is read, then written


def _em2_compiled_residual(step, topo, spring, node, work, extra, u, warm, res):
    return em2_residual(step, topo, spring, node, work, u, res)


def _em2_compiled_jacobian(topo, spring, node, work, places, extra, h, data):
    em2_jacobian(topo, spring, node, work, places, h, data)


def _em2_compiled_finish(step, topo, spring, node, work, extra, u, phi, new):
    return em2_finish(step, topo, spring, node, work, u, phi, new)


def _em2_compiled_linearize(spring, work, extra, h):
    em2_linearize(spring, work, h)


def _em2_compiled_damp(step, topo, spring, node, work, extra, res, norms, vectors):
    return em2_damp(step, topo, spring, node, work, res, norms, vectors)


register_scheme("em2", build)
