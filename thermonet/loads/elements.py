"""What loads do to one node or one load, for every target (CPU kernels, CUDA device functions,
Python under the CUDA simulator), as :mod:`thermonet.kernels.subflows` does for kicks and drifts.

Bound per kernel variant like the sub-flows (:func:`thermonet.kernels.specialize.rebind`):
``gather_force`` is the sub-flow's, ``evaluate`` / ``evaluate_rate`` the time functions'
(:mod:`thermonet.timefunctions`). ``loads`` is a :class:`~thermonet.loads.arrays.LoadArrays`.

The loads enter an explicit step as the extended-phase-space splitting of the time-dependent
Hamiltonian: time advances with the drifts, so the driven positions are set to the time after
each drift (:func:`drive_member`); a kick of τ at time t adds τ f(t) to the loaded nodes' momenta
(:func:`node_load`) and τ ∂H/∂t to the work (:func:`load_power`): the work is then the energy of
the clock, and H − H(0) − W is a modified-energy error of the symplectic splitting (bounded,
no drift, of the integrator's order).
"""

from __future__ import annotations

import numpy as np

from ..kernels.specialize import rebind, specialize_by_content
from ..timefunctions import evaluate as evaluate_, evaluate_rate as evaluate_rate_

gather_force = evaluate = evaluate_rate = None


def evaluate_load(i, loads, t):
    """value[i], rate[i] (3,) ← load i's functions and their rates at t (0 where not set)."""
    for ax in range(3):
        f = loads.component[i, ax]
        if f >= 0:
            loads.value[i, ax] = evaluate(loads.kind, loads.params, loads.ptr, loads.times, loads.values, f, t)
            loads.rate[i, ax] = evaluate_rate(loads.kind, loads.params, loads.ptr, loads.times, loads.values, f, t)
        else:
            loads.value[i, ax] = 0.0
            loads.rate[i, ax] = 0.0


def node_load(a, f0, f1, f2, node_force, node_weight, node_drive, value, free):
    """Node a's force with its force load's share added (w_a f(t)) and its driven axes zeroed
    (their momentum stays 0; the drive sets their positions). The arrays are those of a
    :class:`~thermonet.loads.arrays.LoadArrays`, unpacked by the caller once per pass (a record
    handed to a per-node call costs a copy of the record). Returns (f0, f1, f2)."""
    j = node_force[a]
    if j >= 0:
        w = node_weight[a]
        f0 += w * value[j, 0]
        f1 += w * value[j, 1]
        f2 += w * value[j, 2]
    d = node_drive[a]
    if d >= 0:
        f0 *= free[d, 0]
        f1 *= free[d, 1]
        f2 *= free[d, 2]
    return f0, f1, f2


def load_power(i, x, s, topology, nodes, loads):
    """∂H/∂t of load i at positions x (T/l per spring in s) and the stage's rates: for a drive
    −(R + G)·u̇, R the spring forces on its nodes (written to reaction[i]) and G gravity on those
    of its nodes that are free in some axis (their potential is part of H); for a force −ḟ·Σ w x
    (the potential −f·Σ w x is not part of the reported H: see :mod:`thermonet.loads.balance`)."""
    r0 = 0.0
    r1 = 0.0
    r2 = 0.0
    g0 = 0.0
    g1 = 0.0
    g2 = 0.0
    drive = loads.is_drive[i]
    for k in range(loads.member_ptr[i], loads.member_ptr[i + 1]):
        a = loads.member[k]
        if drive:
            f0, f1, f2 = gather_force(a, x, s, topology.inc_ptr, topology.inc_spring, topology.inc_other,
                                      nodes.masses, nodes.gravity, False)
            r0 += f0
            r1 += f1
            r2 += f2
            if nodes.with_gravity and not nodes.anchored[a]:
                g0 += nodes.masses[a] * nodes.gravity[0]
                g1 += nodes.masses[a] * nodes.gravity[1]
                g2 += nodes.masses[a] * nodes.gravity[2]
        else:
            w = loads.member_weight[k]
            r0 += w * x[a, 0]
            r1 += w * x[a, 1]
            r2 += w * x[a, 2]
    if drive:
        loads.reaction[i, 0] = r0
        loads.reaction[i, 1] = r1
        loads.reaction[i, 2] = r2
        return -((r0 + g0) * loads.rate[i, 0] + (r1 + g1) * loads.rate[i, 1] + (r2 + g2) * loads.rate[i, 2])
    return -(loads.rate[i, 0] * r0 + loads.rate[i, 1] * r1 + loads.rate[i, 2] * r2)


def add_work(i, loads, power, step1, step2):
    """work[i] += step1 power, += step2 power: two additions, as the kick they belong to."""
    if step1 != 0.0:
        loads.work[i] += step1 * power
    loads.work[i] += step2 * power


def drive_member(k, i, x, loads):
    """The driven axes of member k (of drive i) at X + u(t) − u(0) (value[i] holds u(t))."""
    a = loads.member[k]
    for ax in range(3):
        if loads.free[i, ax] == 0.0:
            x[a, ax] = loads.member_ref[k, ax] + loads.value[i, ax]


def stage_time(loads, h, step, tau):
    """The time of fraction tau of step ``step`` of a call: origin + ((steps before the call +
    step) + tau) h, the same bits however the run is cut into calls."""
    return loads.clock[0] + ((loads.clock[1] + step) + tau) * h


#: the functions above, in the order a kernel factory binds them (callees first)
SHARED = ("evaluate_load", "node_load", "load_power", "add_work", "drive_member", "stage_time")


def cpu_evaluate_loads(loads, t):
    """Every load's value and rate at t (serial: a handful of loads)."""
    for i in range(loads.component.shape[0]):
        evaluate_load(i, loads, t)


def cpu_load_work(x, s, topology, nodes, loads, step1, step2):
    """Reactions and work of a kick of step1 + step2 at x (serial over each load's nodes, in a
    fixed order: the same bits for any thread count)."""
    for i in range(loads.component.shape[0]):
        add_work(i, loads, load_power(i, x, s, topology, nodes, loads), step1, step2)


def cpu_drive_positions(x, loads):
    """The driven nodes' positions at the loads' current values."""
    for i in range(loads.component.shape[0]):
        if loads.is_drive[i]:
            for k in range(loads.member_ptr[i], loads.member_ptr[i + 1]):
                drive_member(k, i, x, loads)


CPU_PASSES = ("cpu_evaluate_loads", "cpu_load_work", "cpu_drive_positions")


def source_digest() -> str:
    """A short hash of this module's source (part of the kernels' cache names)."""
    import hashlib
    import inspect
    import sys

    return hashlib.sha256(inspect.getsource(sys.modules[__name__]).encode()).hexdigest()[:8]


#: the ``loads`` argument of kernels compiled without loads
NO_LOADS = (np.empty(0),)


def bind_loads(ns: dict, tag: str, compile_) -> str:
    """Bind this module's functions into the kernel namespace ``ns`` (which already holds the
    sub-flows' ``gather_force``), each compiled by ``compile_``; the time functions are the
    compiled ones. Returns the suffix the kernels' cache tag takes."""
    suffix = f"_L{source_digest()}"
    ns["evaluate"] = evaluate_
    ns["evaluate_rate"] = evaluate_rate_
    for name in SHARED:
        ns[name] = compile_(rebind(globals()[name], tag + suffix, ns))
    # the serial passes are called, not inlined at their several call sites in a kernel, and
    # named by what they read (no model, threading or heat flow): one compiled copy serves every
    # variant (inlined, they were most of what loads add to a kernel's compile time)
    for name in CPU_PASSES:
        ns[name] = specialize_by_content(globals()[name], tag + suffix, ns, cache=True, error_model="numpy",
                                         boundscheck=False, _nrt=False)
    return suffix
