"""Loads resolved against a net: the kernels' record (:class:`LoadArrays`, internal numbering)
and what the diagnostics need (:class:`LoadSet`).

A node may belong to at most one driven group and at most one force load; a driven group may not
contain anchored nodes (an anchor is a driven node with u = 0 already).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..errors import InputError
from ..explicit.schedule import STAGE
from ..timefunctions import pack
from .spec import AXES, Drive, Force


class LoadArrays(NamedTuple):
    """The loads as the explicit kernels read them (internal numbering).

    kind, params, ptr, times, values: the packed time functions (:func:`thermonet.timefunctions.pack`);
    component: (L, 3) int64 the function of each load's axis (−1: none); is_drive: (L,) bool;
    value, rate: (L, 3) scratch, the loads' u or f and their rates at the stage's time;
    free: (L, 3) 1.0 on the axes a drive leaves free (and on every axis of a force);
    node_force, node_drive: (n,) int64 the force load and the drive of each node (−1: none);
    node_weight: (n,) the node's share of its force load (1, or m_a / Σ m with a total force);
    member_ptr: (L+1,) int64 CSR offsets into member (K,) int64 nodes, member_ref (K, 3) the
    drive's reference positions X − u(0), member_weight (K,);
    work: (L,) the work accumulators (a state's ``extra["load_work"]``); reaction: (L, 3) scratch;
    clock: (2,) the time origin and the steps from it at the call's start; kick_time,
    drift_time: (R,) per row of the stage table, the fraction of h at its kick and after its drift.
    """

    kind: np.ndarray
    params: np.ndarray
    ptr: np.ndarray
    times: np.ndarray
    values: np.ndarray
    component: np.ndarray
    is_drive: np.ndarray
    value: np.ndarray
    rate: np.ndarray
    free: np.ndarray
    node_force: np.ndarray
    node_drive: np.ndarray
    node_weight: np.ndarray
    member_ptr: np.ndarray
    member: np.ndarray
    member_ref: np.ndarray
    member_weight: np.ndarray
    work: np.ndarray
    reaction: np.ndarray
    clock: np.ndarray
    kick_time: np.ndarray
    drift_time: np.ndarray


@dataclass(eq=False)
class LoadSet:
    """The loads of a simulation. names: (L,); loads: the Drive/Force objects; nodes: per load
    its user node indices; components: per load its 3 TimeFunctions (None: not set); free:
    (L, 3); u0: (L, 3) the drives' u(0); fully_driven: (n,) bool, user numbering (nodes whose
    every axis is driven: the kernels treat them like anchors); positions (n, 3), masses (n,):
    the net's, user numbering."""

    names: list
    loads: list
    nodes: list
    components: list
    free: np.ndarray
    u0: np.ndarray
    fully_driven: np.ndarray
    positions: np.ndarray
    masses: np.ndarray

    def __len__(self) -> int:
        return len(self.names)

    @property
    def drives(self) -> list[int]:
        return [i for i, load in enumerate(self.loads) if load.kind == "drive"]

    def value(self, i: int, t: float) -> np.ndarray:
        """(3,) load i's u(t) − u(0) (drives) or f(t) (forces), 0 where not set."""
        out = np.array([0.0 if c is None else c(t) for c in self.components[i]])
        return out - self.u0[i]

    def describe(self, i: int) -> str:
        """Load i in words (``thermonet info``)."""
        load = self.loads[i]
        comps = ", ".join(f"{a}: {c.describe()}" for a, c in zip(AXES, self.components[i]) if c is not None)
        if load.kind == "drive":
            rest = "" if all(c is not None for c in self.components[i]) else \
                f"; other axes {'free' if load.free else 'held'}"
            return f"drive on {len(self.nodes[i])} nodes; u = {{{comps}}}{rest}"
        spread = "total, spread by mass" if load.total else "per node"
        return f"force ({spread}) on {len(self.nodes[i])} nodes; f = {{{comps}}}"


def resolve(loads, net) -> LoadSet | None:
    """Check ``loads`` (a sequence of Drive/Force, or a mapping name -> load) against ``net``;
    None when there are none. Errors name the load (``loads.<name>``) and the key."""
    if loads is None:
        return None
    items = list(loads.items()) if isinstance(loads, dict) else [(getattr(l, "name", "") or f"load{i}", l)
                                                                 for i, l in enumerate(loads)]
    if not items:
        return None
    names, objs, nodes, comps, free, u0 = [], [], [], [], [], []
    n = net.n_nodes
    force_of = np.full(n, -1)
    drive_of = np.full(n, -1)
    for i, (name, load) in enumerate(items):
        where = f"loads.{name}"
        if not isinstance(load, (Drive, Force)):
            raise InputError(f"{where}: expected a thermonet.loads.Drive or Force, got {type(load).__name__}")
        idx = _group_nodes(load.group, net, f"{where}.group")
        c, fr = load.components(where)
        if all(x is None for x in c):
            raise InputError(f"{where}: no axis is set")
        owner = drive_of if load.kind == "drive" else force_of
        clash = idx[owner[idx] >= 0]
        if clash.size:
            other = names[owner[clash[0]]]
            raise InputError(f"{where}.group: node {int(clash[0])} is also in loads.{other}; a node may be in at most "
                             f"one {load.kind} load")
        if load.kind == "drive":
            anchored = idx[net.anchored[idx]]
            if anchored.size:
                raise InputError(f"{where}.group: node {int(anchored[0])} is anchored; a driven group may not "
                                 f"contain anchors (remove it from effects.anchors or from the group)")
        owner[idx] = i
        names.append(name)
        objs.append(load)
        nodes.append(idx)
        comps.append(c)
        free.append(fr)
        u0.append([0.0 if (x is None or load.kind != "drive") else x(0.0) for x in c])
    if len(set(names)) != len(names):
        raise InputError(f"loads: names must be unique, got {names}")
    free = np.array(free)
    fully = np.zeros(n, dtype=bool)
    for i, load in enumerate(objs):
        if load.kind == "drive" and not free[i].any():
            fully[nodes[i]] = True
    return LoadSet(names, objs, nodes, comps, free, np.array(u0), fully, net.positions, net.masses)


def _group_nodes(group, net, where: str) -> np.ndarray:
    """User node indices of a group name or an index list (checked, sorted, unique)."""
    return np.unique(net.nodes(group, where))


def kernel_arrays(load_set: LoadSet, layout, table) -> LoadArrays:
    """The :class:`LoadArrays` of ``load_set`` in the internal numbering of ``layout``, for the
    rows of the stage table ``table``."""
    functions, component = [], np.full((len(load_set), 3), -1, dtype=np.int64)
    for i, comps in enumerate(load_set.components):
        for a, c in enumerate(comps):
            if c is not None:
                component[i, a] = len(functions)
                functions.append(c)
    packed = pack(functions)
    n = len(load_set.masses)
    rank = layout.node_rank
    node_force = np.full(n, -1, dtype=np.int64)
    node_drive = np.full(n, -1, dtype=np.int64)
    node_weight = np.zeros(n)
    ptr = np.zeros(len(load_set) + 1, dtype=np.int64)
    members, refs, weights = [], [], []
    for i, (load, idx) in enumerate(zip(load_set.loads, load_set.nodes)):
        internal = rank[idx]
        order = np.argsort(internal)  # members in internal order: a fixed summation order
        internal, idx = internal[order], idx[order]
        m = load_set.masses[idx]
        w = m / m.sum() if (load.kind == "force" and load.total) else np.ones(len(idx))
        if load.kind == "drive":
            node_drive[internal] = i
        else:
            node_force[internal] = i
            node_weight[internal] = w
        ref = load_set.positions[idx] - np.where(load_set.free[i] > 0, 0.0, load_set.u0[i])[None, :]
        members.append(internal)
        refs.append(ref)
        weights.append(w)
        ptr[i + 1] = ptr[i] + len(idx)
    kick_time, drift_time = row_times(table)
    L = len(load_set)
    return LoadArrays(*packed, component, np.array([l.kind == "drive" for l in load_set.loads]),
                      np.zeros((L, 3)), np.zeros((L, 3)), np.ascontiguousarray(load_set.free),
                      node_force, node_drive, node_weight, ptr,
                      np.ascontiguousarray(np.concatenate(members)), np.ascontiguousarray(np.concatenate(refs)),
                      np.ascontiguousarray(np.concatenate(weights)), np.zeros(L), np.zeros((L, 3)), np.zeros(2),
                      kick_time, drift_time)


def row_times(table) -> tuple[np.ndarray, np.ndarray]:
    """(kick_time, drift_time) (R,): per row of a stage table the fraction of h at which its
    kick acts and after its drift (the step's end exactly 1, so that the closing kick of one
    call and the first of the next see the same time, bit for bit)."""
    R = len(table.code)
    kick, after = np.zeros(R), np.zeros(R)
    tau = 0.0
    stage = table.code == STAGE  # other rows (sub-flows, heat flow) keep their time in ``drift``
    last = max((r for r in range(R) if stage[r] and table.drift[r] != 0.0), default=-1)
    for r in range(R):
        kick[r] = tau
        if stage[r]:
            tau = 1.0 if r == last else tau + float(table.drift[r])
        after[r] = tau
    return kick, after
