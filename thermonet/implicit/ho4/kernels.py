"""HO4's kernels (docs/theory.md §2.2, paper (53)–(59)): the residual (also as a SUBSET variant over listed
springs and nodes, for local Jacobi steps) and the finish, as Numba templates compiled per model
by :func:`build` (registered as scheme "ho4"); the per-spring thermal solve is
:mod:`thermonet.implicit.ho4.thermal`, the Newton matrix (assembled, matrix-free, Jacobi rows) :mod:`thermonet.implicit.ho4.linear`.
Conventions (records, blocking, status codes): :mod:`thermonet.implicit.core.schemes`.

Unknowns d^½, d¹ per free node (block of 6); θ⁰, θ¹ condensed per spring (θ^½ = mean):

    R1_c = m_c (8 d^½ − d¹)_c / (3h) − (h/6) f⁰_c − p_c                                 (58a)
    R2_c = m_c (d¹ − 2 d^½)_c / h − (h/4) f^½_c                              (57a) × h/4
    Γ⁰ = Γ¹,  (3Γ⁰ + 4Γ^½ − Γ¹)/6 = η                                 per spring (57b), (58c)

The work record is :class:`HO4Work`: per spring lenh, len1 (m,) and dirh, dir1 (3, m) at x^½
and x¹, θ⁰ ``th0`` and θ¹ ``th1`` (m,), ``dth`` (4, m) = dθ⁰/dl^½, dθ⁰/dl¹, dθ¹/dl^½,
dθ¹/dl¹, ``gs`` (m,) = Γ⁰ = Γ¹ (the next residual's seed), the matrix-free coefficients ``jc``
(5, m), and the start kernel's :class:`~thermonet.implicit.core.records.StartWork` (``start``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import prange

from ..core.schemes import (BLOCK, COLLAPSED, INLINE, LOG_AFFINE, NO_TEMPERATURE, NOT_FINITE, OK, OPTIONS,
                            UNIFORM, _admissible, _all_count, _first_flagged, _first_flagged_entry,
                            _first_flagged_position, _listed_count, _listed_entry, _listed_position,
                            register_scheme)
from ..core.records import StartWork
from ...kernels.specialize import specialize, specialize_by_content
from . import linear as _linear, thermal as _thermal
from ..core import local_jacobi as _local

# Bound per model by specialize(); listed so the templates read as ordinary code.
entropy = temperature = tension = d2F_dtheta2 = None
ho4_thermal = ho4_thermal_vector = ho4_thermal_closed = finish_nodes = None
ho4_residual = ho4_jacobian = ho4_finish = ho4_linearize = ho4_local_jacobi = None
ho4_residual_springs = ho4_finish_springs = None
#: the residual's index helpers, bound per variant (a kernel compiled with a conditional index
#: ran 25 % slower): in the full kernel ``listed(indices, j)`` is j, ``listed_count(indices, n)``
#: is n and ``first_flagged_listed`` is :func:`_first_flagged`; in the SUBSET kernel, which
#: recomputes only the listed springs and node rows, indices[j], len(indices) and the same over
#: the listed entries
listed = listed_count = first_flagged_listed = None


class HO4Work(NamedTuple):
    """HO4's per-spring arrays (see the module doc); shapes for m springs."""

    start: StartWork
    lenh: np.ndarray
    dirh: np.ndarray
    len1: np.ndarray
    dir1: np.ndarray
    th0: np.ndarray
    th1: np.ndarray
    dth: np.ndarray
    gs: np.ndarray
    jc: np.ndarray

    @classmethod
    def allocate(cls, start: StartWork) -> "HO4Work":
        m = start.len0.shape[0]
        return cls(start, np.empty(m), np.empty((3, m)), np.empty(m), np.empty((3, m)), np.empty(m), np.empty(m),
                   np.empty((4, m)), np.empty(m), np.empty((5, m)))


def build(ns: dict, tag: str, ptag: str, parallel: bool) -> dict:
    """HO4's kernels for the model namespace ``ns`` (see core.schemes.register_scheme)."""
    t = _thermal
    ns["ho4_derivatives"] = specialize(t._ho4_derivatives, tag, ns, **INLINE)
    ns["ho4_temperature_derivatives"] = specialize(t._ho4_temperature_derivatives, tag, ns, **INLINE)
    ns["ho4_correct"] = specialize(t._ho4_correct, tag, ns, **INLINE)
    ns["ho4_thermal_closed"] = specialize(t._ho4_thermal_closed, tag, ns, **INLINE)
    ns["ho4_thermal_exact"] = specialize(t._ho4_thermal_exact, tag, ns, **INLINE)
    ns["ho4_thermal"] = specialize(t._ho4_thermal, tag, ns, **OPTIONS)
    ns["ho4_thermal_vector"] = specialize(t._ho4_thermal_vector, tag, ns, **INLINE)
    subset = dict(ns, listed=_listed_entry, listed_count=_listed_count, first_flagged_listed=_first_flagged_entry)
    ns.update(listed=_listed_position, listed_count=_all_count, first_flagged_listed=_first_flagged_position)
    # (the spring blocks: serial, shared by the serial and the threaded kernels)
    ns["ho4_residual_springs"] = specialize_by_content(_ho4_residual_springs, tag, ns, **OPTIONS)
    subset["ho4_residual_springs"] = specialize_by_content(_ho4_residual_springs, f"{tag}_subset", subset, **OPTIONS)
    ns["ho4_finish_springs"] = specialize_by_content(_ho4_finish_springs, tag, ns, **OPTIONS)
    residual = specialize(_ho4_residual, ptag, ns, parallel=parallel, **OPTIONS)
    jacobian = specialize(_linear._ho4_jacobian, tag, ns, **OPTIONS)
    finish = specialize(_ho4_finish, ptag, ns, parallel=parallel, **OPTIONS)
    linearize = specialize(_linear._ho4_linearize, ptag, ns, parallel=parallel, **OPTIONS)
    calls = dict(ns, ho4_residual=residual, ho4_jacobian=jacobian, ho4_finish=finish, ho4_linearize=linearize)
    residual_subset = specialize(_ho4_residual, f"{ptag}_subset", subset, parallel=parallel, **OPTIONS)
    local_calls = dict(scheme_jacobi_rows=_linear.ho4_jacobi_rows, scheme_residual_subset=residual_subset)
    calls["ho4_local_jacobi"] = specialize(_local._local_jacobi, ptag, local_calls, **OPTIONS)
    return dict(
        residual=residual,
        residual_subset=residual_subset,
        local_jacobi=calls["ho4_local_jacobi"],
        linearize=linearize,
        jacobian=jacobian,
        finish=finish,
        # the compiled Newton path's signatures (implicit/core/compiled_newton.py), extra = (springs,
        # nodes, local): the residual's two empty index lists, the local Jacobi step's scratch
        compiled_residual=specialize(_ho4_compiled_residual, ptag, calls, **INLINE),
        compiled_jacobian=specialize(_ho4_compiled_jacobian, ptag, calls, **INLINE),
        compiled_finish=specialize(_ho4_compiled_finish, ptag, calls, **INLINE),
        compiled_linearize=specialize(_ho4_compiled_linearize, ptag, calls, **INLINE),
        compiled_local=specialize(_ho4_compiled_local, ptag, calls, **INLINE),
        sweep=_linear.sweep_kernel(parallel),
        jacobi_rows=_linear.ho4_jacobi_rows,
        thermal=ns["ho4_thermal"],
        # the two per-spring solves, callable alone (tests)
        thermal_vector=specialize(t._ho4_thermal_vector, f"{tag}_alone", ns, **OPTIONS),
    )


def _ho4_residual(step, topo, spring, node, work, u, warm, res, springs, nodes):
    """``res``: R, Rabs (6 n_free,) at unknowns u (6 n_free,), and peak (2, n_free) each free
    node's largest |R| and Rabs (for the local steps' node selection; Rabs or peak may be
    empty, then not written: the compiled Newton path passes an empty Rabs, reading only its
    maximum); fills ``work``'s lengths (m,) and unit vectors (3, m) at x^½ and x¹, θ⁰, θ¹ (m,), dth (4, m) = dθ⁰/dl^½, dθ⁰/dl¹,
    dθ¹/dl^½, dθ¹/dl¹ and gs (m,) = Γ⁰ = Γ¹. With ``warm``, the previous call's gs (at nearby u),
    moved along its length derivatives, seeds the thermal solves. With LOG_AFFINE (closed-form
    solves: no seeds) dth and gs are not written; the linearization and the Jacobian recompute
    the derivatives from the lengths and temperatures (they are called less often), and the
    solve and the force at x⁰ use what the start kernel kept of the step's start
    (``work.start.keep``, KEEP_START): T(l⁰, θ⁰) = T(l⁰, A) + F_lθ(l⁰) (θ⁰ − A), exact for a
    LOG_AFFINE model, whose tension is affine in θ. The start record's fs (6, m), guess, code
    (m,): scratch; fs holds each spring's force terms afterwards. The SUBSET variant computes
    only the springs listed in ``springs`` (int64) and the rows of the free nodes listed in
    ``nodes`` (int64), in the same arithmetic and order as a full call: after u changed at a few
    nodes, the listed springs are those at these nodes and the listed nodes those at these
    springs' ends, and the rest keep the values of the last call (in the full kernel both lists
    are empty and unused). Returns (status, spring, max |R|, max Rabs), the maxima over the rows
    computed."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    start, lenh, dirh, len1, dir1, th0, th1, dth, gs, jc = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    R, Rabs, peak = res
    none = edges.shape[0]
    m = listed_count(springs, none)
    bad = none
    # (the work record rebuilt in the loop: Numba cannot hand a record that holds a record to
    # a parallel loop's body)
    work_arrays = work[1:]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = np.int64(blk) * BLOCK
        bad = min(bad, ho4_residual_springs(step, topo, spring, (start,) + work_arrays, u, warm, springs, lo,
                                            min(BLOCK, m - lo)))
    if bad < none:
        return code[bad], bad, math.inf, math.inf
    rmax = 0.0
    smax = 0.0
    magnitudes = Rabs.shape[0] > 0
    peaks = peak.shape[1] > 0
    for j_node in prange(listed_count(nodes, x0.shape[0])):
        a = listed(nodes, j_node)
        k = free_index[a]
        if k < 0:
            continue
        w = masses[a] / h
        # the node's rows and their magnitudes in registers, written once (the same sums in the
        # same order as accumulating in R, Rabs)
        g0 = h / 6.0 * masses[a] * gravity[0] if with_gravity else 0.0
        gh = h / 4.0 * masses[a] * gravity[0] if with_gravity else 0.0
        i1 = w * (8.0 * u[6 * k + 0] - u[6 * k + 3]) / 3.0
        i2 = w * (u[6 * k + 3] - 2.0 * u[6 * k + 0])
        r0 = i1 - p[a, 0] - g0
        s0 = abs(i1) + abs(p[a, 0]) + abs(g0)
        r3 = i2 - gh
        s3 = abs(i2) + abs(gh)
        g0 = h / 6.0 * masses[a] * gravity[1] if with_gravity else 0.0
        gh = h / 4.0 * masses[a] * gravity[1] if with_gravity else 0.0
        i1 = w * (8.0 * u[6 * k + 1] - u[6 * k + 4]) / 3.0
        i2 = w * (u[6 * k + 4] - 2.0 * u[6 * k + 1])
        r1 = i1 - p[a, 1] - g0
        s1 = abs(i1) + abs(p[a, 1]) + abs(g0)
        r4 = i2 - gh
        s4 = abs(i2) + abs(gh)
        g0 = h / 6.0 * masses[a] * gravity[2] if with_gravity else 0.0
        gh = h / 4.0 * masses[a] * gravity[2] if with_gravity else 0.0
        i1 = w * (8.0 * u[6 * k + 2] - u[6 * k + 5]) / 3.0
        i2 = w * (u[6 * k + 5] - 2.0 * u[6 * k + 2])
        r2 = i1 - p[a, 2] - g0
        s2 = abs(i1) + abs(p[a, 2]) + abs(g0)
        r5 = i2 - gh
        s5 = abs(i2) + abs(gh)
        for j in range(inc_ptr[a], inc_ptr[a + 1]):
            e = inc_spring[j]
            sg = -inc_sign[j]
            v0 = fs[0, e]
            v1 = fs[1, e]
            v2 = fs[2, e]
            v3 = fs[3, e]
            v4 = fs[4, e]
            v5 = fs[5, e]
            r0 += sg * v0
            s0 += abs(v0)
            r1 += sg * v1
            s1 += abs(v1)
            r2 += sg * v2
            s2 += abs(v2)
            r3 += sg * v3
            s3 += abs(v3)
            r4 += sg * v4
            s4 += abs(v4)
            r5 += sg * v5
            s5 += abs(v5)
        R[6 * k + 0] = r0
        R[6 * k + 1] = r1
        R[6 * k + 2] = r2
        R[6 * k + 3] = r3
        R[6 * k + 4] = r4
        R[6 * k + 5] = r5
        if magnitudes:
            Rabs[6 * k + 0] = s0
            Rabs[6 * k + 1] = s1
            Rabs[6 * k + 2] = s2
            Rabs[6 * k + 3] = s3
            Rabs[6 * k + 4] = s4
            Rabs[6 * k + 5] = s5
        big = max(max(abs(r0), abs(r1)), max(max(abs(r2), abs(r3)), max(abs(r4), abs(r5))))
        if not (abs(r0) + abs(r1) + abs(r2) + abs(r3) + abs(r4) + abs(r5) < math.inf):
            big = math.inf  # a NaN row (max() passes over NaN) shows in the norm as not finite
        scale = max(max(s0, s1), max(max(s2, s3), max(s4, s5)))
        if peaks:
            peak[0, k] = big
            peak[1, k] = scale
        rmax = max(rmax, big)
        smax = max(smax, scale)
    return 0, -1, rmax, smax


def _ho4_residual_springs(step, topo, spring, work, u, warm, springs, lo, n):
    """Springs lo … lo + n − 1 (of the list ``springs`` where SUBSET) of :func:`_ho4_residual`
    (n ≤ BLOCK), a serial function called once per block: see
    thermonet.explicit.cpu._spring_pass. Returns the block's first flagged spring (m if
    none)."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    start, lenh, dirh, len1, dir1, th0, th1, dth, gs, jc = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    none = edges.shape[0]
    for i in range(n):  # gather: the spring vectors at x^½ and x¹
        e = np.uint64(listed(springs, lo + i))
        a = edges[e, 0]
        b = edges[e, 1]
        ka = free_index[a]
        kb = free_index[b]
        ex = x0[b, 0] - x0[a, 0]
        ey = x0[b, 1] - x0[a, 1]
        ez = x0[b, 2] - x0[a, 2]
        hx = ex
        hy = ey
        hz = ez
        if kb >= 0:
            hx += u[6 * kb]
            hy += u[6 * kb + 1]
            hz += u[6 * kb + 2]
            ex += u[6 * kb + 3]
            ey += u[6 * kb + 4]
            ez += u[6 * kb + 5]
        if ka >= 0:
            hx -= u[6 * ka]
            hy -= u[6 * ka + 1]
            hz -= u[6 * ka + 2]
            ex -= u[6 * ka + 3]
            ey -= u[6 * ka + 4]
            ez -= u[6 * ka + 5]
        fs[0, e] = hx
        fs[1, e] = hy
        fs[2, e] = hz
        fs[3, e] = ex
        fs[4, e] = ey
        fs[5, e] = ez
    for i in range(n):  # geometry (vectorized; a loop of its own: with the thermal solve's
        # stores in the same loop, LLVM did not vectorize it)
        e = np.uint64(listed(springs, lo + i))
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        hx = fs[0, e]
        hy = fs[1, e]
        hz = fs[2, e]
        ex = fs[3, e]
        ey = fs[4, e]
        ez = fs[5, e]
        lh = math.sqrt(hx * hx + hy * hy + hz * hz)
        l1 = math.sqrt(ex * ex + ey * ey + ez * ez)
        if not LOG_AFFINE:  # a seed (the closed form needs none): G = Γ(l⁰, θ⁰) moved along dG/dl
            guess[e] = gs[e] - d2F_dtheta2(len0[e], th0[e], l0[e], P, pe) * (
                dth[0, e] * (lh - lenh[e]) + dth[1, e] * (l1 - len1[e]))
        lenh[e] = lh
        ih = 1.0 / lh
        dirh[0, e] = hx * ih
        dirh[1, e] = hy * ih
        dirh[2, e] = hz * ih
        len1[e] = l1
        i1 = 1.0 / l1
        dir1[0, e] = ex * i1
        dir1[1, e] = ey * i1
        dir1[2, e] = ez * i1
    for i in range(n):  # thermal solve (vectorized; the forces in a loop of their own, as above)
        e = np.uint64(listed(springs, lo + i))
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        lh = lenh[e]
        l1 = len1[e]
        rest = l0[e]
        if LOG_AFFINE:
            G, t0, t1 = ho4_thermal_closed(keep[0, e], temperature(l1, eta[e], rest, P, pe), keep[3, e], lh,
                                           eta[e], rest, P, pe)
        else:
            G, t0, t1, d0h, d01, d1h, d11, ok = ho4_thermal_vector(len0[e], lh, l1, eta[e], rest, P, pe, guess[e],
                                                                   warm)
            # the warm seed and its derivatives (else recomputed where needed)
            gs[e] = G
            dth[0, e] = d0h
            dth[1, e] = d01
            dth[2, e] = d1h
            dth[3, e] = d11
            code[e] = ok  # the solve's success, read by the force loop
        th0[e] = t0
        th1[e] = t1
    for i in range(n):  # forces (vectorized)
        e = np.uint64(listed(springs, lo + i))
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        lh = lenh[e]
        l1 = len1[e]
        rest = l0[e]
        t0 = th0[e]
        t1 = th1[e]
        if LOG_AFFINE:  # T(l⁰, θ⁰) = T(l⁰, A) + F_lθ(l⁰) (θ⁰ − A), exact (see the doc)
            c0 = h / 6.0 * (keep[1, e] + keep[2, e] * (t0 - keep[0, e]))
        else:
            c0 = h / 6.0 * tension(len0[e], t0, rest, P, pe)
        ch = h / 4.0 * tension(lh, 0.5 * (t0 + t1), rest, P, pe)
        fs[0, e] = c0 * dir0[0, e]
        fs[1, e] = c0 * dir0[1, e]
        fs[2, e] = c0 * dir0[2, e]
        fs[3, e] = ch * dirh[0, e]
        fs[4, e] = ch * dirh[1, e]
        fs[5, e] = ch * dirh[2, e]
    for i in range(n):  # the springs' status, apart from the forces (in their loop, it kept
        # LLVM from vectorizing it: the residual cost 1.6× as much)
        e = np.uint64(listed(springs, lo + i))
        lh = lenh[e]
        l1 = len1[e]
        if LOG_AFFINE:
            ok = _admissible(th0[e]) & _admissible(th1[e])
        else:
            ok = code[e] != 0
        lok = (lh > 0.0) & (lh < math.inf) & (l1 > 0.0) & (l1 < math.inf)
        code[e] = OK if (ok & lok) else NO_TEMPERATURE
    for i in range(n):  # the scalar solve where the vectorized one did not converge
        e = listed(springs, lo + i)
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        if code[e] == OK:
            continue
        lh = lenh[e]
        l1 = len1[e]
        if not (lh > 0.0 and lh < math.inf and l1 > 0.0 and l1 < math.inf):
            code[e] = COLLAPSED
            continue
        la = len0[e]
        seed = guess[e]
        if LOG_AFFINE:  # no seed was written: start from η
            seed = eta[e]
        G, t0, t1, d0h, d01, d1h, d11, ok = ho4_thermal(la, lh, l1, eta[e], l0[e], P, pe, seed, warm)
        if not LOG_AFFINE:
            gs[e] = G
        if not ok:
            continue
        code[e] = OK
        th0[e] = t0
        th1[e] = t1
        if not LOG_AFFINE:
            dth[0, e] = d0h
            dth[1, e] = d01
            dth[2, e] = d1h
            dth[3, e] = d11
        c0 = h / 6.0 * tension(la, t0, l0[e], P, pe)
        ch = h / 4.0 * tension(lh, 0.5 * (t0 + t1), l0[e], P, pe)
        for j in range(3):
            fs[j, e] = c0 * dir0[j, e]
            fs[3 + j, e] = ch * dirh[j, e]
    return first_flagged_listed(code, springs, lo, n, none)


def _ho4_finish(step, topo, spring, node, work, u, phi, new):
    """The next state from converged unknowns u into ``new`` (StateArrays; phi (m,) the step's
    start): x¹ = x⁰ + d¹; Φ¹ = Φ⁰ + h (θ⁰ + θ¹)/2; η¹ = (−Γ⁰ + 4Γ^½ + 3Γ¹)/6 measured (58d);
    and p¹ = p⁰ + h (f⁰ + 4 f^½ + f¹)/6, which is (58b) given (58a) and (57a) and conserves
    linear momentum to round-off whatever the solver residual. fs must hold the last residual's
    per-spring terms (that residual was evaluated at u). Returns (status, spring)."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    start, lenh, dirh, len1, dir1, th0, th1, dth, gs, jc = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    x_new, p_new, phi_new, eta_new = new
    m = edges.shape[0]
    bad = m
    # (the work record rebuilt in the loop: Numba cannot hand a record that holds a record to
    # a parallel loop's body)
    work_arrays = work[1:]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = np.int64(blk) * BLOCK
        bad = min(bad, ho4_finish_springs(step, topo, spring, (start,) + work_arrays, phi, new, lo,
                                          min(BLOCK, m - lo)))
    if bad < m:
        return code[bad], bad
    return finish_nodes(step, topo, node, fs, u, 6, 3, new)


def _ho4_finish_springs(step, topo, spring, work, phi, new, lo, n):
    """Springs lo … lo + n − 1 of :func:`_ho4_finish` (n ≤ BLOCK), a serial function called once
    per block: see thermonet.explicit.cpu._spring_pass. Returns the block's first flagged spring
    (m if none)."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    start, lenh, dirh, len1, dir1, th0, th1, dth, gs, jc = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    x_new, p_new, phi_new, eta_new = new
    m = edges.shape[0]
    for i in range(n):  # vectorized
        e = np.uint64(lo + i)
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        t0 = th0[e]
        t1 = th1[e]
        th = 0.5 * (t0 + t1)
        phi_new[e] = phi[e] + h * th
        rest = l0[e]
        l1 = len1[e]
        G0 = entropy(len0[e], t0, rest, P, pe)
        Gh = entropy(lenh[e], th, rest, P, pe)
        G1 = entropy(l1, t1, rest, P, pe)
        eta1 = (-G0 + 4.0 * Gh + 3.0 * G1) / 6.0
        eta_new[e] = eta1
        th_end = temperature(l1, eta1, rest, P, pe)
        c1 = h / 6.0 * tension(l1, t1, rest, P, pe)
        # fs holds (h/6) T⁰ n⁰ and (h/4) T^½ n^½ from the last residual
        fs[0, e] = fs[0, e] + 8.0 / 3.0 * fs[3, e] + c1 * dir1[0, e]
        fs[1, e] = fs[1, e] + 8.0 / 3.0 * fs[4, e] + c1 * dir1[1, e]
        fs[2, e] = fs[2, e] + 8.0 / 3.0 * fs[5, e] + c1 * dir1[2, e]
        code[e] = (OK if _admissible(th_end) else NO_TEMPERATURE) if abs(eta1) < math.inf else NOT_FINITE
    return _first_flagged(code, lo, n, m)


def _ho4_compiled_residual(step, topo, spring, node, work, extra, u, warm, res):
    return ho4_residual(step, topo, spring, node, work, u, warm, res, extra[0], extra[1])


def _ho4_compiled_jacobian(topo, spring, node, work, places, extra, h, data):
    ho4_jacobian(topo, spring, node, work, places, h, data)


def _ho4_compiled_finish(step, topo, spring, node, work, extra, u, phi, new):
    return ho4_finish(step, topo, spring, node, work, u, phi, new)


def _ho4_compiled_linearize(spring, work, extra, h):
    ho4_linearize(spring, work, h)


def _ho4_compiled_local(step, topo, spring, node, work, extra, u, res, warm, threshold):
    return ho4_local_jacobi(step, topo, spring, node, work, u, res, warm, threshold, extra[2])


register_scheme("ho4", build, keeps_start=True, extrapolates=True)
