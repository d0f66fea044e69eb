"""The CPU passes of heat flow (templates compiled per model by
:func:`thermonet.explicit.cpu.splitting_kernels` and :func:`heat_kernels`).

A conduction sweep (:func:`_conduction_sweep`) runs at a step boundary: the reverse half sweep
that ends a conduction cycle (the star colours backwards, each block's nodes last to first, then
the boundary entries: baths, sources), the forward half sweep that starts the next one (the
boundary entries, then the colours in order), or both back to back; then one entropy update per
spring. A colour's blocks run in parallel (they share no spring); each block and each boundary
spring is computed by one thread in a fixed order, so results do not depend on the thread count.
With factors shared by all springs a thread takes a colour's blocks two at a time (the serial
kernel always, the threaded one where a colour has a pair for every thread or more), node k of one
with node k of the other, their junction sums in one loop (:func:`_star_nodes`: a
node's sum is a chain of dependent additions, two chains overlap); with no bath or source
entries between the half sweeps, the reverse sweep's last colour and the forward sweep's first
run as one phase, each block reverse then forward. Each block's operations, and their order, are those of
:func:`thermonet.heat.exchange.star_block`: the same bits.
The forward sweeps of ``K_f(kh/2) ∘ A(h)^k ∘ K_r(kh/2)`` are the exact reverse of the reverse
ones, which makes the cycle symmetric.
"""

from __future__ import annotations

import math

import numpy as np
import numba
from numba import njit, prange

from ..explicit.codes import FORCE_DEFERRED
from ..kernels.records import KickDrift, Run, Scratch
from ..kernels.specialize import kernel_namespace, model_fingerprint, rebind, specialize
from . import exchange

#: what a conduction sweep does (a bit set): the forward half sweep, the reverse one; SAVE: keep
#: the entropies, production log and temperatures before the sweep (a call ends with it);
#: CONTINUE: start the entropy update from the kept ones (the next call's first sweep), so that
#: it covers both half sweeps, as the one update of a call that runs them back to back
FORWARD = 1
REVERSE = 2
SAVE = 4
CONTINUE = 8
#: leave the entropy update to the caller, who runs it with the next kick's spring pass
#: (:func:`_finish_refresh_pass`: one pass over the springs instead of two)
DEFER_FINISH = 16
#: (:func:`_sweep_colour` only) each block forward, then in reverse: a forward half sweep's last
#: colour and the next reverse half sweep's first, as one phase (sub-sweeps)
FORWARD_THEN_REVERSE = 32

# Bound per kernel variant (see thermonet.explicit.cpu; spring_pass and node_pass for
# conduction_boundary, which only the explicit step uses).
spring_pass = temperature_pass = conduction_sweep = node_pass = None
finish_refresh_pass = refresh_pass = None
cpu_evaluate_loads = cpu_load_work = None
LOADS = False
star_node = star_block = boundary_exchange = finish_spring = wave_exchange = reverse_half = None
spring_temperature = squared_length = None
tension = outside_admissible = advance_thermal_displacement = spring_energy = None
model_strain = tension_at_strain = None
boundary_node_pass = None
UNIFORM = False
#: the serial kernel (a thread takes a colour's blocks two at a time from two blocks on; with
#: threads, from PAIRS_FROM blocks on, a pair per thread of Numba's thread pool: see _sweep_colour)
PAIRED = False
#: (a compile-time constant, part of the kernels' cache names through source_digest: Numba cannot
#: cache a kernel that asks for the thread count as it runs)
PAIRS_FROM = 2 * max(1, numba.config.NUMBA_NUM_THREADS)
#: springs per block of the temperature pass (see thermonet.kernels.blocks.BLOCK)
BLOCK = 512

_OPTIONS = dict(cache=True, error_model="numpy", boundscheck=False, _nrt=False)  # specialize(): no reference counting


def bind_heat_flow(ns: dict, tag: str, compile_) -> None:
    """Bind :mod:`thermonet.heat.exchange`'s functions into the kernel namespace ``ns``,
    each compiled by ``compile_`` (the time functions' ``evaluate`` with it)."""
    _bind_exchange(ns, tag, compile_)
    if ns.get("model_strain") is None or ns.get("tension_at_strain") is None:
        # T from the length itself (the "strain" kept is the length)
        ns["model_strain"] = compile_(_length_as_strain)
        ns["tension_at_strain"] = compile_(rebind(_tension_of_length, tag, ns))


def _bind_exchange(ns: dict, tag: str, compile_) -> None:
    from ..kernels.fastmath import log
    from ..timefunctions import evaluate_py

    ns["evaluate"] = compile_(evaluate_py)
    ns["log"] = log
    for name in exchange.SHARED:
        ns[name] = compile_(rebind(getattr(exchange, name), tag, ns))


def _length_as_strain(l, l0):
    """Stands in for ``Model.strain`` where a model has none."""
    return l


def _tension_of_length(L, l, theta, l0, P, e):
    """Stands in for ``Model.tension_at_strain`` where a model has none: T(l, θ)."""
    return tension(l, theta, l0, P, e)


#: the heat passes compiled in this process, by cache tag (:func:`sweep_tag`, :func:`pass_tag`)
_COMPILED: dict = {}


def sweep_tag(parallel: bool) -> str:
    """The cache tag of the conduction and wave sweeps: they read the temperatures, the heat
    record and the time functions, no model, so one compiled sweep (per threading) serves every
    model and kernel variant (with or without loads, other sub-flows, an implicit stepper's)."""
    from ..kernels.fastmath import log
    from ..kernels.specialize import function_fingerprint
    from ..timefunctions import evaluate_py

    return f"{'par' if parallel else 'ser'}_h{source_digest(parallel)}_e{function_fingerprint(evaluate_py, log)}"


def pass_tag(model, parallel: bool, uniform: bool) -> str:
    """The cache tag of the heat passes that read the model (temperature, refresh, entropy update,
    the springs' sums): the model, threading and parameter layout, and the sources they inline;
    not the loads, sub-flows or rows of the kernel variant that calls them."""
    from ..kernels.fastmath import log
    from ..kernels.specialize import function_fingerprint
    from ..kernels.subflows import source_digest as subflows_digest

    return (f"{model.name}_{model_fingerprint(model)}_{'par' if parallel else 'ser'}{'_uniform' if uniform else ''}"
            f"_s{subflows_digest()}_h{source_digest(parallel)}_e{function_fingerprint(log)}")


def bind_heat_passes(ns: dict, model, parallel: bool, uniform: bool) -> None:
    """Bind the passes below into ``ns`` (which must hold the model, subflows and exchange
    bindings of ``model``, thermal, ``uniform``), each compiled once per process for its
    :func:`pass_tag` or :func:`sweep_tag` (and loaded from Numba's disk cache under it)."""
    tag = pass_tag(model, parallel, uniform)
    ns["gather_two_forces"] = specialize(_gather_two_forces, tag, ns, inline="always", **_OPTIONS)
    if tag not in _COMPILED:
        own = dict(ns)
        own["_refresh_spring"] = specialize(_refresh_spring, tag, own, inline="always", **_OPTIONS)
        # (called, not inlined: the threaded passes' loop bodies are then one call, which Numba's
        # parallel compiler processes in a fraction of the time; see explicit.cpu._spring_pass)
        own["_refresh_block"] = specialize(_refresh_block, tag, own, **_OPTIONS)
        own["_state_spring_block"] = specialize(_state_spring_block, tag, own, **_OPTIONS)
        _COMPILED[tag] = {name: specialize(template, tag, own, parallel=parallel, **_OPTIONS) for name, template in (
            ("temperature_pass", _temperature_pass), ("refresh_pass", _refresh_pass),
            ("finish_refresh_pass", _finish_refresh_pass), ("state_spring_sums", _state_spring_sums))}
    ns.update(_COMPILED[tag])
    ns.update(_sweeps(parallel))


def _sweeps(parallel: bool) -> dict:
    """{"conduction_sweep": …, "wave_sweep": …} compiled for ``parallel`` (see :func:`sweep_tag`)."""
    tag = sweep_tag(parallel)
    if tag not in _COMPILED:
        ns = {"PAIRED": not parallel}
        _bind_exchange(ns, tag, njit(inline="always", error_model="numpy", boundscheck=False))
        # the block exchanges called, not inlined, from the colour's parallel loop: its body is then
        # one call, which Numba's parallel compiler processes in a fraction of the time (see
        # thermonet.explicit.cpu._spring_pass); one call per block costs nothing at run time
        ns["star_block"] = specialize(exchange.star_block, tag, ns, **_OPTIONS)
        ns["_star_nodes"] = specialize(_star_nodes, tag, ns, inline="always", **_OPTIONS)
        ns["_star_blocks"] = specialize(_star_blocks, tag, ns, **_OPTIONS)
        ns["_runs_direction"] = specialize(_runs_direction, tag, ns, inline="always", **_OPTIONS)
        # a function of its own, not inlined into the sweep (whose compile time it would add to;
        # one call per colour costs nothing at run time)
        ns["_sweep_colour"] = specialize(_sweep_colour, tag, ns, parallel=parallel, **_OPTIONS)
        _COMPILED[tag] = {"conduction_sweep": specialize(_conduction_sweep, tag, ns, parallel=parallel, **_OPTIONS),
                          "wave_sweep": specialize(_wave_sweep, tag, ns, parallel=parallel, **_OPTIONS)}
    return _COMPILED[tag]


def _temperature_pass(x, eta, topology, springs, theta, length):
    """theta[e] = θ(l_e, η_e) and length[e] = l_e at positions x, per spring: in blocks, the
    gather first (squared lengths into length), then a loop over contiguous arrays that
    vectorizes (as the spring pass of :mod:`thermonet.explicit.cpu`)."""
    edges = topology.edges
    m = edges.shape[0]
    P = springs.P
    rest = springs.rest
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        n = min(BLOCK, m - lo)
        for i in range(n):
            length[lo + i] = squared_length(x, edges, np.uint64(lo + i))
        for i in range(n):
            e = np.uint64(lo + i)
            c = np.uint64(0) if UNIFORM else e
            l = math.sqrt(length[e])
            length[e] = l
            theta[e] = spring_temperature(l, eta[e], rest[e], P, c)


def _gather_two_forces(a, x, s1, s2, inc_ptr, inc_spring, inc_other, masses, gravity, with_gravity):
    """Node a's forces for two sets of T/l (s1, s2: (m,)) in one walk over its incidences, each
    summed in the order of :func:`thermonet.kernels.subflows.gather_force` (the same bits):
    the deferred kick's and the next kick's, which act at the same positions."""
    xa0 = x[a, 0]
    xa1 = x[a, 1]
    xa2 = x[a, 2]
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    g0 = 0.0
    g1 = 0.0
    g2 = 0.0
    for j in range(inc_ptr[a], inc_ptr[a + 1]):
        ju = np.uint64(j)
        e = inc_spring[ju]
        b = inc_other[ju]
        d0 = x[b, 0] - xa0
        d1 = x[b, 1] - xa1
        d2 = x[b, 2] - xa2
        f0 += s1[e] * d0
        f1 += s1[e] * d1
        f2 += s1[e] * d2
        g0 += s2[e] * d0
        g1 += s2[e] * d1
        g2 += s2[e] * d2
    if with_gravity:
        f0 += masses[a] * gravity[0]
        f1 += masses[a] * gravity[1]
        f2 += masses[a] * gravity[2]
        g0 += masses[a] * gravity[0]
        g1 += masses[a] * gravity[1]
        g2 += masses[a] * gravity[2]
    return f0, f1, f2, g0, g1, g2


def _refresh_spring(e, L, theta, length, phi, springs, s, steps, run):
    """Spring e's part of :func:`_refresh_pass` with its strain L (``Model.strain`` of its
    length): T/l into s[e], Φ[e] += steps[0] θ, += steps[1] θ. Returns whether it is outside
    the admissible states."""
    rest = springs.rest[e]
    c = np.uint64(0) if UNIFORM else e
    l = length[e]
    th = theta[e]
    force = tension_at_strain(L, l, th, rest, springs.P, c) / l
    s[e] = force
    if run.track_phi:
        advance_thermal_displacement(phi, e, th, steps[0], steps[1])
    return outside_admissible(l, rest, force, th, run.stretch_min, run.stretch_max)


def _refresh_block(lo, n, theta, length, strain, strain_ok, phi, springs, s, steps, run):
    """:func:`_refresh_spring` of springs lo … lo + n − 1, their strains from ``strain`` when
    ``strain_ok`` (kept by the spring pass that kept the lengths: no logarithm), else from the
    lengths (the same bits). Returns the number outside the admissible states."""
    bad = 0
    if strain_ok:
        for i in range(n):
            e = np.uint64(lo + i)
            bad += _refresh_spring(e, strain[e], theta, length, phi, springs, s, steps, run)
    else:
        for i in range(n):
            e = np.uint64(lo + i)
            bad += _refresh_spring(e, model_strain(length[e], springs.rest[e]), theta, length, phi, springs, s, steps,
                                   run)
    return bad


def _refresh_pass(theta, length, strain, strain_ok, phi, springs, s, steps, run):
    """The spring pass of a kick at the positions of the last full one, after conduction sweeps
    changed θ: per spring T/l from the stored length (and its strain, see :func:`_refresh_block`)
    and the swept θ into s, Φ += steps[0] θ, += steps[1] θ. No gather, no square root, no
    θ(l, η): a stream over contiguous arrays. theta, length, strain, phi, s: (m,). Returns the
    number of springs outside the admissible states."""
    m = theta.shape[0]
    bad = 0
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        bad += _refresh_block(lo, min(BLOCK, m - lo), theta, length, strain, strain_ok, phi, springs, s, steps, run)
    return bad


def _finish_refresh_pass(heat, theta, eta, phi, springs, s, steps, run, strain_ok):
    """The sweeps' entropy update left to the caller (DEFER_FINISH: :func:`finish_spring` from
    heat.theta_start, heat.capacity into eta and heat.produced) and :func:`_refresh_pass` (the
    lengths and strains heat.length, heat.strain) in one pass over the springs: the same
    operations per spring, the same bits. steps = (τ0, τ2): the deferred kick's Φ += τ0 θ from the
    temperatures before the sweeps (heat.theta_start: its spring pass left Φ to this pass, which
    reads them anyway), then the refresh's Φ += τ2 θ. Returns the number of springs outside the
    admissible states."""
    theta_start = heat.theta_start
    capacity = heat.capacity
    produced = heat.produced
    length = heat.length
    strain = heat.strain
    deferred = steps[0]
    track = run.track_phi and deferred != 0.0
    bad = 0
    m = theta.shape[0]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        n = min(BLOCK, m - lo)
        for i in range(n):  # (loops of their own over a block: each vectorizes, one would not)
            finish_spring(np.uint64(lo + i), theta, theta_start, eta, capacity, produced)
        if track:
            for i in range(n):
                e = np.uint64(lo + i)
                phi[e] += deferred * theta_start[e]
        bad += _refresh_block(lo, n, theta, length, strain, strain_ok, phi, springs, s, (0.0, steps[1]), run)
    return bad


def _star_nodes(i1, i2, inc_ptr, inc_spring, weight, decay, node_scale, theta):
    """:func:`thermonet.heat.exchange.star_node` of nodes i1 and i2, which share no spring, with
    shared factors (weight, decay: floats): the two junction sums in one loop, each in its own
    order (the same bits), so that the processor overlaps their chains of dependent additions.
    i2 < 0: i1 alone."""
    lo1 = inc_ptr[i1]
    n1 = inc_ptr[i1 + 1] - lo1
    lo2 = lo1
    n2 = 0
    if i2 >= 0:
        lo2 = inc_ptr[i2]
        n2 = inc_ptr[i2 + 1] - lo2
    both = min(n1, n2)
    total1 = 0.0
    total2 = 0.0
    for j in range(both):
        total1 += weight * theta[inc_spring[np.uint64(lo1 + j)]]
        total2 += weight * theta[inc_spring[np.uint64(lo2 + j)]]
    for j in range(both, n1):
        total1 += weight * theta[inc_spring[np.uint64(lo1 + j)]]
    for j in range(both, n2):
        total2 += weight * theta[inc_spring[np.uint64(lo2 + j)]]
    junction1 = total1 * node_scale[i1]
    for j in range(n1):
        e = inc_spring[np.uint64(lo1 + j)]
        theta[e] = junction1 + (theta[e] - junction1) * decay
    if n2 > 0:
        junction2 = total2 * node_scale[i2]
        for j in range(n2):
            e = inc_spring[np.uint64(lo2 + j)]
            theta[e] = junction2 + (theta[e] - junction2) * decay


def _star_blocks(b1, b2, heat, reverse, theta):
    """:func:`thermonet.heat.exchange.star_block` of blocks b1 and b2 of one colour (b2 < 0: b1
    alone) with shared factors (heat.factor_mask[0] == 0), node k of one with node k of the
    other (:func:`_star_nodes`); each block's nodes in their order, so the same bits."""
    block_ptr = heat.block_ptr
    block_node = heat.block_node
    inc_ptr = heat.inc_ptr
    inc_spring = heat.inc_spring
    node_scale = heat.node_scale
    weight = heat.weight[0]
    decay = heat.decay[0]
    lo1 = block_ptr[b1]
    n1 = block_ptr[b1 + 1] - lo1
    lo2 = lo1
    n2 = 0
    if b2 >= 0:
        lo2 = block_ptr[b2]
        n2 = block_ptr[b2 + 1] - lo2
    for k in range(max(n1, n2)):
        i1 = -1
        i2 = -1
        if k < n1:
            i1 = block_node[lo1 + n1 - 1 - k if reverse else lo1 + k]
        if k < n2:
            i2 = block_node[lo2 + n2 - 1 - k if reverse else lo2 + k]
        if i1 < 0:
            i1, i2 = i2, i1
        _star_nodes(i1, i2, inc_ptr, inc_spring, weight, decay, node_scale, theta)


def _runs_direction(q, directions):
    """Whether a block of :func:`_sweep_colour` runs its q-th pass (0: reverse, 1: forward, 2:
    reverse again), in that order, for ``directions``."""
    if q == 0:
        return directions & REVERSE != 0
    if q == 1:
        return directions & (FORWARD | FORWARD_THEN_REVERSE) != 0
    return directions & FORWARD_THEN_REVERSE != 0


def _sweep_colour(heat, ptr, colour, directions, theta):
    """The blocks of one colour, in parallel: each reverse (REVERSE), forward (FORWARD),
    reverse then forward (both), or forward then reverse (FORWARD_THEN_REVERSE). With shared
    factors and two blocks or more (with threads:
    PAIRS_FROM or more, a pair for every thread of the pool), the blocks go in pairs (block k
    with block k + ⌈B/2⌉ of the colour, :func:`_star_blocks`), the pairs in parallel; the pairing changes no result, only
    the order in which independent blocks interleave. (Unpaired, a thread's junction sums are
    one chain of dependent additions at a time: two threads on single blocks were no faster
    than one thread on pairs.)"""
    lo = ptr[colour]
    count = ptr[colour + 1] - lo
    if count >= (2 if PAIRED else PAIRS_FROM) and heat.factor_mask[0] == 0:
        half = count // 2
        odd = count - 2 * half
        for k in prange(half + odd):
            b1 = lo + k
            b2 = b1 + half + odd if k < half else -1
            for q in range(3):  # (two inlined copies of the block exchange, not three)
                if _runs_direction(q, directions):
                    if q == 1:  # (literal directions: a block's node order compiled in)
                        _star_blocks(b1, b2, heat, False, theta)
                    else:
                        _star_blocks(b1, b2, heat, True, theta)
    else:
        for b in prange(lo, lo + count):
            for q in range(3):
                if _runs_direction(q, directions):
                    if q == 1:
                        star_block(b, heat, False, theta)
                    else:
                        star_block(b, heat, True, theta)


def _conduction_sweep(heat, theta, theta_start, eta, tau, t, directions):
    """Conduction half sweeps over τ each at time t (see the module docstring): ``directions``
    REVERSE (the half that ends a cycle), FORWARD (the half that starts one) or both (the reverse
    one first), with SAVE or CONTINUE. A step boundary is 2j half sweeps, j = heat.sweeps[0],
    alternately reverse and forward: the first j end a cycle, their last a reverse one, the last
    j start the next, their first a forward one (j = 1: one reverse, one forward; j = 2: forward,
    reverse | forward, reverse). theta must hold the springs' temperatures at the current
    positions, and is kept so; theta_start (m,) is scratch. Ends with each spring's entropy
    update (:func:`finish_spring`) unless DEFER_FINISH."""
    ptr = heat.star_colour_ptr
    n_colours = ptr.shape[0] - 1
    # the arrays written in parallel loops are taken out of the record first: Numba's parallel
    # loops lose writes made through a record's attribute
    produced = heat.produced
    logs = (produced, heat.entry_heat, heat.entry_flux)
    capacity = heat.capacity
    n_bound = heat.bound_spring.shape[0]
    m = theta.shape[0]
    pending_eta = heat.pending_eta
    pending_produced = heat.pending_produced
    pending_theta = heat.pending_theta
    if directions & CONTINUE:
        for e in prange(m):
            theta_start[e] = pending_theta[e]
            eta[e] = pending_eta[e]
            produced[e] = pending_produced[e]
    else:
        for e in prange(m):
            theta_start[e] = theta[e]
    sweeps = heat.sweeps[0]
    first = 0 if directions & REVERSE else sweeps
    last = 2 * sweeps if directions & FORWARD else sweeps
    # with no boundary entries between them, a half sweep's last colour and the next one's first
    # (the same colour: the directions alternate) run as one phase, each block in one direction
    # then the other (a block's springs meet no other block of its colour: the same operations
    # in the same order); one colour alone is one phase either way
    fuse = n_bound == 0 and n_colours > 1
    joined = False  # this half sweep's first colour ran with the last one's last
    for half in range(first, last):
        more = fuse and half + 1 < last
        reverse = reverse_half(half, sweeps)
        # forward: the boundary entries, then the colours in order; reverse: the colours backwards,
        # then the entries (one call site each: each is compiled once)
        for stage in range(3):
            if stage == 1:
                for i in range(1 if joined else 0, n_colours):
                    code = REVERSE if reverse else FORWARD
                    if more and i == n_colours - 1:
                        code = REVERSE | FORWARD if reverse else FORWARD_THEN_REVERSE
                    # (np.int64: with a literal, the call would compile a second _sweep_colour)
                    _sweep_colour(heat, ptr, n_colours - 1 - i if reverse else i, np.int64(code), theta)
            elif n_bound > 0 and (stage == 2) == reverse:  # (a parallel loop costs a barrier even when empty)
                for j in prange(n_bound):
                    boundary_exchange(j, heat, tau, t, reverse, theta, logs)
        joined = more
    if directions & SAVE:
        for e in prange(m):
            pending_theta[e] = theta_start[e]
            pending_eta[e] = eta[e]
            pending_produced[e] = produced[e]
    if not directions & DEFER_FINISH:
        for e in prange(m):
            finish_spring(e, theta, theta_start, eta, capacity, produced)


def conduction_boundary(state, cur, topology, springs, scratch, heat, run, pending, directions, step):
    """The conduction sweeps at the start of step ``step`` of a call of the explicit kernel (``directions``:
    REVERSE ends a cycle, FORWARD starts one; SAVE, CONTINUE as :func:`_conduction_sweep`), the
    springs' θ at the positions ``cur`` in scratch.theta_keep. A closing kick still pending
    there (``pending``, its coefficient) acts with the temperatures before the sweeps: its
    spring pass runs now (it leaves θ and l at cur), its forces kept in heat.s_before, and its
    node pass is deferred by the caller (the sweeps do not touch p). Returns the number of
    inadmissible springs that spring pass found (0: swept)."""
    if pending != 0.0:  # (its T/l straight into heat.s_before)
        before = Scratch(scratch.x_buf, heat.s_before, scratch.f_keep, scratch.theta_keep, scratch.energy_buf,
                         scratch.sums, scratch.node_accs, scratch.node_terms)
        # with DEFER_FINISH the entropy update's pass (finish_refresh_pass) adds this kick's Φ
        # += τ θ, from the same θ and in the same order: one read and write of Φ less
        own_phi = Run(run.h, run.t0, run.n_steps, run.track_phi and (directions & DEFER_FINISH) == 0, run.stretch_min,
                      run.stretch_max, run.reuse_boundary, run.want_sums, run.conduction_every, run.cycle_step)
        # keep = (pending != 0.0), True here, as a run-time bool: the literal True would compile
        # a second spring pass, differing from the step's only in a branch outside its loops
        bad = spring_pass(cur, state.eta, state.phi, topology, springs, before, (0.0, pending * run.h), own_phi,
                          pending != 0.0, heat.length, heat.strain)[0]
        if bad > 0:
            return bad
    conduction_sweep(heat, scratch.theta_keep, heat.theta_start, state.eta,
                     0.5 * run.conduction_every * run.h / heat.sweeps[0], run.t0 + step * run.h, directions)
    return 0


def deferred_kick(x, x_new, p, topology, nodes, scratch, heat, loads, when, want_sums):
    """The kick deferred past the sweeps by itself, with the forces in heat.s_before at x and,
    with LOADS, the loads at time t (and their work); when = (τ, already times h; t). With
    ``want_sums`` (a call's end) it is the call's closing node pass: it reduces the node sums of a
    diagnostics row at (x, the new p) into scratch.node_accs as
    :func:`thermonet.explicit.cpu._node_pass` does."""
    tau, t = when
    if LOADS:
        cpu_evaluate_loads(loads, t)
    if want_sums:
        boundary_node_pass(x, x_new, p, topology, nodes, scratch, KickDrift(tau, 0.0, 0.0, True),
                           np.int64(FORCE_DEFERRED), np.bool_(True), (heat.s_before, loads))
    else:
        node_pass(x, x_new, p, topology, nodes, scratch, KickDrift(tau, 0.0, 0.0, True), np.int64(FORCE_DEFERRED),
                  False, (heat.s_before, loads))
    if LOADS:
        cpu_load_work(x, heat.s_before, topology, nodes, loads, 0.0, tau)


def _state_spring_sums(x, eta, topology, springs, energy, theta):
    """Each spring's U(l, η) at (x (n, 3), η (m,)) into energy (m,), with the arithmetic of
    :func:`thermonet.kernels.reductions._spring_energies` (the same bits), and (min θ, max θ):
    a diagnostics row's spring terms for a call that ends on a conduction sweep, whose last
    spring pass ran before the sweep changed η. theta: (m,) scratch."""
    edges = topology.edges
    l0 = springs.rest
    P = springs.P
    m = edges.shape[0]
    theta_min = math.inf
    theta_max = -math.inf
    for blk in prange((m + BLOCK - 1) // BLOCK):  # (the body one call: see _refresh_block)
        lo = np.int64(blk) * BLOCK
        block_min, block_max = _state_spring_block(x, eta, edges, l0, P, energy, theta, lo, min(BLOCK, m - lo))
        theta_min = min(theta_min, block_min)
        theta_max = max(theta_max, block_max)
    return theta_min, theta_max


def _state_spring_block(x, eta, edges, l0, P, energy, theta, lo, n):
    """Springs lo … lo + n − 1 of :func:`_state_spring_sums`; returns their range of θ."""
    for i in range(n):
        theta[lo + i] = squared_length(x, edges, np.uint64(lo + i))
    for i in range(n):
        e = np.uint64(lo + i)
        c = np.uint64(0) if UNIFORM else e
        l = math.sqrt(theta[e])
        th = spring_temperature(l, eta[e], l0[e], P, c)
        theta[e] = th
        energy[e] = spring_energy(l, eta[e], th, l0[e], P, c)
    block_min = math.inf
    block_max = -math.inf
    for i in range(n):
        e = np.uint64(lo + i)
        block_min = min(block_min, theta[e])
        block_max = max(block_max, theta[e])
    return block_min, block_max


def _wave_sweep(heat, phi, eta, tau):
    """The Green–Naghdi flow over τ, colour by colour (total entropy exact)."""
    ptr = heat.colour_ptr
    first, second, wave = heat.first, heat.second, heat.wave
    for colour in range(ptr.shape[0] - 1):
        for k in prange(ptr[colour], ptr[colour + 1]):
            wave_exchange(k, first, second, wave, tau, phi, eta)


_CACHE: dict = {}


def source_digest(parallel: bool) -> str:
    """A short hash of this module's and :mod:`thermonet.heat.exchange`'s sources, part of the
    cache names of the kernels that compile them in (Numba's disk cache checks only the file of
    the function it caches, not the passes that file's kernel calls); for the threaded kernels,
    with PAIRS_FROM (the serial ones do not read it, so a process with another thread count,
    such as an MPI rank or a Dask worker, loads them from the cache)."""
    import hashlib
    import inspect
    import sys

    text = inspect.getsource(sys.modules[__name__]) + exchange.source_digest()
    if parallel:
        text += f"pairs from {PAIRS_FROM}"
    return hashlib.sha256(text.encode()).hexdigest()[:8]


def heat_kernels(model, parallel: bool, uniform: bool):
    """(temperature_pass, conduction_sweep) for steppers that run conduction around their own
    steps (the implicit ones): ``temperature_pass(x, eta, topology, springs, theta, length)``,
    ``conduction_sweep(heat, theta, theta_start, eta, tau, t, directions)``."""
    from ..kernels.subflows import bind_subflows

    key = (model_fingerprint(model), bool(parallel), bool(uniform))
    if key not in _CACHE:
        tag = pass_tag(model, parallel, uniform)
        ns = kernel_namespace(model, True, uniform)
        inline = njit(inline="always", error_model="numpy", boundscheck=False)
        bind_subflows(ns, tag, inline)
        bind_heat_flow(ns, tag, inline)
        bind_heat_passes(ns, model, parallel, uniform)
        _CACHE[key] = (ns["temperature_pass"], ns["conduction_sweep"])
    return _CACHE[key]
