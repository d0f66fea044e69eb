"""A stage of the explicit step as one pass over the nodes (the CUDA kernels' default path).

Each node's thread computes T/l of every spring incident to it from the spring's two ends,
gathers its force in the CPU's incidence order, kicks p and drifts into the second position
buffer; the spring's other per-spring work (Φ's update and the admissibility test) is done by
one of its two ends, the *owner* (the node that is the spring's first end, marked by the top bit
of its incidence's ``inc_other`` entry: :func:`owned_incidences`). So a stage is one launch (or
one grid-wide barrier in the fused kernel) instead of two, and moves no T/l array: per
spring-step it reads the incidences, η and the rest length instead of the edges, writing and
reading back T/l (about 86 bytes per spring-step on a 6-neighbour lattice against 118).

Both ends compute the same T/l bit for bit: the same operations on the same inputs (the other
end's difference vector is the exact negative, its squares equal), so the forces, p and x are
those of the spring pass followed by the node pass, and Φ is updated once. Runs with loads keep
the two passes (their reactions read T/l).
"""

from __future__ import annotations

import math

import numpy as np
from numba import cuda

from . import FLAG_SET

# Bound per model by thermonet.cuda.kernels.cuda_kernels
spring_force = outside_admissible = advance_thermal_displacement = kick_momentum = drift_position = None
load_row = store_row = _raise_flag = None
THERMAL = True
UNIFORM = False

#: the owner bit of an ``inc_other`` entry (node indices stay below it)
OWNER = np.uint32(1 << 31)
NODE_MASK = np.uint32((1 << 31) - 1)


def owned_incidences(edges: np.ndarray, inc_ptr: np.ndarray, inc_spring: np.ndarray, inc_other: np.ndarray):
    """``inc_other`` (2m,) uint32 with the top bit set on the incidence of each spring's first end
    (edges[e, 0]), which updates the spring's Φ and tests it. Needs fewer than 2³¹ nodes."""
    n = inc_ptr.shape[0] - 1
    if n >= int(OWNER):
        raise ValueError(f"{n} nodes: the CUDA kernels index nodes below 2**31")
    node_of = np.repeat(np.arange(n, dtype=np.int64), np.diff(inc_ptr))
    owner = edges[inc_spring.astype(np.int64), 0].astype(np.int64) == node_of
    return (inc_other.astype(np.uint32) | np.where(owner, OWNER, np.uint32(0))).astype(np.uint32)


def _stage_update(a, x, x_new, state, springs, topology, nodes, steps, run):
    """Node a over one stage: for each incident spring (CPU incidence order) T/l from both ends'
    positions, the force gathered as :func:`thermonet.kernels.subflows.gather_force` does, on the
    owned springs Φ += steps[0] θ, += steps[1] θ and the admissibility test; then
    p += steps[0] f, += steps[1] f (not on anchors) and x_new = x + steps[2] p / m. steps =
    (kick1 h, kick2 h, drift h, with_force). Returns whether an owned spring left the admissible
    states. x, x_new: (n, 3); state: StateArrays (p, Φ, η used; its x is not); topology.inc_other
    with owner bits (:func:`owned_incidences`)."""
    xa0, xa1, xa2 = load_row(x, a)
    anchored = nodes.anchored[a]
    bad = False
    if steps[3]:
        eta = state.eta
        phi = state.phi
        f0 = 0.0
        f1 = 0.0
        f2 = 0.0
        for j in range(topology.inc_ptr[a], topology.inc_ptr[a + 1]):
            other = topology.inc_other[j]
            owner = (other & OWNER) != 0
            if anchored and not owner:
                continue
            e = topology.inc_spring[j]
            b = other & NODE_MASK
            d0 = x[b, 0] - xa0
            d1 = x[b, 1] - xa1
            d2 = x[b, 2] - xa2
            l = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            c = 0 if UNIFORM else e
            rest = springs.rest[e]
            theta, force = spring_force(l, eta[e] if THERMAL else 0.0, rest, springs.P, c)
            if owner:
                if THERMAL and run.track_phi:
                    advance_thermal_displacement(phi, e, theta, steps[0], steps[1])
                bad = bad | outside_admissible(l, rest, force, theta, run.stretch_min, run.stretch_max)
            f0 += force * d0
            f1 += force * d1
            f2 += force * d2
        if anchored:
            store_row(x_new, a, xa0, xa1, xa2)
            return bad
        if nodes.with_gravity:
            f0 += nodes.masses[a] * nodes.gravity[0]
            f1 += nodes.masses[a] * nodes.gravity[1]
            f2 += nodes.masses[a] * nodes.gravity[2]
        p0, p1, p2 = kick_momentum(state.p[a, 0], state.p[a, 1], state.p[a, 2], f0, f1, f2, steps[0], steps[1])
        store_row(state.p, a, p0, p1, p2)
    elif anchored:
        store_row(x_new, a, xa0, xa1, xa2)
        return bad
    else:
        p0, p1, p2 = load_row(state.p, a)
    drift_position(x_new, a, xa0, xa1, xa2, p0, p1, p2, steps[2] * nodes.inv_mass[a])
    return bad


def _stage_kernel(x, x_new, state, springs, topology, nodes, steps, run, flag, where):
    """Thread a: :func:`_stage_update` of node a, unless the call already stopped (``flag``);
    where: (step, row, stages) written into ``flag`` if an owned spring of a is outside the
    admissible states."""
    a = cuda.grid(1)
    if a < x.shape[0] and flag[FLAG_SET] == 0:
        if _stage_update(a, x, x_new, state, springs, topology, nodes, steps, run):
            _raise_flag(flag, where)
