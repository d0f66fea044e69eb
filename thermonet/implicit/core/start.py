"""The start kernel of every implicit scheme (:mod:`thermonet.implicit.core.schemes` for the conventions): the
geometry and forces at the step's start x⁰ and the explicit predictor of the step's unknowns, a
Taylor-like series in the acceleration and its time derivatives along the exact (adiabatic) flow;
for a scheme registered with ``extrapolates`` (HO4), with the previous step's stage acceleration
extrapolated in. A Numba template compiled per model, scheme and threading by
:func:`thermonet.implicit.core.schemes.implicit_kernels`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from .status import BLOCK, COLLAPSED, NO_TEMPERATURE, OK, _admissible, _first_flagged

# Bound per model by specialize(); listed so the template reads as ordinary code.
temperature = tension = d2F_dl2 = d2F_dl_dtheta = d2F_dtheta2 = adiabatic_stiffness = start_springs = None
#: compile-time constants bound per model and scheme (core.schemes.implicit_kernels): the
#: acceleration's time derivatives the predictor uses (ImplicitStepper.rate), whether the start
#: keeps per-spring values for the residuals (``keep``), one shared parameter column, and
#: whether the predictor extrapolates from the previous step's stage acceleration (RATE 2 only)
RATE = 0
KEEP_START = False
UNIFORM = False
EXTRAPOLATE = False


def _adiabatic_stiffness(l, eta, l0, P, e):
    """dT/dl at constant entropy η: F_ll − F_lθ²/F_θθ at (l, θ(l, η))."""
    th = temperature(l, eta, l0, P, e)
    flt = d2F_dl_dtheta(l, th, l0, P, e)
    return d2F_dl2(l, th, l0, P, e) - flt * flt / d2F_dtheta2(l, th, l0, P, e)


#: the predictor's ä term is used at a node only where h²/8 |ä| ≤ SNAP_TRUST (|a| + h/2 |ȧ|)
SNAP_TRUST = 0.1
#: relative length step of the forward difference for d²T/dl² along an adiabat (the model gives
#: second derivatives of F only): its error ~ STIFFNESS_STEP, its round-off ~ 1e-16/STIFFNESS_STEP,
#: both far below what a predictor term needs (a central difference costs one more evaluation)
STIFFNESS_STEP = 1e-5


def _start(step, topo, spring, node, work, coef, pred):
    """Lengths ``work.len0`` (m,) and unit vectors ``work.dir0`` (3, m) at x0 (n, 3) (``work``: a
    StartWork record), and the explicit predictor of the step's unknowns into pred (B n_free,):
    per free node and sub-block j (B = 3 × rows
    of coef), pred = coef[j, 0] v + coef[j, 1] a + coef[j, 2] ȧ + coef[j, 3] ä with v = p/m,
    a = f/m (+ g) the acceleration at (x0, θ(l0, η)) and its first (``RATE`` ≥ 1) and second
    (``RATE`` 2) time derivatives along the exact (adiabatic) flow at (x0, p0) (else 0), for a
    Taylor-like predictor. Scratch: fs (6, m), ws (6, m) (``RATE`` 2), nodal (n + 1, 6) (``RATE``
    2), code (m,). h: step.h. With KEEP_START, keep (KEEP_ROWS, m) receives per spring θ(l⁰, η),
    T(l⁰, θ(l⁰, η)), F_lθ(l⁰) and the log-affine coefficient C = −θ F_θθ (HO4's closed-form
    thermal solve reads them at every residual of the step). Returns (status, spring).

    With EXTRAPOLATE (HO4), where ``work.history[0]`` (nodal[n, 0]) is h (the previous step had this h, was
    committed, and pred still holds its converged unknowns; this kernel clears it), the
    series a + (h/2) ȧ + (h²/8) ä for the stage acceleration a^½ gains its next term from the
    previous step's stage acceleration a⁻ = Σ_j coef[j, 5] pred_j (read before pred is written):
    (h³/48) a⃛ ≈ Δ = a − (h/2) ȧ + (h²/8) ä − a⁻, and pred_j += coef[j, 4] Δ. The predictor's
    error falls from O(h³) to O(h⁴) in a^½ (measured: 1.2–6× smaller scaled residual on the
    benchmark lattice at h = 0.01, so one Newton correction suffices more often). Used at a node
    only where its ä term is (SNAP_TRUST) and |Δ| ≤ SNAP_TRUST (|a| + h/2 |ȧ|) (a stale or
    unsteady history falls back to the series).

    Per spring f = T n, T = T(l, θ(l, η)) along the adiabat with T' = dT/dl (adiabatic
    stiffness), l̇ = n·v, ṅ = (v − n l̇)/l (v, α: relative velocity and acceleration of the ends):
    ḟ = T' l̇ n + T ṅ;  f̈ = T'' l̇² n + T' l̈ n + 2 T' l̇ ṅ + T n̈ with l̈ = n·α + (|v|² − l̇²)/l,
    n̈ = (α − n l̈ − 2 ṅ l̇)/l; T'' by a forward difference of T'. ä needs the nodes' a: a second
    spring pass and node pass."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = work
    m = edges.shape[0]
    bad = m
    last = x0.shape[0]  # nodal's last row: the committed step's h (StartWork.history)
    extrapolate = EXTRAPOLATE and nodal[last, 0] == h
    if EXTRAPOLATE:
        nodal[last, 0] = 0.0  # pred is overwritten below
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = np.int64(blk) * BLOCK
        bad = min(bad, start_springs(step, topo, spring, node, work, lo, min(BLOCK, m - lo)))
    if bad < m:
        return code[bad], bad
    J = coef.shape[0]
    for a in prange(x0.shape[0]):
        k = free_index[a]
        if k < 0:
            if RATE > 1:
                for i in range(6):
                    nodal[a, i] = 0.0
            continue
        f0 = 0.0
        f1 = 0.0
        f2 = 0.0
        r0 = 0.0
        r1 = 0.0
        r2 = 0.0
        for j in range(inc_ptr[a], inc_ptr[a + 1]):
            e = inc_spring[j]
            sg = inc_sign[j]
            f0 += sg * fs[0, e]
            f1 += sg * fs[1, e]
            f2 += sg * fs[2, e]
            if RATE > 0:
                r0 += sg * fs[3, e]
                r1 += sg * fs[4, e]
                r2 += sg * fs[5, e]
        w = inv_mass[a]
        for i in range(3):
            f = f0 if i == 0 else (f1 if i == 1 else f2)
            r = r0 if i == 0 else (r1 if i == 1 else r2)
            v = w * p[a, i]
            acc = w * f + (gravity[i] if with_gravity else 0.0)
            jerk = w * r
            if RATE > 1:  # the prediction waits for ä
                nodal[a, i] = acc
                nodal[a, 3 + i] = jerk
                continue
            for s in range(J):
                pred[3 * J * k + 3 * s + i] = coef[s, 0] * v + coef[s, 1] * acc + coef[s, 2] * jerk
    if RATE < 2:
        return 0, -1
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        n = min(BLOCK, m - lo)
        for i in range(n):  # gather: relative acceleration
            e = np.uint64(lo + i)
            a = edges[e, 0]
            b = edges[e, 1]
            fs[0, e] = nodal[b, 0] - nodal[a, 0]
            fs[1, e] = nodal[b, 1] - nodal[a, 1]
            fs[2, e] = nodal[b, 2] - nodal[a, 2]
        for i in range(n):  # f̈ (vectorized)
            e = np.uint64(lo + i)
            l = len0[e]
            nx = dir0[0, e]
            ny = dir0[1, e]
            nz = dir0[2, e]
            vx = ws[0, e]
            vy = ws[1, e]
            vz = ws[2, e]
            ax = fs[0, e]
            ay = fs[1, e]
            az = fs[2, e]
            T = ws[3, e]
            Tl = ws[4, e]
            Tll = ws[5, e]
            ldot = nx * vx + ny * vy + nz * vz
            mx = (vx - nx * ldot) / l  # ṅ
            my = (vy - ny * ldot) / l
            mz = (vz - nz * ldot) / l
            lddot = nx * ax + ny * ay + nz * az + (vx * vx + vy * vy + vz * vz - ldot * ldot) / l
            radial = Tll * ldot * ldot + Tl * lddot - T * lddot / l
            side = 2.0 * (Tl - T / l) * ldot
            q = T / l
            fs[3, e] = radial * nx + side * mx + q * ax
            fs[4, e] = radial * ny + side * my + q * ay
            fs[5, e] = radial * nz + side * mz + q * az
    for a in prange(x0.shape[0]):
        k = free_index[a]
        if k < 0:
            continue
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        for j in range(inc_ptr[a], inc_ptr[a + 1]):
            e = inc_spring[j]
            sg = inc_sign[j]
            s0 += sg * fs[3, e]
            s1 += sg * fs[4, e]
            s2 += sg * fs[5, e]
        w = inv_mass[a]
        # the series a + τ ȧ + τ²/2 ä (τ ≤ h) is trusted with its ä term only where that term
        # is small next to the others (ω h ≲ 1 locally); a step near the stability limit keeps
        # the third-order guess
        lower = 0.0
        top = 0.0
        for i in range(3):
            lower = max(lower, abs(nodal[a, i]) + 0.5 * h * abs(nodal[a, 3 + i]))
            top = max(top, 0.125 * h * h * w * abs(s0 if i == 0 else (s1 if i == 1 else s2)))
        use = top <= SNAP_TRUST * lower
        # the previous step's stage acceleration against the series' value there (EXTRAPOLATE)
        d0 = 0.0
        d1 = 0.0
        d2 = 0.0
        if EXTRAPOLATE and extrapolate and use:
            big = 0.0
            for i in range(3):
                sn = w * (s0 if i == 0 else (s1 if i == 1 else s2))
                before = 0.0
                for s in range(J):
                    before += coef[s, 5] * pred[3 * J * k + 3 * s + i]
                d = nodal[a, i] - 0.5 * h * nodal[a, 3 + i] + 0.125 * h * h * sn - before
                big = max(big, abs(d))
                if i == 0:
                    d0 = d
                elif i == 1:
                    d1 = d
                else:
                    d2 = d
            if not big <= SNAP_TRUST * lower:
                d0 = d1 = d2 = 0.0
        for i in range(3):
            sn = w * (s0 if i == 0 else (s1 if i == 1 else s2)) if use else 0.0
            v = w * p[a, i]
            acc = nodal[a, i]
            jerk = nodal[a, 3 + i]
            d = d0 if i == 0 else (d1 if i == 1 else d2)
            for s in range(J):
                q = coef[s, 0] * v + coef[s, 1] * acc + coef[s, 2] * jerk + coef[s, 3] * sn
                pred[3 * J * k + 3 * s + i] = q + coef[s, 4] * d if EXTRAPOLATE else q
    return 0, -1


def _start_springs(step, topo, spring, node, work, lo, n):
    """Springs lo … lo + n − 1 of :func:`_start`'s first spring pass (n ≤ BLOCK), a serial
    function called once per block: see thermonet.explicit.cpu._spring_pass. Returns the block's
    first flagged spring (m if none)."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = work
    m = edges.shape[0]
    for i in range(n):  # gather: spring vector and relative velocity
        e = np.uint64(lo + i)
        a = edges[e, 0]
        b = edges[e, 1]
        dir0[0, e] = x0[b, 0] - x0[a, 0]
        dir0[1, e] = x0[b, 1] - x0[a, 1]
        dir0[2, e] = x0[b, 2] - x0[a, 2]
        if RATE > 0:
            fs[3, e] = p[b, 0] * inv_mass[b] - p[a, 0] * inv_mass[a]
            fs[4, e] = p[b, 1] * inv_mass[b] - p[a, 1] * inv_mass[a]
            fs[5, e] = p[b, 2] * inv_mass[b] - p[a, 2] * inv_mass[a]
    for i in range(n):  # arithmetic (vectorized)
        e = np.uint64(lo + i)
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        dx = dir0[0, e]
        dy = dir0[1, e]
        dz = dir0[2, e]
        l = math.sqrt(dx * dx + dy * dy + dz * dz)
        il = 1.0 / l
        nx = dx * il
        ny = dy * il
        nz = dz * il
        len0[e] = l
        dir0[0, e] = nx
        dir0[1, e] = ny
        dir0[2, e] = nz
        rest = l0[e]
        th = temperature(l, eta[e], rest, P, pe)
        T = tension(l, th, rest, P, pe)
        fs[0, e] = T * nx
        fs[1, e] = T * ny
        fs[2, e] = T * nz
        if KEEP_START:
            keep[0, e] = th
            keep[1, e] = T
        lok = (l > 0.0) & (l < math.inf)
        code[e] = OK if (lok & _admissible(th)) else (NO_TEMPERATURE if lok else COLLAPSED)
    # what KEEP_START and RATE add, each in a loop of its own: in one loop with the above
    # LLVM vectorized none of it (HO4's start cost 17–21 CO2 steps instead of ≈ 3)
    if KEEP_START:
        for i in range(n):
            e = np.uint64(lo + i)
            pe = np.uint64(0) if UNIFORM else np.uint64(e)
            l = len0[e]
            rest = l0[e]
            th = keep[0, e]
            keep[2, e] = d2F_dl_dtheta(l, th, rest, P, pe)
            keep[3, e] = -th * d2F_dtheta2(l, th, rest, P, pe)
    if RATE > 0:
        for i in range(n):
            e = np.uint64(lo + i)
            pe = np.uint64(0) if UNIFORM else np.uint64(e)
            l = len0[e]
            nx = dir0[0, e]
            ny = dir0[1, e]
            nz = dir0[2, e]
            rest = l0[e]
            if KEEP_START:  # what the loop above kept (the same values)
                th = keep[0, e]
                T = keep[1, e]
                flt = keep[2, e]
            else:
                th = temperature(l, eta[e], rest, P, pe)
                T = tension(l, th, rest, P, pe)
                flt = d2F_dl_dtheta(l, th, rest, P, pe)
            vx = fs[3, e]
            vy = fs[4, e]
            vz = fs[5, e]
            ldot = nx * vx + ny * vy + nz * vz
            Tl = d2F_dl2(l, th, rest, P, pe) - flt * flt / d2F_dtheta2(l, th, rest, P, pe)
            Tdot = Tl * ldot
            q = T / l
            fs[3, e] = Tdot * nx + q * (vx - nx * ldot)
            fs[4, e] = Tdot * ny + q * (vy - ny * ldot)
            fs[5, e] = Tdot * nz + q * (vz - nz * ldot)
            if RATE > 1:
                ws[0, e] = vx
                ws[1, e] = vy
                ws[2, e] = vz
                ws[3, e] = T
                ws[4, e] = Tl
    if RATE > 1:
        for i in range(n):
            e = np.uint64(lo + i)
            pe = np.uint64(0) if UNIFORM else np.uint64(e)
            l = len0[e]
            dl = STIFFNESS_STEP * l
            ws[5, e] = (adiabatic_stiffness(l + dl, eta[e], l0[e], P, pe) - ws[4, e]) / dl
    return _first_flagged(code, lo, n, m)
