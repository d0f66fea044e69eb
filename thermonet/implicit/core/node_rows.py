"""The free nodes' rows in the node passes of the schemes with a block of 3 unknowns per node
(GTR-α, EM2; :mod:`thermonet.implicit.core.schemes` for the conventions): the residual's rows and the matrix-
free sweep's, for a block of NODE_BLOCK nodes, a spring's correction difference, and the inertia
blocks of the assembled Jacobian.
The row functions are inlined into a scheme's loop over node blocks (``for b in
prange(node_blocks(n))``), which keeps its reduction of the returned maxima; the arithmetic is the
schemes' own, in the same order.
HO4's nodes carry 6 rows with their own inertia blocks (:mod:`thermonet.implicit.ho4.kernels`, :mod:`thermonet.implicit.ho4.linear`).
Also the 2-norm of a residual for EM2's line search (:func:`norm2`).
"""

from __future__ import annotations

import math

from numba import njit


#: nodes per call of the row functions: a kernel's node loop runs over blocks of nodes, so that
#: the arrays a row function takes are counted (Numba's runtime, kept in parallel kernels) once
#: per block and not once per node
NODE_BLOCK = 256


@njit(cache=True, inline="always")
def node_blocks(n):
    """The number of NODE_BLOCK blocks of n nodes."""
    return (n + NODE_BLOCK - 1) // NODE_BLOCK


@njit(cache=True, inline="always", error_model="numpy", boundscheck=False)
def residual_rows3(step, topo, node, fs, u, gc, R, Rabs, block):
    """Rows of the free nodes a of node block ``block`` (block k = free_index[a]; none where
    anchored) into R, Rabs:

        R_i = (m/h) u_i − p_i − gc m g_i + Σ_e ∓fs[i, e]   (− at a spring's first end)

    and Rabs_i the sum of the magnitudes of those terms; fs (≥ 3, m) the springs' impulses of
    the residual, gc the gravity's coefficient (GTR-α: α h; EM2: h/2). Returns (max |R_i|,
    max Rabs_i) over the block's rows ((0, 0) without free nodes); Rabs may be empty (then
    only its maximum is returned: the compiled Newton path). (R, Rabs are taken apart
    from the residual's record by the caller, outside its parallel loop: arrays unpacked from a
    tuple within a prange body were written to a copy.)"""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    rmax = 0.0
    smax = 0.0
    magnitudes = Rabs.shape[0] > 0
    for a in range(block * NODE_BLOCK, min((block + 1) * NODE_BLOCK, free_index.shape[0])):
        k = free_index[a]
        if k < 0:
            continue
        w = masses[a] / h
        # the rows and their magnitudes in registers, written once (the same sums in the same
        # order as accumulating in R, Rabs)
        inertia = w * u[3 * k + 0]
        g = gc * masses[a] * gravity[0] if with_gravity else 0.0
        r0 = inertia - p[a, 0] - g
        s0 = abs(inertia) + abs(p[a, 0]) + abs(g)
        inertia = w * u[3 * k + 1]
        g = gc * masses[a] * gravity[1] if with_gravity else 0.0
        r1 = inertia - p[a, 1] - g
        s1 = abs(inertia) + abs(p[a, 1]) + abs(g)
        inertia = w * u[3 * k + 2]
        g = gc * masses[a] * gravity[2] if with_gravity else 0.0
        r2 = inertia - p[a, 2] - g
        s2 = abs(inertia) + abs(p[a, 2]) + abs(g)
        for j in range(inc_ptr[a], inc_ptr[a + 1]):
            e = inc_spring[j]
            sg = -inc_sign[j]
            v0 = fs[0, e]
            v1 = fs[1, e]
            v2 = fs[2, e]
            r0 += sg * v0
            s0 += abs(v0)
            r1 += sg * v1
            s1 += abs(v1)
            r2 += sg * v2
            s2 += abs(v2)
        R[3 * k + 0] = r0
        R[3 * k + 1] = r1
        R[3 * k + 2] = r2
        if magnitudes:
            Rabs[3 * k + 0] = s0
            Rabs[3 * k + 1] = s1
            Rabs[3 * k + 2] = s2
        rmax = max(rmax, max(max(abs(r0), abs(r1)), abs(r2)))
        smax = max(smax, max(max(s0, s1), s2))
    return rmax, smax


@njit(cache=True, inline="always", error_model="numpy", boundscheck=False)
def sweep_rows3(topo, node, h, w, du, R, r, block, update, first):
    """A matrix-free sweep's rows of the free nodes a of node block ``block`` (none where
    anchored): r = R − (m/h) du_a − Σ_e ∓w[e, :3] (w (m, ≥ 3): each spring's block applied to
    du_a − du_b, ± at its first end); with ``update`` then du_a += (h/m) r (and r is not
    written); ``first``: du is taken as zero (not read; w neither). Returns max |r| over the
    block's rows (0 without free nodes)."""
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    rmax = 0.0
    for a in range(block * NODE_BLOCK, min((block + 1) * NODE_BLOCK, free_index.shape[0])):
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
        if update:
            du[3 * k] = d0 + r0 / wm
            du[3 * k + 1] = d1 + r1 / wm
            du[3 * k + 2] = d2 + r2 / wm
        rmax = max(rmax, max(max(abs(r0), abs(r1)), abs(r2)))
    return rmax


@njit(cache=True, inline="always")
def spring_difference3(du, ka, kb):
    """du_a − du_b of a spring's ends (blocks ka, kb of 3; −1: anchored, no unknowns)."""
    v0 = 0.0
    v1 = 0.0
    v2 = 0.0
    if ka >= 0:
        v0 += du[3 * ka]
        v1 += du[3 * ka + 1]
        v2 += du[3 * ka + 2]
    if kb >= 0:
        v0 -= du[3 * kb]
        v1 -= du[3 * kb + 1]
        v2 -= du[3 * kb + 2]
    return v0, v1, v2


@njit(cache=True, inline="always")
def inertia_blocks3(free_index, masses, h, node_base, node_stride, data):
    """data (nnz,) ← 0, then m_c/h on the diagonal of each free node's block (block k =
    free_index[a], its CSR places node_base[k] + i node_stride[k] + i): the Jacobian's inertia
    part, before the schemes scatter their spring blocks."""
    data[:] = 0.0
    for a in range(free_index.shape[0]):
        k = free_index[a]
        if k < 0:
            continue
        w = masses[a] / h
        for i in range(3):
            data[node_base[k] + i * node_stride[k] + i] += w


@njit(cache=True, inline="always")
def norm2(v):
    """|v|₂ of v (k,) in a loop (np.dot's threaded BLAS took 7.7 ms at 5e4 entries on 2 busy cores)."""
    s = 0.0
    for x in v:
        s += x * x
    return math.sqrt(s)
