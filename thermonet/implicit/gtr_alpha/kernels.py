"""GTR-α's kernels (docs/theory.md §2.1, paper (45)–(48)): residual, Jacobian values (assembled, and as
per-spring coefficients for the matrix-free sweep), the matrix-free sweep and the finish, as Numba
templates compiled per model by :func:`build` (registered as scheme "gtr"). Conventions (records,
blocking, status codes): :mod:`thermonet.implicit.core.schemes`.

Unknown d = x¹ − x⁰ per free node (block of 3); θ̄ condensed per spring:

    R_c = m_c d_c / h − α h f_c(x⁰, θ̄) − p_c                                         (48a)
    α Γ(l⁰, θ̄) + (1 − α) Γ(l¹, θ̄) = η                                     per spring (48c)

For a model whose entropy is affine in ln θ, Γ(l, θ) = a(l) + C ln θ (LOG_AFFINE; the start
kernel then keeps A = θ(l⁰, η), T(l⁰, A), F_lθ(l⁰) and C per spring, KEEP_START), (48c) is
solved in closed form: Γ(l⁰, θ̄) = η + C ln(θ̄/A), so C ln(θ̄/A) = (1 − α)(η − Γ(l¹, A)), and
dθ̄/dl¹ = (1 − α) F_lθ(l¹) θ̄/C (F_lθ does not depend on θ); T(l⁰, θ̄) = T(l⁰, A) + F_lθ(l⁰)
(θ̄ − A). A temperature that is not admissible goes to the scalar solve as before.

The work record is :class:`GTRWork`: per spring len1 (m,), dir1 (3, m) at x¹, θ̄ ``theta`` and
dθ̄/dl¹ ``dtheta`` (m,), the matrix-free coefficient ``jc`` (m,), and the start kernel's
:class:`~thermonet.implicit.core.records.StartWork` (``start``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import prange

from ...kernels.fastmath import exp as exp_
from ..core.schemes import (BLOCK, INLINE, KEEP_START, LOCAL_ITERATIONS, MAX_LOG_STEP, NO_TEMPERATURE, NOT_FINITE, OK,
                            OPTIONS, THETA_STOP, UNIFORM, COLLAPSED, _admissible, _first_flagged, _log_step,
                            _usable, register_scheme, scatter_spring_block)
from ..core.records import StartWork
from ..core.node_rows import inertia_blocks3, node_blocks, residual_rows3, spring_difference3, sweep_rows3
from ...kernels.specialize import specialize, specialize_by_content

# Bound per model by specialize(); listed so the templates read as ordinary code.
entropy = temperature = tension = d2F_dl_dtheta = d2F_dtheta2 = None
gtr_thermal = gtr_thermal_vector = gtr_correct = finish_nodes = None
gtr_residual = gtr_jacobian = gtr_finish = gtr_linearize = None
gtr_residual_springs = gtr_finish_springs = None


class GTRWork(NamedTuple):
    """GTR-α's per-spring arrays (see the module doc); shapes for m springs."""

    start: StartWork
    len1: np.ndarray
    dir1: np.ndarray
    theta: np.ndarray
    dtheta: np.ndarray
    jc: np.ndarray

    @classmethod
    def allocate(cls, start: StartWork) -> "GTRWork":
        m = start.len0.shape[0]
        return cls(start, np.empty(m), np.empty((3, m)), np.empty(m), np.empty(m), np.empty(m))


def build(ns: dict, tag: str, ptag: str, parallel: bool) -> dict:
    """GTR-α's kernels for the model namespace ``ns`` (see core.schemes.register_scheme)."""
    ns["gtr_correct"] = specialize(_gtr_correct, tag, ns, **INLINE)
    ns["gtr_thermal"] = specialize(_gtr_thermal, tag, ns, **OPTIONS)
    ns["gtr_thermal_vector"] = specialize(_gtr_thermal_vector, tag, ns, **INLINE)
    # (the spring blocks: serial, shared by the serial and the threaded kernels)
    ns["gtr_residual_springs"] = specialize_by_content(_gtr_residual_springs, tag, ns, **OPTIONS)
    ns["gtr_finish_springs"] = specialize_by_content(_gtr_finish_springs, tag, ns, **OPTIONS)
    residual = specialize(_gtr_residual, ptag, ns, parallel=parallel, **OPTIONS)
    jacobian = specialize(_gtr_jacobian, tag, ns, **OPTIONS)
    finish = specialize(_gtr_finish, ptag, ns, parallel=parallel, **OPTIONS)
    linearize = specialize(_gtr_linearize, ptag, ns, parallel=parallel, **OPTIONS)
    calls = dict(ns, gtr_residual=residual, gtr_jacobian=jacobian, gtr_finish=finish, gtr_linearize=linearize)
    return dict(
        residual=residual,
        linearize=linearize,
        jacobian=jacobian,
        finish=finish,
        # the compiled Newton path's signatures (implicit/core/compiled_newton.py), extra = (α,)
        compiled_residual=specialize(_gtr_compiled_residual, ptag, calls, **INLINE),
        compiled_jacobian=specialize(_gtr_compiled_jacobian, ptag, calls, **INLINE),
        compiled_finish=specialize(_gtr_compiled_finish, ptag, calls, **INLINE),
        compiled_linearize=specialize(_gtr_compiled_linearize, ptag, calls, **INLINE),
        sweep=sweep_kernel(parallel),
        thermal=ns["gtr_thermal"],
        # the two per-spring solves, callable alone (tests)
        thermal_vector=specialize(_gtr_thermal_vector, f"{tag}_alone", ns, **OPTIONS),
    )


_SWEEPS: dict = {}


def sweep_kernel(parallel: bool):
    """The matrix-free sweep (model-independent: compiled once per threading)."""
    if parallel not in _SWEEPS:
        _SWEEPS[parallel] = specialize(_gtr_sweep, "par" if parallel else "ser", {}, parallel=parallel, **OPTIONS)
    return _SWEEPS[parallel]


def _gtr_thermal(la, lb, eta, l0, P, e, alpha, guess):
    """θ̄ with α Γ(la, θ̄) + (1 − α) Γ(lb, θ̄) = η, its derivative dθ̄/dlb, and success (1, else
    0: an integer, which Numba's alias analysis of a parallel loop treats as immutable).

    Newton in ln θ from ``guess`` when usable, else from θ(α la + (1 − α) lb, η) (the answer
    itself when α is 0 or 1). The scalar solve: iterates to convergence."""
    beta = 1.0 - alpha
    th = guess if _usable(guess) else temperature(alpha * la + beta * lb, eta, l0, P, e)
    if not _usable(th):
        return th, 0.0, 0
    done = False
    for _ in range(LOCAL_ITERATIONS):
        G = alpha * entropy(la, th, l0, P, e) + beta * entropy(lb, th, l0, P, e) - eta
        Gt = -(alpha * d2F_dtheta2(la, th, l0, P, e) + beta * d2F_dtheta2(lb, th, l0, P, e))
        step = _log_step(G / (Gt * th))
        th = th * math.exp(-step)
        if abs(step) <= THETA_STOP:
            done = True
            break
    if not (done and _usable(th)):
        return th, 0.0, 0
    Gt = -(alpha * d2F_dtheta2(la, th, l0, P, e) + beta * d2F_dtheta2(lb, th, l0, P, e))
    return th, beta * d2F_dl_dtheta(lb, th, l0, P, e) / Gt, 1


def _gtr_correct(la, lb, eta, l0, P, e, alpha, th):
    """One Newton correction of :func:`_gtr_thermal` (branch-free): (new θ̄, the ln θ step)."""
    beta = 1.0 - alpha
    G = alpha * entropy(la, th, l0, P, e) + beta * entropy(lb, th, l0, P, e) - eta
    Gt = -(alpha * d2F_dtheta2(la, th, l0, P, e) + beta * d2F_dtheta2(lb, th, l0, P, e))
    s = G / (Gt * th)
    step = min(max(s, -MAX_LOG_STEP), MAX_LOG_STEP)
    return th * exp_(-step), s


def _gtr_thermal_vector(la, lb, eta, l0, P, e, alpha, guess):
    """The vectorized loop's solve of :func:`_gtr_thermal`: VECTOR_CORRECTIONS corrections from
    the same start; success when the last one is below THETA_STOP. Same returns."""
    beta = 1.0 - alpha
    th = guess if _admissible(guess) else temperature(alpha * la + beta * lb, eta, l0, P, e)
    th, s = gtr_correct(la, lb, eta, l0, P, e, alpha, th)
    th, s = gtr_correct(la, lb, eta, l0, P, e, alpha, th)
    ok = 1 if (abs(s) <= THETA_STOP) & _admissible(th) else 0
    Gt = -(alpha * d2F_dtheta2(la, th, l0, P, e) + beta * d2F_dtheta2(lb, th, l0, P, e))
    return th, beta * d2F_dl_dtheta(lb, th, l0, P, e) / Gt, ok


def _gtr_residual(step, topo, spring, node, work, alpha, u, warm, res):
    """R, Rabs (3 n_free,) of ``res`` at unknowns u (3 n_free,); fills ``work``'s len1 (m,), dir1
    (3, m), θ̄ and dθ̄/dl¹ (m,) for the Jacobian and the finish. With ``warm``, the θ̄ of the
    previous call (at nearby u), moved along dθ̄/dl¹, seeds each thermal solve. The start
    record's fs (≥ 3, m), guess, code (m,): scratch. Returns (status, spring, max |R|, max Rabs)."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    start, len1, dir1, theta, dtheta, jc = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    R, Rabs, peak = res
    m = edges.shape[0]
    bad = m
    # (the work record rebuilt in the loop: Numba cannot hand a record that holds a record to
    # a parallel loop's body)
    work_arrays = work[1:]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = np.int64(blk) * BLOCK
        bad = min(bad, gtr_residual_springs(step, topo, spring, (start,) + work_arrays, alpha, u, warm, lo,
                                            min(BLOCK, m - lo)))
    if bad < m:
        return code[bad], bad, math.inf, math.inf
    rmax = 0.0
    smax = 0.0
    gc = alpha * h
    for blk in prange(node_blocks(x0.shape[0])):
        big, scale = residual_rows3(step, topo, node, fs, u, gc, R, Rabs, blk)
        rmax = max(rmax, big)
        smax = max(smax, scale)
    return 0, -1, rmax, smax


def _gtr_residual_springs(step, topo, spring, work, alpha, u, warm, lo, n):
    """Springs lo … lo + n − 1 of :func:`_gtr_residual` (n ≤ BLOCK), a serial function called
    once per block: see thermonet.explicit.cpu._spring_pass. Returns the block's first flagged
    spring (m if none)."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    start, len1, dir1, theta, dtheta, jc = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    m = edges.shape[0]
    for i in range(n):  # gather: the spring vector at x¹
        e = np.uint64(lo + i)
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
        fs[0, e] = dx
        fs[1, e] = dy
        fs[2, e] = dz
    for i in range(n):  # geometry (vectorized)
        e = np.uint64(lo + i)
        dx = fs[0, e]
        dy = fs[1, e]
        dz = fs[2, e]
        l1 = math.sqrt(dx * dx + dy * dy + dz * dz)
        # read unconditionally: a conditional read of len1 before its store made LLVM's
        # runtime alias check always fail (the loop ran its scalar version)
        g = theta[e] + dtheta[e] * (l1 - len1[e])
        g = g if warm else -1.0
        guess[e] = g
        len1[e] = l1
        i1 = 1.0 / l1
        dir1[0, e] = dx * i1
        dir1[1, e] = dy * i1
        dir1[2, e] = dz * i1
    for i in range(n):  # thermal solve and impulses (vectorized; apart from the geometry,
        # whose stores in the same loop kept LLVM from vectorizing it)
        e = np.uint64(lo + i)
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        l1 = len1[e]
        g = guess[e]
        la = len0[e]
        if KEEP_START:  # closed form (see the module doc), T affine in θ
            A = keep[0, e]
            C = keep[3, e]
            th = A * exp_((1.0 - alpha) * (eta[e] - entropy(l1, A, l0[e], P, pe)) / C)
            dth = (1.0 - alpha) * d2F_dl_dtheta(l1, th, l0[e], P, pe) * th / C
            ok = 1 if _admissible(th) else 0
            T = keep[1, e] + keep[2, e] * (th - A)
        else:
            th, dth, ok = gtr_thermal_vector(la, l1, eta[e], l0[e], P, pe, alpha, g)
            T = tension(la, th, l0[e], P, pe)
        theta[e] = th
        dtheta[e] = dth
        c = alpha * h * T
        fs[0, e] = c * dir0[0, e]
        fs[1, e] = c * dir0[1, e]
        fs[2, e] = c * dir0[2, e]
        code[e] = OK if ((ok != 0) & (l1 > 0.0) & (l1 < math.inf)) else NO_TEMPERATURE
    for i in range(n):  # the scalar solve where the vectorized one did not converge
        e = lo + i
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        if code[e] == OK:
            continue
        l1 = len1[e]
        if not (l1 > 0.0 and l1 < math.inf):
            code[e] = COLLAPSED
            continue
        la = len0[e]
        th, dth, ok = gtr_thermal(la, l1, eta[e], l0[e], P, pe, alpha, guess[e])
        if not ok:
            continue
        code[e] = OK
        theta[e] = th
        dtheta[e] = dth
        c = alpha * h * tension(la, th, l0[e], P, pe)
        for j in range(3):
            fs[j, e] = c * dir0[j, e]
    return _first_flagged(code, lo, n, m)


def _gtr_linearize(spring, work, alpha, h):
    """Per-spring coefficient of the Jacobian at the last residual's point (matrix-free use):
    spring e's block is jc[e] n⁰ n¹ᵀ, jc[e] = α h F_lθ(l⁰, θ̄) dθ̄/dl¹ (m,) (``work.jc``)."""
    l0, P = spring
    start, len1, dir1, theta, dtheta, jc = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    m = len0.shape[0]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        for i in range(min(BLOCK, m - lo)):
            e = np.uint64(lo + i)
            pe = np.uint64(0) if UNIFORM else np.uint64(e)
            jc[e] = alpha * h * d2F_dl_dtheta(len0[e], theta[e], l0[e], P, pe) * dtheta[e]


def _gtr_jacobian(topo, spring, node, work, places, alpha, h, data):
    """Values of ∂R/∂u at the last residual's point into the CSR value array ``data``
    (nnz,), at the places of ``places`` (BlockPlaces).

    ∂R_c/∂d_g = δ_cg m_c/h I + α h s_c s_g F_lθ(l⁰, θ̄) (dθ̄/dl¹) n⁰ n¹ᵀ, s_a = +1, s_b = −1."""
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    start, len1, dir1, theta, dtheta, jc = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    node_base, node_stride, spring_base, spring_stride, B = places
    inertia_blocks3(free_index, masses, h, node_base, node_stride, data)
    for e in range(edges.shape[0]):
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        c = alpha * h * d2F_dl_dtheta(len0[e], theta[e], l0[e], P, pe) * dtheta[e]
        if c == 0.0:
            continue
        for i in range(3):
            for j in range(3):
                B[i, j] = c * dir0[i, e] * dir1[j, e]
        scatter_spring_block(data, places, e, B, 3)


def _gtr_finish(step, topo, spring, node, work, alpha, u, phi, new):
    """The next state from converged unknowns u into ``new`` (StateArrays; phi (m,) the step's
    start): x¹ = x⁰ + d; Φ¹ = Φ⁰ + h θ̄; η¹ = α Γ(l⁰, θ̄) + (1 − α) Γ(l¹, θ̄) measured (48d); and
    p¹ = p⁰ + h [α f(x⁰, θ̄) + (1 − α) f(x¹, θ̄)], which is (48b) given (48a) and, forces being
    central pairs, conserves linear momentum to round-off whatever the solver residual.
    fs must hold the last residual's per-spring terms (that residual was evaluated at u).
    Returns (status, spring)."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    start, len1, dir1, theta, dtheta, jc = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    x_new, p_new, phi_new, eta_new = new
    m = edges.shape[0]
    bad = m
    # (the work record rebuilt in the loop: Numba cannot hand a record that holds a record to
    # a parallel loop's body)
    work_arrays = work[1:]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = np.int64(blk) * BLOCK
        bad = min(bad, gtr_finish_springs(step, topo, spring, (start,) + work_arrays, alpha, phi, new, lo,
                                          min(BLOCK, m - lo)))
    if bad < m:
        return code[bad], bad
    return finish_nodes(step, topo, node, fs, u, 3, 0, new)



def _gtr_finish_springs(step, topo, spring, work, alpha, phi, new, lo, n):
    """Springs lo … lo + n − 1 of :func:`_gtr_finish` (n ≤ BLOCK), a serial function called once
    per block: see thermonet.explicit.cpu._spring_pass. Returns the block's first flagged spring
    (m if none)."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    start, len1, dir1, theta, dtheta, jc = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    x_new, p_new, phi_new, eta_new = new
    m = edges.shape[0]
    for i in range(n):  # vectorized
        e = np.uint64(lo + i)
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        th = theta[e]
        phi_new[e] = phi[e] + h * th
        l1 = len1[e]
        eta1 = alpha * entropy(len0[e], th, l0[e], P, pe) + (1.0 - alpha) * entropy(l1, th, l0[e], P, pe)
        eta_new[e] = eta1
        th1 = temperature(l1, eta1, l0[e], P, pe)
        c1 = (1.0 - alpha) * h * tension(l1, th, l0[e], P, pe)
        fs[0, e] += c1 * dir1[0, e]  # fs holds α h T(l⁰, θ̄) n⁰ from the last residual
        fs[1, e] += c1 * dir1[1, e]
        fs[2, e] += c1 * dir1[2, e]
        code[e] = (OK if _admissible(th1) else NO_TEMPERATURE) if abs(eta1) < math.inf else NOT_FINITE
    return _first_flagged(code, lo, n, m)


def _gtr_sweep(topo, node, work, h, du, R, r, update, first):
    """r = R − J du (du, R, r: (3 n_free,)); with ``update``, then du += D⁻¹ r (and r is not
    written). Returns max |r|. ``first``: du is taken as zero (not read; the spring loop is skipped).

    Spring e's block is jc[e] n⁰ n¹ᵀ: w[e, :3] = n⁰ jc[e] n¹·(du_a − du_b)."""
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    start, len1, dir1, theta, dtheta, jc = work
    len0, dir0, keep, fs, ws, w, nodal, guess, code = start
    m = ends.shape[0]
    for e in prange(0 if first else m):
        eu = np.uint64(e)
        ka = ends[eu, 0]
        kb = ends[eu, 1]
        v0, v1, v2 = spring_difference3(du, ka, kb)
        s = dir1[0, eu] * v0 + dir1[1, eu] * v1 + dir1[2, eu] * v2
        c = jc[eu] * s
        w[eu, 0] = c * dir0[0, eu]
        w[eu, 1] = c * dir0[1, eu]
        w[eu, 2] = c * dir0[2, eu]
    rmax = 0.0
    for blk in prange(node_blocks(free_index.shape[0])):
        rmax = max(rmax, sweep_rows3(topo, node, h, w, du, R, r, blk, update, first))
    return rmax


def _gtr_compiled_residual(step, topo, spring, node, work, extra, u, warm, res):
    return gtr_residual(step, topo, spring, node, work, extra[0], u, warm, res)


def _gtr_compiled_jacobian(topo, spring, node, work, places, extra, h, data):
    gtr_jacobian(topo, spring, node, work, places, extra[0], h, data)


def _gtr_compiled_finish(step, topo, spring, node, work, extra, u, phi, new):
    return gtr_finish(step, topo, spring, node, work, extra[0], u, phi, new)


def _gtr_compiled_linearize(spring, work, extra, h):
    gtr_linearize(spring, work, extra[0], h)


register_scheme("gtr", build, keeps_start=True)
