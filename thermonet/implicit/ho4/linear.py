"""HO4's Newton matrix (docs/theory.md §2.2) at the last residual's point: its values in the assembled CSR
matrix, its per-spring coefficients and the matrix-free sweep built on them (see
:mod:`.gtr_alpha` for the sweep's idea), and the Jacobi step on a few nodes' rows (local steps).
Numba templates, compiled by :func:`thermonet.implicit.ho4.kernels.build`.

Spring e's block (rows R1, R2; columns d^½, d¹), with signs s_c s_g (s_a = +1, s_b = −1):
  ∂R1/∂x^σ = h/6 F_lθ(l⁰, θ⁰) dθ⁰/dl^σ n⁰ n^σᵀ
  ∂R2/∂x^½ = h/4 [(F_ll + F_lθ dθ^½/dl^½) n^½ n^½ᵀ + T/l (I − n^½ n^½ᵀ)] at (l^½, θ^½)
  ∂R2/∂x¹  = h/4 F_lθ(l^½, θ^½) dθ^½/dl¹ n^½ n¹ᵀ;
the nodal inertia block D = m/h [[8/3, −1/3], [−2, 1]] ⊗ I, D⁻¹ = h/m ½ [[1, 1/3], [2, 8/3]] ⊗ I.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..core.schemes import BLOCK, OPTIONS, UNIFORM, scatter_spring_block
from ...kernels.specialize import specialize

# Bound per model by specialize(); listed so the templates read as ordinary code.
tension = d2F_dl2 = d2F_dl_dtheta = ho4_temperature_derivatives = None

_SWEEPS: dict = {}


def sweep_kernel(parallel: bool):
    """The matrix-free sweep (model-independent: compiled once per threading)."""
    if parallel not in _SWEEPS:
        _SWEEPS[parallel] = specialize(_ho4_sweep, "par" if parallel else "ser", {}, parallel=parallel, **OPTIONS)
    return _SWEEPS[parallel]


def _ho4_linearize(spring, work, h):
    """Per-spring coefficients of the Jacobian at the last residual's point (matrix-free use),
    ``work.jc`` (5, m): spring e's block (rows R1, R2; columns d^½, d¹) is
      [[a₁ n⁰ n^½ᵀ, a₂ n⁰ n¹ᵀ], [(k − t) n^½ n^½ᵀ + t I, c n^½ n¹ᵀ]],   jc[:, e] = (a₁, a₂, k − t, t, c)
    with the terms of :func:`_ho4_jacobian`."""
    l0, P = spring
    start, lenh, dirh, len1, dir1, th0, th1, dth, gs, jc = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    m = len0.shape[0]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        for i in range(min(BLOCK, m - lo)):
            e = np.uint64(lo + i)
            pe = np.uint64(0) if UNIFORM else np.uint64(e)
            t0 = th0[e]
            t1 = th1[e]
            th = 0.5 * (t0 + t1)
            lh = lenh[e]
            rest = l0[e]
            d0h, d01, d1h, d11 = ho4_temperature_derivatives(dth, e, len0[e], lh, len1[e], rest, P, pe, t0, t1)
            c0 = h / 6.0 * d2F_dl_dtheta(len0[e], t0, rest, P, pe)
            flt = d2F_dl_dtheta(lh, th, rest, P, pe)
            axial = h / 4.0 * (d2F_dl2(lh, th, rest, P, pe) + flt * 0.5 * (d0h + d1h))
            lateral = h / 4.0 * tension(lh, th, rest, P, pe) / lh
            jc[0, e] = c0 * d0h
            jc[1, e] = c0 * d01
            jc[2, e] = axial - lateral
            jc[3, e] = lateral
            jc[4, e] = h / 4.0 * flt * 0.5 * (d01 + d11)


def _ho4_jacobian(topo, spring, node, work, places, h, data):
    """Values of ∂R/∂u at the last residual's point into the CSR value array ``data``
    (nnz,), at the places of ``places`` (BlockPlaces).

    Node block (rows R1, R2; columns d^½, d¹): m/h [[8/3, −1/3], [−2, 1]] ⊗ I. Spring block,
    added with sign s_c s_g (s_a = +1, s_b = −1):
      ∂R1/∂x^σ = h/6 F_lθ(l⁰, θ⁰) dθ⁰/dl^σ n⁰ n^σᵀ
      ∂R2/∂x^½ = h/4 [(F_ll + F_lθ dθ^½/dl^½) n^½ n^½ᵀ + T/l (I − n^½ n^½ᵀ)] at (l^½, θ^½)
      ∂R2/∂x¹  = h/4 F_lθ(l^½, θ^½) dθ^½/dl¹ n^½ n¹ᵀ."""
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    l0, P = spring
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    start, lenh, dirh, len1, dir1, th0, th1, dth, gs, jc = work
    len0, dir0, keep, fs, ws, sweep, nodal, guess, code = start
    node_base, node_stride, spring_base, spring_stride, B = places
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
    for e in range(edges.shape[0]):
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        t0 = th0[e]
        th = 0.5 * (t0 + th1[e])
        lh = lenh[e]
        d0h, d01, d1h, d11 = ho4_temperature_derivatives(dth, e, len0[e], lh, len1[e], l0[e], P, pe, t0, th1[e])
        c0 = h / 6.0 * d2F_dl_dtheta(len0[e], t0, l0[e], P, pe)
        flt = d2F_dl_dtheta(lh, th, l0[e], P, pe)
        dthh_h = 0.5 * (d0h + d1h)
        dthh_1 = 0.5 * (d01 + d11)
        axial = h / 4.0 * (d2F_dl2(lh, th, l0[e], P, pe) + flt * dthh_h)
        lateral = h / 4.0 * tension(lh, th, l0[e], P, pe) / lh
        c21 = h / 4.0 * flt * dthh_1
        for i in range(3):
            for j in range(3):
                B[i, j] = c0 * d0h * dir0[i, e] * dirh[j, e]
                B[i, 3 + j] = c0 * d01 * dir0[i, e] * dir1[j, e]
                nn = dirh[i, e] * dirh[j, e]
                B[3 + i, j] = (axial - lateral) * nn + (lateral if i == j else 0.0)
                B[3 + i, 3 + j] = c21 * dirh[i, e] * dir1[j, e]
        scatter_spring_block(data, places, e, B, 6)


def _ho4_sweep(topo, node, work, h, du, R, r, update, first):
    """r = R − J du (du, R, r: (6 n_free,)); with ``update``, then du += D⁻¹ r (and r is not
    written). Returns max |r|. ``first``: du is taken as zero (not read; the spring loop is skipped).

    Spring e's block applied to the difference (v^½, v¹) = du_a − du_b, into w[e, :] (6,):
    rows R1: n⁰ (a₁ n^½·v^½ + a₂ n¹·v¹); rows R2: n^½ ((k − t) n^½·v^½ + c n¹·v¹) + t v^½."""
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    start, lenh, dirh, len1, dir1, th0, th1, dth, gs, jc = work
    len0, dir0, keep, fs, ws, w, nodal, guess, code = start
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


@njit(cache=True, boundscheck=False)
def ho4_jacobi_rows(u, R, blocks, block_mass, h):
    """HO4's Jacobi step on the free nodes ``blocks``: u −= D⁻¹ R there, D⁻¹ = (h/m) ½ [[1, 1/3],
    [2, 8/3]] on (R^½, R¹) per node (as HO4Stepper.apply_inverse_inertia); returns max |change|."""
    big = 0.0
    for q in range(blocks.shape[0]):
        k = blocks[q]
        c = 0.5 * h / block_mass[k]
        for i in range(3):
            rh = R[6 * k + i]
            r1 = R[6 * k + 3 + i]
            dh = c * (rh + r1 / 3.0)
            d1 = c * (2.0 * rh + 8.0 / 3.0 * r1)
            u[6 * k + i] -= dh
            u[6 * k + 3 + i] -= d1
            big = max(big, max(abs(dh), abs(d1)))
    return big
