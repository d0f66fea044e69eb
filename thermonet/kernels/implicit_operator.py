"""Matrix-free products with the implicit integrators' Newton matrices, and the block-Jacobi
(inertia) sweep built on them.

The Newton matrix of GTR-α and HO4 is ``J = D + Σ_e (spring e's block)``, where ``D`` is the
nodal inertia block (``m/h I`` for GTR-α; ``m/h [[8/3, −1/3], [−2, 1]] ⊗ I`` for HO4) and spring
e = (a, b) adds ``s_c s_g B_e`` to block (c, g), s_a = +1, s_b = −1. So
``(J v)_c = D_c v_c + s_c Σ_e B_e (v_a − v_b)``: one pass over the springs (``B_e`` from a few
per-spring coefficients and the unit vectors the residual stored) and one gather per node. This
costs a fraction of a residual evaluation and never forms the matrix.

A sweep computes the linear residual ``r = R − J du`` and then ``du += D⁻¹ r`` (r is written out
only by a sweep that does not update du: a product for GMRES): Richardson's
iteration preconditioned by the inertia, which dominates J for steps below the explicit
stability limit (the contraction per sweep is about h² times the largest stiffness over mass;
measured ≈ 0.02–0.05 on the benchmark lattices at h = 0.01). Both loops are parallel when
compiled with parallel=True; each node sums its springs in a fixed order (thread-independent).

Shapes: du, R, r (B n_free,); w (m, B) scratch, spring-major (the node gather reads a spring's B
values from one cache line); jc per-spring coefficients ((m,)
GTR-α, (5, m) HO4, see :mod:`.implicit`); dir* (3, m); ends (m, 2) the unknown blocks of the
springs' ends (free_index of edges, −1 where anchored); free_index (n,); inc_ptr (n+1,),
inc_spring (2m,) uint32, inc_sign (2m,) the node→spring incidence; masses (n,). Per-spring arrays
are component-major like the residual's; indices are read as unsigned.
"""

from __future__ import annotations

import numpy as np
from numba import prange

from .specialize import specialize

_OPTIONS = dict(cache=True, error_model="numpy", boundscheck=False)
_CACHE: dict = {}


def operator_kernels(scheme: str, parallel: bool):
    """The sweep kernel of ``scheme`` ("gtr" or "ho4"), multi-threaded when ``parallel``."""
    key = (scheme, bool(parallel))
    if key not in _CACHE:
        template = {"gtr": _gtr_sweep, "ho4": _ho4_sweep}[scheme]
        _CACHE[key] = specialize(template, "par" if parallel else "ser", {}, parallel=parallel, **_OPTIONS)
    return _CACHE[key]


def _gtr_sweep(du, R, r, w, jc, dir0, dir1, ends, free_index, inc_ptr, inc_spring, inc_sign, masses, h, update, first):
    """r = R − J du; with ``update``, then du += D⁻¹ r (and r is not written). Returns max |r|.
    ``first``: du is taken as zero (not read; the spring loop is skipped).

    Spring e's block is jc[e] n⁰ n¹ᵀ: w[e, :3] = n⁰ jc[e] n¹·(du_a − du_b)."""
    m = ends.shape[0]
    for e in prange(0 if first else m):
        eu = np.uint64(e)
        ka = ends[eu, 0]
        kb = ends[eu, 1]
        s = 0.0
        for i in range(3):
            d = 0.0
            if ka >= 0:
                d += du[3 * ka + i]
            if kb >= 0:
                d -= du[3 * kb + i]
            s += dir1[i, eu] * d
        c = jc[eu] * s
        w[eu, 0] = c * dir0[0, eu]
        w[eu, 1] = c * dir0[1, eu]
        w[eu, 2] = c * dir0[2, eu]
    rmax = 0.0
    for a in prange(free_index.shape[0]):
        k = free_index[a]
        if k < 0:
            continue
        wm = masses[a] / h
        # the node's rows in registers (r written once; the same sums in the same order)
        d0 = 0.0 if first else du[3 * k]
        d1 = 0.0 if first else du[3 * k + 1]
        d2 = 0.0 if first else du[3 * k + 2]
        r0 = R[3 * k] - (0.0 if first else wm * d0)
        r1 = R[3 * k + 1] - (0.0 if first else wm * d1)
        r2 = R[3 * k + 2] - (0.0 if first else wm * d2)
        if not first:
            for j in range(inc_ptr[a], inc_ptr[a + 1]):
                e = inc_spring[j]
                sg = -inc_sign[j]
                r0 += sg * w[e, 0]
                r1 += sg * w[e, 1]
                r2 += sg * w[e, 2]
        if not update:  # a sweep that updates du keeps r in registers (no caller reads it then)
            r[3 * k] = r0
            r[3 * k + 1] = r1
            r[3 * k + 2] = r2
        rmax = max(rmax, abs(r0))
        rmax = max(rmax, abs(r1))
        rmax = max(rmax, abs(r2))
        if update:
            du[3 * k] = d0 + r0 / wm
            du[3 * k + 1] = d1 + r1 / wm
            du[3 * k + 2] = d2 + r2 / wm
    return rmax


def _ho4_sweep(du, R, r, w, jc, dir0, dirh, dir1, ends, free_index, inc_ptr, inc_spring, inc_sign, masses, h, update, first):
    """r = R − J du; with ``update``, then du += D⁻¹ r (and r is not written). Returns max |r|.
    ``first``: du is taken as zero (not read; the spring loop is skipped).

    Spring e's block applied to the difference (v^½, v¹) = du_a − du_b, into w[e, :] (6,):
    rows R1: n⁰ (a₁ n^½·v^½ + a₂ n¹·v¹); rows R2: n^½ ((k − t) n^½·v^½ + c n¹·v¹) + t v^½."""
    m = ends.shape[0]
    for e in prange(0 if first else m):
        eu = np.uint64(e)
        ka = ends[eu, 0]
        kb = ends[eu, 1]
        vh0 = 0.0
        vh1 = 0.0
        vh2 = 0.0
        v10 = 0.0
        v11 = 0.0
        v12 = 0.0
        if ka >= 0:
            vh0 += du[6 * ka]
            vh1 += du[6 * ka + 1]
            vh2 += du[6 * ka + 2]
            v10 += du[6 * ka + 3]
            v11 += du[6 * ka + 4]
            v12 += du[6 * ka + 5]
        if kb >= 0:
            vh0 -= du[6 * kb]
            vh1 -= du[6 * kb + 1]
            vh2 -= du[6 * kb + 2]
            v10 -= du[6 * kb + 3]
            v11 -= du[6 * kb + 4]
            v12 -= du[6 * kb + 5]
        ph = dirh[0, eu] * vh0 + dirh[1, eu] * vh1 + dirh[2, eu] * vh2
        p1 = dir1[0, eu] * v10 + dir1[1, eu] * v11 + dir1[2, eu] * v12
        c1 = jc[0, eu] * ph + jc[1, eu] * p1
        c2 = jc[2, eu] * ph + jc[4, eu] * p1
        t = jc[3, eu]
        w[eu, 0] = c1 * dir0[0, eu]
        w[eu, 1] = c1 * dir0[1, eu]
        w[eu, 2] = c1 * dir0[2, eu]
        w[eu, 3] = c2 * dirh[0, eu] + t * vh0
        w[eu, 4] = c2 * dirh[1, eu] + t * vh1
        w[eu, 5] = c2 * dirh[2, eu] + t * vh2
    rmax = 0.0
    for a in prange(free_index.shape[0]):
        k = free_index[a]
        if k < 0:
            continue
        wm = masses[a] / h
        q = 0.5 / wm
        # the node's six rows in registers (r written once; the same sums in the same order)
        dh0 = 0.0 if first else du[6 * k]
        dh1 = 0.0 if first else du[6 * k + 1]
        dh2 = 0.0 if first else du[6 * k + 2]
        d10 = 0.0 if first else du[6 * k + 3]
        d11 = 0.0 if first else du[6 * k + 4]
        d12 = 0.0 if first else du[6 * k + 5]
        r0 = R[6 * k] - wm * (8.0 * dh0 - d10) / 3.0
        r1 = R[6 * k + 1] - wm * (8.0 * dh1 - d11) / 3.0
        r2 = R[6 * k + 2] - wm * (8.0 * dh2 - d12) / 3.0
        r3 = R[6 * k + 3] - wm * (d10 - 2.0 * dh0)
        r4 = R[6 * k + 4] - wm * (d11 - 2.0 * dh1)
        r5 = R[6 * k + 5] - wm * (d12 - 2.0 * dh2)
        if not first:
            for j in range(inc_ptr[a], inc_ptr[a + 1]):
                e = inc_spring[j]
                sg = -inc_sign[j]
                r0 += sg * w[e, 0]
                r1 += sg * w[e, 1]
                r2 += sg * w[e, 2]
                r3 += sg * w[e, 3]
                r4 += sg * w[e, 4]
                r5 += sg * w[e, 5]
        if not update:  # a sweep that updates du keeps r in registers (no caller reads it then)
            r[6 * k] = r0
            r[6 * k + 1] = r1
            r[6 * k + 2] = r2
            r[6 * k + 3] = r3
            r[6 * k + 4] = r4
            r[6 * k + 5] = r5
        rmax = max(rmax, max(abs(r0), abs(r3)))
        rmax = max(rmax, max(abs(r1), abs(r4)))
        rmax = max(rmax, max(abs(r2), abs(r5)))
        if update:
            # D⁻¹ = h/m · ½ [[1, 1/3], [2, 8/3]]
            du[6 * k] = dh0 + q * (r0 + r3 / 3.0)
            du[6 * k + 1] = dh1 + q * (r1 + r4 / 3.0)
            du[6 * k + 2] = dh2 + q * (r2 + r5 / 3.0)
            du[6 * k + 3] = d10 + q * (2.0 * r0 + 8.0 / 3.0 * r3)
            du[6 * k + 4] = d11 + q * (2.0 * r1 + 8.0 / 3.0 * r4)
            du[6 * k + 5] = d12 + q * (2.0 * r2 + 8.0 / 3.0 * r5)
    return rmax
