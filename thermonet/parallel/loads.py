"""Loads (drives and forces) on a distributed net: each process drives and pushes the nodes of
its share, and the loads' reactions and work are summed over their nodes in the whole net's
order, so the work columns are those of one process, bit for bit.

The CPU kernel sums a load's power over its member nodes in member order
(:func:`thermonet.loads.elements.load_power`). Here each process computes the terms of the
members it owns (a drive: the spring force on the node, gathered as the node pass gathers it; a
force: the node's position), the processes exchange them (one ``Allgatherv`` of a few rows per
force evaluation), and every process adds them up in member order with the same operations, so
every process holds the same work accumulators and reactions.
"""

from __future__ import annotations

import numpy as np

from ..kernels.specialize import function_fingerprint, specialize

# bound per kernel variant (the loads' functions of thermonet.loads.elements, the sub-flows')
cpu_evaluate_loads = cpu_drive_positions = gather_force = None

_OPTIONS = dict(cache=True, error_model="numpy", boundscheck=False, _nrt=False)
_CACHE: dict = {}


def _evaluate(loads, t):
    """Every load's value and rate at t."""
    cpu_evaluate_loads(loads, t)


def _drive(x, loads):
    """The driven nodes of the share (owned and ghost) at the drives' current values."""
    cpu_drive_positions(x, loads)


def _member_terms(x, s, topology, nodes, members, is_drive, out):
    """out[j] (k, 3): the spring force on local node members[j] (a drive's member, as the node
    pass gathers it, gravity left out) or its position (a force's member)."""
    for j in range(members.shape[0]):
        a = members[j]
        if is_drive[j]:
            f0, f1, f2 = gather_force(a, x, s, topology.inc_ptr, topology.inc_spring, topology.inc_other,
                                      nodes.masses, nodes.gravity, False)
        else:
            f0, f1, f2 = x[a, 0], x[a, 1], x[a, 2]
        out[j, 0] = f0
        out[j, 1] = f1
        out[j, 2] = f2


def load_functions(namespace: dict, variant: str):
    """(evaluate, drive, member_terms) compiled around a loads variant's functions."""
    if variant not in _CACHE:
        names = ("cpu_evaluate_loads", "cpu_drive_positions", "gather_force")
        ns = {k: namespace[k] for k in names}
        tag = f"{variant}_{function_fingerprint(*(ns[k].py_func for k in names))}"
        _CACHE[variant] = tuple(specialize(f, tag, ns, **_OPTIONS) for f in (_evaluate, _drive, _member_terms))
    return _CACHE[variant]


class ShareLoads:
    """The loads of one process's share.

    loads: the whole net's :class:`~thermonet.loads.stepping.StepperLoads` (its clock is the
    run's; its per-member arrays are read, its per-node ones only while this is built); share,
    dec: :mod:`thermonet.parallel.domain`; base: the whole net's Nodes record (masses, anchored,
    gravity of the power's gravity terms: kept at the members); functions: :func:`load_functions`.
    """

    def __init__(self, loads, share, dec, base, functions):
        self.loads = loads
        self.evaluate, self.drive, self._terms = functions
        A = loads.arrays
        n_loads = len(A.work)
        local_of = np.full(len(dec.owner), -1, dtype=np.int64)
        local_of[share.nodes] = np.arange(len(share.nodes))
        load_of = np.repeat(np.arange(n_loads), np.diff(A.member_ptr))  # the load of each member k
        inside = local_of[A.member] >= 0
        ptr = np.concatenate([[0], np.cumsum(np.bincount(load_of[inside], minlength=n_loads))]).astype(np.int64)
        self._local = A._replace(node_force=np.ascontiguousarray(A.node_force[share.nodes]),
                                 node_drive=np.ascontiguousarray(A.node_drive[share.nodes]),
                                 node_weight=np.ascontiguousarray(A.node_weight[share.nodes]),
                                 member_ptr=ptr, member=np.ascontiguousarray(local_of[A.member[inside]]),
                                 member_ref=np.ascontiguousarray(A.member_ref[inside]),
                                 member_weight=np.ascontiguousarray(A.member_weight[inside]))
        owner = dec.owner[A.member]
        mine = np.flatnonzero(owner == share.rank)
        self._members = np.ascontiguousarray(local_of[A.member[mine]])
        self._is_drive = np.ascontiguousarray(A.is_drive[load_of[mine]])
        self._mine = np.empty((len(mine), 3))
        # the gathered rows come rank by rank: where each goes in member order
        self._order = np.concatenate([np.flatnonzero(owner == q) for q in range(dec.size)])
        self._counts = np.array([3 * np.count_nonzero(owner == q) for q in range(dec.size)], dtype=np.int64)
        self._offsets = np.concatenate([[0], np.cumsum(self._counts)[:-1]])
        self._gathered = np.empty(3 * len(A.member))
        self.terms = np.empty((len(A.member), 3))
        # what the drives' power reads of the member nodes (the whole Nodes record is not kept)
        self._member_mass = np.ascontiguousarray(base.masses[A.member])
        self._member_anchored = np.ascontiguousarray(base.anchored[A.member])
        self._gravity, self._with_gravity = base.gravity, bool(base.with_gravity)

    def arrays_for(self, state, h: float):
        """The share's LoadArrays for a call from ``state`` (the run's clock and work)."""
        whole = self.loads.arrays_for(state, h)
        self._local = self._local._replace(work=whole.work)
        return self._local

    def add_work(self, comm, x, s, topology, nodes, step1: float, step2: float) -> None:
        """Reactions and work of a kick of step1 + step2 at x (T/l per spring in s, local
        numbering; topology, nodes: the share's records): the CPU kernel's ``load_power`` and
        ``add_work`` over the whole net's members, in member order, on every process."""
        from mpi4py import MPI

        self._terms(x, s, topology, nodes, self._members, self._is_drive, self._mine)
        comm.Allgatherv(self._mine.ravel(), [self._gathered, self._counts, self._offsets, MPI.DOUBLE])
        self.terms[self._order] = self._gathered.reshape(-1, 3)
        A, terms = self._local, self.terms
        mass, anchored, gravity, with_gravity = self._member_mass, self._member_anchored, self._gravity, self._with_gravity
        whole_weight = self.loads.arrays.member_weight
        for i in range(len(A.work)):
            r0 = r1 = r2 = g0 = g1 = g2 = 0.0
            drive = A.is_drive[i]
            for k in range(self.loads.arrays.member_ptr[i], self.loads.arrays.member_ptr[i + 1]):
                if drive:
                    r0 += terms[k, 0]
                    r1 += terms[k, 1]
                    r2 += terms[k, 2]
                    if with_gravity and not anchored[k]:
                        g0 += mass[k] * gravity[0]
                        g1 += mass[k] * gravity[1]
                        g2 += mass[k] * gravity[2]
                else:
                    w = whole_weight[k]
                    r0 += w * terms[k, 0]
                    r1 += w * terms[k, 1]
                    r2 += w * terms[k, 2]
            rate = A.rate
            if drive:
                A.reaction[i, 0], A.reaction[i, 1], A.reaction[i, 2] = r0, r1, r2
                power = -((r0 + g0) * rate[i, 0] + (r1 + g1) * rate[i, 1] + (r2 + g2) * rate[i, 2])
            else:
                power = -(rate[i, 0] * r0 + rate[i, 1] * r1 + rate[i, 2] * r2)
            if step1 != 0.0:
                A.work[i] += step1 * power
            A.work[i] += step2 * power
