"""A local Jacobi step of the implicit integrators, :func:`_local_jacobi` (both Newton paths:
``ImplicitStepper.local_jacobi`` and the compiled driver), and its scheme-independent pieces: the
springs at the free nodes whose residual rows are large and the free nodes at those springs'
ends (whose residual rows the step changes), and the one pass over the residual's per-node
maxima that gives its norms (the step's update of the listed nodes is the scheme's:
``ho4.linear.ho4_jacobi_rows``). Serial: the
sets are small (a few per cent of the net at most, else the caller takes a global step), and
their order does not change any result (each spring and each node row is computed on its own;
a node sums its springs in incidence order)."""

from __future__ import annotations

from numba import njit


@njit(cache=True, boundscheck=False)
def neighbourhood(blocks, node_of_block, inc_ptr, inc_spring, edges, free_index, spring_mark, node_mark,
                  springs_out, nodes_out):
    """The springs at the nodes of ``blocks`` into springs_out and the free nodes at their ends
    into nodes_out, each once; returns (springs, nodes). spring_mark (m,), node_mark (n,) uint8
    scratch, zero on entry and on return."""
    ns = 0
    nn = 0
    for q in range(blocks.shape[0]):
        a = node_of_block[blocks[q]]
        for j in range(inc_ptr[a], inc_ptr[a + 1]):
            e = inc_spring[j]
            if spring_mark[e]:
                continue
            spring_mark[e] = 1
            springs_out[ns] = e
            ns += 1
            for end in range(2):
                b = edges[e, end]
                if free_index[b] >= 0 and not node_mark[b]:
                    node_mark[b] = 1
                    nodes_out[nn] = b
                    nn += 1
    for q in range(ns):
        spring_mark[springs_out[q]] = 0
    for q in range(nn):
        node_mark[nodes_out[q]] = 0
    return ns, nn


@njit(cache=True, boundscheck=False)
def scan(peak, threshold, out):
    """(max |R|, max Rabs, count) in one pass over the per-node maxima of a residual, ``peak``
    (2, n_free): row 0 the largest |R| of each free node's rows, row 1 the largest Rabs (the
    residual kernel writes them: 16 bytes per node to read instead of 2 × B × 8): the norms of the
    residual, and the free nodes with peak[0] > threshold, in increasing order, into ``out``;
    count is their number, or len(out) + 1 where there are more."""
    rmax = 0.0
    smax = 0.0
    count = 0
    for k in range(peak.shape[1]):
        big = peak[0, k]
        rmax = max(rmax, big)
        smax = max(smax, peak[1, k])
        if big > threshold:
            if count < out.shape[0]:
                out[count] = k
            count += 1
    return rmax, smax, min(count, out.shape[0] + 1)


# Bound per scheme by specialize() (ho4.build); listed so the template reads as ordinary code.
scheme_jacobi_rows = scheme_residual_subset = None


def _local_jacobi(step, topo, spring, node, work, u, res, warm, threshold, local):
    """A local Jacobi step (ImplicitStepper.local_jacobi; the compiled driver's scheme_local):
    u −= D⁻¹ R on the free nodes whose row maximum (``res`` peak) exceeds ``threshold``, then the residual recomputed at
    their springs and at those springs' ends (the scheme's SUBSET residual kernel; the lists in
    the order found, which changes no result). local: (out (≥ 1,) int64, spring_mark (m,),
    node_mark (n,) uint8 zeros, springs (m,), nodes (n,) int64 scratch, node_of_block (n_free,),
    block_mass (n_free,)). Returns (done, status, spring, max |R|, max Rabs, max |change of
    u|); not done (nothing changed) where more nodes than ``out`` holds are above the
    threshold."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    out, spring_mark, node_mark, springs, nodes, node_of_block, block_mass = local
    R = res[0]
    peak = res[2]
    rmax, smax, count = scan(peak, threshold, out)
    if count > out.shape[0]:
        return False, 0, -1, rmax, smax, 0.0
    blocks = out[:count]
    change = scheme_jacobi_rows(u, R, blocks, block_mass, h)
    ns, nn = neighbourhood(blocks, node_of_block, inc_ptr, inc_spring, edges, free_index, spring_mark, node_mark,
                           springs, nodes)
    status, bad, _, _ = scheme_residual_subset(step, topo, spring, node, work, u, warm, res, springs[:ns],
                                               nodes[:nn])
    rmax, smax, _ = scan(peak, threshold, out)
    return True, status, bad, rmax, smax, change
