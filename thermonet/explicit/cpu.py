"""The CPU kernel of the explicit integrators: the rows of a stage table, fused.

Every explicit integrator of thermonet is a sequence ``K(k0) D(d0) K(k1) … D(d_{S−1}) K(k_S)``
of sub-flows with coefficients (fractions of h), possibly with further sub-flows between them,
given to the kernel as the rows of a :class:`~thermonet.explicit.schedule.StageTable`:

- kick ``K(k)``: at the current positions x, per spring θ = θ(l, η) and T = T(l, θ);
  ``p += k h f(x, θ)`` and ``Φ += k h θ`` (entropy η is untouched, so it is conserved exactly);
- drift ``D(d)``: ``x += d h M⁻¹ p``;
- a flow row: an extra :class:`~thermonet.explicit.schedule.SubFlow`, one parallel pass over
  its elements.

What each sub-flow does to one spring or node is :mod:`thermonet.kernels.subflows` (shared with
the CUDA kernels); this module decides how the CPU runs them. One *stage* is a kick followed by a
drift and costs two passes over memory:

1. per spring, in blocks of ``BLOCK`` springs (parallel over blocks): a scalar loop gathers the
   squared lengths |x_b − x_a|² into ``s``; a second loop over the same block, now reading only
   contiguous arrays, computes l, θ, T/l into ``s`` and updates Φ. The second loop carries all the
   arithmetic (sqrt, the model's exp/log, divisions) and LLVM vectorizes it, which it does not do
   for a loop that also gathers; the block is still in L1 when the second loop reads it back.
2. per node (parallel over nodes): gather ``f_a = Σ_e s_e (x_b − x_a)`` over the incident springs
   (CSR lists), kick, drift into a second position buffer (others still read the old one).

Indices are read as unsigned (zero-copy views of the int32 arrays): Numba wraps negative signed
indices around with a compare-and-select per access, which costs about a third of the gather
pass and blocks vectorization; an unsigned index has no negative case.

Blow-up detection costs one comparison chain per spring in the vectorized loop: a spring whose
stretch l/l0 leaves (stretch_min, stretch_max), whose T/l is not finite (a non-finite position
gives that too) or, with thermal coupling, whose θ is not > 0 is counted; a stage that counts
any stops the kernel at once, before the node pass. ``advance`` then returns how many steps were
completed before the step in which it happened, with ``x`` holding the positions it was found
at; the caller rewinds to the last good step (see ``Simulation``).

The last kick of one step and the first kick of the next act at the same positions and share one
force evaluation; they are still applied as two separate additions, so a run cut into chunks at
any step boundary gives bit-for-bit the same numbers as one long call. A call ends with the
closing kick of its last step; it keeps that kick's forces and temperatures (``f_keep``,
``theta_keep``), and a following call from the same state (``reuse_boundary``, the caller's
promise) starts from them instead of evaluating them again: without that, every observer stop of a
run (a diagnostics row every 10 steps, say) would cost one more force evaluation, a whole CO2 step.
With ``want_sums`` the closing kick also does a diagnostics row's work at the synchronized state
the call ends in: its spring pass leaves each spring's internal energy in ``energy_buf`` and the
temperature range in ``sums``; its node pass reduces kinetic and gravity energy, the momenta and
the angular momenta exactly (:mod:`thermonet.kernels.exact`) into ``node_accs``, one
accumulator per chunk of nodes. A row then costs an exact sum over two per-spring arrays
(U, η) instead of passes over the state (:mod:`thermonet.kernels.reductions` is the stand-alone
version, for states no call ends in). Every spring and every
node is computed by one thread with a fixed summation order, so results do not depend on the
number of threads.

When every spring has the same model parameters (a common case), :func:`kernel_parameters`
returns a ``(k, 1)`` array and the kernels are compiled with ``UNIFORM``: the model functions are
called with column ``e = 0``, so the loop reads the parameters once instead of ``8 k`` bytes per
spring and force evaluation.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..heat.passes import (CONTINUE, DEFER_FINISH, FORWARD, REVERSE, SAVE, bind_heat_flow, bind_heat_passes,
                           conduction_boundary, deferred_kick, source_digest as heat_source_digest)
from ..heat.rows import THERMAL_WAVES
from ..kernels import subflows
from ..kernels.blocks import BLOCK, squared_lengths
from ..kernels.exact import add_terms, normalize
from ..kernels.reductions import NODE_SUMS, chunk_length, node_diagnostic_terms, rows_digest
from ..kernels.copies import _copy_rows, _copy_values
from ..kernels.records import KickDrift
from ..kernels.specialize import (function_fingerprint, kernel_namespace, model_fingerprint, rebind, specialize,
                                  specialize_by_content)
from ..kernels.subflows import bind_subflows
from ..loads.elements import bind_loads
from .codes import FORCE_DEFERRED, FORCE_GATHER, FORCE_GATHER_KEEP, FORCE_KEPT
from .passes import _apply_flow, _flow_pass, _no_flow, _stopped, _thermal_kick, store_sums
from .schedule import FIRST_FLOW_SLOT

# Bound per kernel variant by splitting_kernels(); listed so the templates read as ordinary code.
# THERMAL, CLOSING, REFERENCE_TEMPERATURE and UNIFORM are compile-time constants: with THERMAL
# False the kernel is the purely mechanical one (every spring at its reference temperature,
# parameter row REFERENCE_TEMPERATURE; no η, θ or Φ is read or written); with UNIFORM, P is
# (k, 1) and shared. The sub-flows (spring_force, gather_force, ...) are those of
# thermonet.kernels.subflows; the small passes (thermal_kick, ...) those of .passes, the row
# copies those of thermonet.kernels.copies;
# the loads' functions (node_load, cpu_*) those of thermonet.loads.elements, with LOADS.
spring_pass = node_pass = boundary_spring_pass = boundary_node_pass = closing_node_kick = spring_block = None
spring_at = None
node_block = closing_node_chunk = None
thermal_kick = copy_rows = apply_flow = None
spring_force = spring_energy = spring_temperature = outside_admissible = advance_thermal_displacement = None
gather_force = kick_momentum = drift_position = load_row = store_row = None
temperature_pass = refresh_pass = finish_refresh_pass = conduction_sweep = wave_sweep = gather_two_forces = None
model_strain = None
_deferred_kick = state_spring_sums = None
node_load = cpu_evaluate_loads = cpu_load_work = cpu_drive_positions = stage_time = None
LOADS = False
THERMAL = True
CONDUCTION = False
WAVES = False
CLOSING = False
REFERENCE_TEMPERATURE = 0
UNIFORM = False

_CACHE: dict = {}
_PASSES: dict = {}  # each variant's namespace: its passes, for thermonet.parallel's stage driver

_OPTIONS = dict(cache=True, error_model="numpy", boundscheck=False, _nrt=False)  # specialize(): no reference counting

def splitting_kernels(model, parallel: bool, thermal: bool = True, uniform: bool = False, flows=(),
                      conduction: bool = False, waves: bool = False, loads: bool = False):
    """``advance(state, scratch, topology, springs, nodes, table, effects, heat, run, loads)`` compiled for
    ``model`` (multi-threaded when ``parallel``; purely mechanical when not ``thermal``, in which
    case ``phi`` and ``eta`` may be empty arrays; for a ``(k, 1)`` parameter array shared by all
    springs when ``uniform``, see :func:`kernel_parameters`) with the extra sub-flows ``flows``
    (:class:`~thermonet.explicit.schedule.SubFlow` s, slot order) in its flow slots, the
    heat-flow rows it may meet compiled in (``conduction``, ``waves``; both need ``thermal``), and
    with ``loads`` the node pass and the step read a :class:`~thermonet.loads.arrays.LoadArrays`
    (the ``loads`` argument; otherwise a placeholder, and the loads' code is compiled out)."""
    key = (model_fingerprint(model), bool(parallel), bool(thermal), bool(uniform),
           tuple(id(f) for f in flows), bool(conduction), bool(waves), bool(loads))
    if key not in _CACHE:
        flows_tag = f"_f{function_fingerprint(*(f.update for f in flows))}" if flows else ""
        tag = (f"{model.name}_{key[0]}_{'par' if parallel else 'ser'}_{'thermal' if thermal else 'mech'}"
               f"{'_uniform' if uniform else ''}_s{subflows.source_digest()}_r{rows_digest()}{flows_tag}")
        if conduction or waves:
            tag += f"_{'k' if conduction else ''}{'w' if waves else ''}{heat_source_digest(parallel)}"
        ns = kernel_namespace(model, thermal, uniform)
        ns["CLOSING"] = False
        ns["CONDUCTION"] = bool(conduction)
        ns["WAVES"] = bool(waves)
        inline = njit(inline="always", error_model="numpy", boundscheck=False)
        bind_subflows(ns, tag, inline)
        if conduction or waves:
            bind_heat_flow(ns, tag, inline)
            bind_heat_passes(ns, model, parallel, uniform)
        ns["LOADS"] = bool(loads)
        if loads:
            tag += bind_loads(ns, tag, inline)
        # the passes are named by what they read (specialize_by_content): a node pass reads no
        # model or parameter layout, a spring pass no loads, so variants share them
        threaded = dict(_OPTIONS, parallel=parallel)
        ns["spring_at"] = specialize_by_content(_spring_at, tag, ns, inline="always", **_OPTIONS)
        ns["spring_block"] = specialize_by_content(_spring_block, tag, ns, **_OPTIONS)
        ns["spring_pass"] = specialize_by_content(_spring_pass, tag, ns, **threaded)
        ns["node_block"] = specialize_by_content(_node_block, tag, ns, **_OPTIONS)
        ns["node_pass"] = specialize_by_content(_node_pass, tag, ns, **threaded)
        boundary = dict(ns, CLOSING=True)
        boundary["spring_block"] = specialize_by_content(_spring_block, tag + "_boundary", boundary, **_OPTIONS)
        boundary["closing_node_kick"] = specialize(_closing_node_kick, tag + "_boundary", boundary, inline="always",
                                                   **_OPTIONS)
        boundary["closing_node_chunk"] = specialize_by_content(_closing_node_chunk, tag + "_boundary", boundary,
                                                               **_OPTIONS)
        ns["boundary_spring_pass"] = specialize_by_content(_spring_pass, tag + "_boundary", boundary, **threaded)
        ns["boundary_node_pass"] = specialize_by_content(_node_pass, tag + "_boundary", boundary, **threaded)
        ns["thermal_kick"] = specialize_by_content(_thermal_kick, tag, ns, **threaded)
        ns["copy_rows"] = specialize_by_content(_copy_rows, tag, ns, **threaded)
        for slot in range(4):
            if slot < len(flows):
                update_ = flows[slot].update
                if not hasattr(update_, "py_func"):
                    update_ = njit(inline="always", error_model="numpy", boundscheck=False)(update_)
                fn = specialize_by_content(_flow_pass, f"{tag}_{slot}", dict(ns, update=update_), **threaded)
            else:
                fn = _no_flow
            ns[f"flow_pass_{slot}"] = fn
        ns["apply_flow"] = specialize(_apply_flow, tag, ns, inline="always", **_OPTIONS)
        ns["_stopped"] = specialize(_stopped, tag, ns, inline="always", **_OPTIONS)
        if conduction:  # the conduction boundary and the kick it defers (thermonet.heat.passes)
            # (called, not inlined: each is called from two places once per cycle, and inlined
            # both copies would be compiled into the kernel)
            ns["_deferred_kick"] = specialize_by_content(deferred_kick, tag, ns, **_OPTIONS)
            ns["conduction_boundary"] = specialize_by_content(conduction_boundary, tag, ns, **_OPTIONS)
        _CACHE[key] = specialize(_advance, tag, ns, **_OPTIONS)
        _PASSES[key] = ns
    return _CACHE[key]


def variant_passes(model, **variant) -> dict:
    """The namespace of the kernel variant :func:`splitting_kernels` makes for ``model`` and
    ``variant`` (its passes by name; built, nothing compiled)."""
    return kernel_passes(splitting_kernels(model, **variant))


def kernel_passes(kernel) -> dict:
    """The namespace of the kernel variant whose step is ``kernel`` (a stepper's ``_advance``):
    its passes by name, to time them one at a time (benchmarks/heat_cost.py --passes)."""
    return next(ns for key, ns in _PASSES.items() if _CACHE[key] is kernel)


def _spring_pass(x, eta, phi, topology, springs, scratch, steps, run, keep, length, strain):
    """Per spring e: s[e] = T/l at x; Φ[e] += steps[0] θ, += steps[1] θ (two additions); θ into
    theta_keep[e] when ``keep`` (THERMAL only); with ``run.want_sums`` (CLOSING only) the
    spring's internal energy (free energy at θ0 when not THERMAL) into energy_buf[e], which a
    diagnostics row sums exactly, and the range of θ.

    x: (n, 3); eta, phi: (m,); steps: (2,) tuple of floats. Returns (the number of springs
    outside the admissible states, min θ, max θ); the range is inf, −inf unless summed. Compiled
    twice: with CLOSING for the calls' first and last kicks, and without (keep and sums compiled
    out) for every other. With CONDUCTION and ``keep`` each spring's length
    goes to length (m,), its strain (``Model.strain``) to strain (m,) and its θ to theta_keep,
    where the conduction sweeps and the refresh pass take them (a kick followed by no drift: θ,
    l and the strain stay valid).

    The loop over blocks is all this pass does; a block's work is :func:`_spring_block`, a
    serial function of its own, shared with the serial variant: inlined into the parallel loop,
    the block's code (with the model's) went through Numba's parallel compiler several times
    over, and a threaded kernel variant took four to five times as long to compile as its
    serial twin (docs/architecture.md).
    """
    edges = topology.edges
    l0 = springs.rest
    P = springs.P
    s = scratch.s
    theta_keep = scratch.theta_keep
    energy_buf = scratch.energy_buf
    phi_h1, phi_h2 = steps
    track_phi = run.track_phi
    stretch_min = run.stretch_min
    stretch_max = run.stretch_max
    want_sums = CLOSING and run.want_sums
    m = edges.shape[0]
    bad = 0
    theta_min = math.inf
    theta_max = -math.inf
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = np.int64(blk) * BLOCK
        n = min(BLOCK, m - lo)
        block_bad, block_min, block_max = spring_block(lo, n, x, eta, phi, edges, l0, P, s, theta_keep, energy_buf,
                                                       length, strain, keep, want_sums, track_phi, stretch_min,
                                                       stretch_max, phi_h1, phi_h2)
        bad += block_bad
        if CLOSING:
            theta_min = min(theta_min, block_min)
            theta_max = max(theta_max, block_max)
    return bad, theta_min, theta_max


def _spring_block(lo, n, x, eta, phi, edges, l0, P, s, theta_keep, energy_buf, length, strain, keep, want_sums,
                  track_phi, stretch_min, stretch_max, phi_h1, phi_h2):
    """Springs lo … lo + n − 1 of :func:`_spring_pass` (n ≤ BLOCK): a scalar loop gathers the
    squared lengths into s, a second loop over contiguous arrays does the arithmetic (and
    vectorizes). Returns (how many are outside the admissible states, min θ, max θ of the block;
    inf, −inf unless ``want_sums``)."""
    squared_lengths(x, edges, lo, n, s, lo)
    bad = 0
    if CONDUCTION and keep:  # the conduction sweeps and the refresh pass start from θ, l and the strain
        # (a loop of its own: model_strain's logarithm is spring_force's, computed once; a branch
        # on keep inside the loop below would take it on every pass)
        for i in range(n):
            e, c, l, rest, theta, outside = spring_at(lo + i, eta, l0, P, s, stretch_min, stretch_max)
            bad += outside
            theta_keep[e] = theta
            length[e] = l
            strain[e] = model_strain(l, rest)
            if CLOSING and want_sums:
                energy_buf[e] = spring_energy(l, eta[e] if THERMAL else 0.0, theta, rest, P, c)
            if THERMAL and track_phi:
                advance_thermal_displacement(phi, e, theta, phi_h1, phi_h2)
    else:
        for i in range(n):
            e, c, l, rest, theta, outside = spring_at(lo + i, eta, l0, P, s, stretch_min, stretch_max)
            bad += outside
            if CLOSING:
                if THERMAL and keep:
                    theta_keep[e] = theta
                if want_sums:
                    energy_buf[e] = spring_energy(l, eta[e] if THERMAL else 0.0, theta, rest, P, c)
            if THERMAL and track_phi:
                advance_thermal_displacement(phi, e, theta, phi_h1, phi_h2)
    block_min = math.inf
    block_max = -math.inf
    if CLOSING:
        if want_sums:  # after the vectorized loop (a reduction inside it would keep it scalar)
            for i in range(n):
                e = np.uint64(lo + i)
                th = theta_keep[e] if THERMAL else P[REFERENCE_TEMPERATURE, np.uint64(0) if UNIFORM else e]
                block_min = min(block_min, th)
                block_max = max(block_max, th)
    return bad, block_min, block_max


def _spring_at(k, eta, l0, P, s, stretch_min, stretch_max):
    """Spring e = k of :func:`_spring_block`, its squared length in s[e]: T/l into s[e]. Returns
    (e, its parameter column c, l, rest length, θ, whether it is outside the admissible states)."""
    e = np.uint64(k)
    c = np.uint64(0) if UNIFORM else e
    l = math.sqrt(s[e])
    rest = l0[e]
    theta, force = spring_force(l, eta[e] if THERMAL else 0.0, rest, P, c)
    s[e] = force
    return e, c, l, rest, theta, outside_admissible(l, rest, force, theta, stretch_min, stretch_max)


def _node_pass(x, x_new, p, topology, nodes, scratch, steps, force_source, want_sums, inputs):
    """Per node a: f = Σ s_e (x_b − x_a) (+ m g); p += kick1 f; p += kick2 f; x_new = x + drift p/m,
    with steps a :class:`~thermonet.kernels.records.KickDrift`.

    x, x_new, p: (n, 3). force_source (:mod:`thermonet.explicit.codes`): FORCE_GATHER gather f;
    FORCE_GATHER_KEEP gather f and keep it in f_keep (n, 3) (a call's closing kick, whose drift is
    0: x_new is then not written, the positions stay in x); FORCE_KEPT take f from f_keep;
    FORCE_DEFERRED (CONDUCTION) kick1 with the forces of s_before (m,) (a kick deferred past the
    conduction sweeps, which do not touch p), kick2 with those of s.
    inputs = (s_before, loads): with LOADS, the node's force load (a
    :class:`~thermonet.loads.arrays.LoadArrays`) is added to f and its driven axes zeroed
    (:func:`thermonet.loads.elements.node_load`).

    Parallel over nodes; with CLOSING over at most ``reductions.CHUNKS`` chunks of whole blocks
    of BLOCK nodes, each reducing, with ``want_sums``, the sums over its free nodes at (x, the new
    p) of kinetic energy, gravity potential −Σ m g·x, p and (x − ref) × p exactly into
    scratch.node_accs[chunk] (:data:`~thermonet.kernels.reductions.NODE_SUMS` order; the chunks'
    accumulators add up to the row's, whatever the threads; scratch.node_terms holds each
    chunk's terms of a block).
    """
    inc_ptr = topology.inc_ptr
    inc_spring = topology.inc_spring
    inc_other = topology.inc_other
    masses = nodes.masses
    inv_mass = nodes.inv_mass
    anchored = nodes.anchored
    gravity = nodes.gravity
    with_gravity = nodes.with_gravity
    ref = nodes.reference
    s = scratch.s
    f_keep = scratch.f_keep
    kick1, kick2, drift, with_force = steps
    s_before = inputs[0]
    loads = inputs[1]
    # Arrays are taken out of their records here, before the loops: an array read from a record
    # inside a parallel loop is reference-counted at every read (the pass ran 1.8× slower), and
    # writes to one so read were lost.
    if LOADS:
        node_force = loads.node_force
        node_weight = loads.node_weight
        node_drive = loads.node_drive
        load_value = loads.value
        load_free = loads.free
    else:  # (placeholders, unread)
        node_force = node_weight = node_drive = load_value = load_free = s
    n_nodes = x.shape[0]
    # (each parallel loop's body is one call of a serial function: see _spring_pass)
    if CLOSING:
        move = force_source != FORCE_GATHER_KEEP
        node_accs = scratch.node_accs
        node_terms = scratch.node_terms
        per_chunk = chunk_length(n_nodes)
        for c in prange((n_nodes + per_chunk - 1) // per_chunk):
            closing_node_chunk(np.int64(c), per_chunk, x, x_new, p, s, s_before, f_keep, inc_ptr, inc_spring,
                               inc_other, masses, inv_mass, anchored, gravity, with_gravity, ref, kick1, kick2, drift,
                               with_force, force_source, move, want_sums, node_accs, node_terms, node_force,
                               node_weight, node_drive, load_value, load_free)
        return
    for blk in prange((n_nodes + BLOCK - 1) // BLOCK):
        lo = np.int64(blk) * BLOCK
        node_block(lo, min(n_nodes, lo + BLOCK), x, x_new, p, s, s_before, inc_ptr, inc_spring, inc_other, masses,
                   inv_mass, anchored, gravity, with_gravity, kick1, kick2, drift, with_force, force_source, node_force,
                   node_weight, node_drive, load_value, load_free)


def _closing_node_chunk(c, per_chunk, x, x_new, p, s, s_before, f_keep, inc_ptr, inc_spring, inc_other, masses,
                        inv_mass, anchored, gravity, with_gravity, ref, kick1, kick2, drift, with_force, force_source,
                        move, want_sums, node_accs, node_terms, node_force, node_weight, node_drive, load_value,
                        load_free):
    """Chunk c (nodes c·per_chunk … (c + 1)·per_chunk − 1, whole blocks) of a closing
    :func:`_node_pass`: each node's :func:`_closing_node_kick` and, with ``want_sums``, the
    chunk's sums into node_accs[c]."""
    n_nodes = x.shape[0]
    terms = node_terms[c]
    rest = terms[len(NODE_SUMS)]
    if want_sums:
        node_accs[c] = 0
    for lo in range(c * per_chunk, min(n_nodes, (c + 1) * per_chunk), BLOCK):
        k = min(BLOCK, n_nodes - lo)
        for i in range(k):
            a = np.uint64(lo + i)  # (unsigned: no wraparound test per access)
            free, xa0, xa1, xa2, p0, p1, p2 = closing_node_kick(
                a, x, x_new, p, s, s_before, f_keep, inc_ptr, inc_spring, inc_other, masses, inv_mass,
                anchored, gravity, with_gravity, kick1, kick2, drift, with_force, force_source, move,
                node_force, node_weight, node_drive, load_value, load_free)
            if want_sums:  # (a node held still counts for nothing)
                kinetic, potential, l0_, l1_, l2_ = node_diagnostic_terms(xa0, xa1, xa2, p0, p1, p2,
                                                                          masses[a], gravity, ref)
                terms[0, i] = kinetic if free else 0.0
                terms[1, i] = potential if free else 0.0
                terms[2, i] = p0 if free else 0.0
                terms[3, i] = p1 if free else 0.0
                terms[4, i] = p2 if free else 0.0
                terms[5, i] = l0_ if free else 0.0
                terms[6, i] = l1_ if free else 0.0
                terms[7, i] = l2_ if free else 0.0
        if want_sums:
            for q in range(len(NODE_SUMS)):
                add_terms(node_accs[c, q], terms[q], k, rest)
    if want_sums:
        for q in range(len(NODE_SUMS)):
            normalize(node_accs[c, q])


def _node_block(start, stop, x, x_new, p, s, s_before, inc_ptr, inc_spring, inc_other, masses, inv_mass, anchored,
                gravity, with_gravity, kick1, kick2, drift, with_force, force_source, node_force, node_weight,
                node_drive, load_value, load_free):
    """Nodes start … stop − 1 of a :func:`_node_pass` that does not close a call."""
    # (the node's work written out here rather than called like the closing kick's: as an inlined
    # call the stepping passes ran 6–8 % slower)
    for i in range(start, stop):
        a = np.uint64(i)
        xa0, xa1, xa2 = load_row(x, a)
        if anchored[a]:
            store_row(x_new, a, xa0, xa1, xa2)
            continue
        p0, p1, p2 = load_row(p, a)
        deferred = False
        if CONDUCTION:
            deferred = force_source == FORCE_DEFERRED
        if deferred:
            if kick2 != 0.0:
                f0, f1, f2, g0, g1, g2 = gather_two_forces(a, x, s_before, s, inc_ptr, inc_spring, inc_other, masses,
                                                           gravity, with_gravity)
            else:
                f0, f1, f2 = gather_force(a, x, s_before, inc_ptr, inc_spring, inc_other, masses, gravity,
                                          with_gravity)
                g0 = g1 = g2 = 0.0
            if LOADS:
                f0, f1, f2 = node_load(a, f0, f1, f2, node_force, node_weight, node_drive, load_value, load_free)
            p0, p1, p2 = kick_momentum(p0, p1, p2, f0, f1, f2, 0.0, kick1)
            if kick2 != 0.0:
                if LOADS:
                    g0, g1, g2 = node_load(a, g0, g1, g2, node_force, node_weight, node_drive, load_value, load_free)
                p0, p1, p2 = kick_momentum(p0, p1, p2, g0, g1, g2, 0.0, kick2)
            store_row(p, a, p0, p1, p2)
        elif with_force:
            f0, f1, f2 = gather_force(a, x, s, inc_ptr, inc_spring, inc_other, masses, gravity, with_gravity)
            if LOADS:
                f0, f1, f2 = node_load(a, f0, f1, f2, node_force, node_weight, node_drive, load_value, load_free)
            p0, p1, p2 = kick_momentum(p0, p1, p2, f0, f1, f2, kick1, kick2)
            store_row(p, a, p0, p1, p2)
        drift_position(x_new, a, xa0, xa1, xa2, p0, p1, p2, drift * inv_mass[a])


def _closing_node_kick(a, x, x_new, p, s, s_before, f_keep, inc_ptr, inc_spring, inc_other, masses, inv_mass,
                       anchored, gravity, with_gravity, kick1, kick2, drift, with_force, force_source, move, node_force,
                       node_weight, node_drive, load_value, load_free):
    """Node a's work in a closing :func:`_node_pass`, whose arrays it takes one by one (x_new
    written where ``move``). Returns (whether the node is free, its x, its new p); an anchored
    node's p is returned as zeros, unread."""
    xa0, xa1, xa2 = load_row(x, a)
    if anchored[a]:
        if move:
            store_row(x_new, a, xa0, xa1, xa2)
        return False, xa0, xa1, xa2, 0.0, 0.0, 0.0
    p0, p1, p2 = load_row(p, a)
    deferred = False
    if CONDUCTION:
        deferred = force_source == FORCE_DEFERRED
    if deferred:  # no keep
        if kick2 != 0.0:
            f0, f1, f2, g0, g1, g2 = gather_two_forces(a, x, s_before, s, inc_ptr, inc_spring, inc_other, masses,
                                                       gravity, with_gravity)
        else:
            f0, f1, f2 = gather_force(a, x, s_before, inc_ptr, inc_spring, inc_other, masses, gravity,
                                      with_gravity)
            g0 = g1 = g2 = 0.0
        if LOADS:
            f0, f1, f2 = node_load(a, f0, f1, f2, node_force, node_weight, node_drive, load_value, load_free)
        p0, p1, p2 = kick_momentum(p0, p1, p2, f0, f1, f2, 0.0, kick1)
        if kick2 != 0.0:
            if LOADS:
                g0, g1, g2 = node_load(a, g0, g1, g2, node_force, node_weight, node_drive, load_value, load_free)
            p0, p1, p2 = kick_momentum(p0, p1, p2, g0, g1, g2, 0.0, kick2)
        store_row(p, a, p0, p1, p2)
    elif with_force:
        if force_source == FORCE_KEPT:
            f0, f1, f2 = load_row(f_keep, a)
        else:
            f0, f1, f2 = gather_force(a, x, s, inc_ptr, inc_spring, inc_other, masses, gravity, with_gravity)
            if LOADS:
                f0, f1, f2 = node_load(a, f0, f1, f2, node_force, node_weight, node_drive, load_value, load_free)
            if force_source == FORCE_GATHER_KEEP:
                store_row(f_keep, a, f0, f1, f2)
        p0, p1, p2 = kick_momentum(p0, p1, p2, f0, f1, f2, kick1, kick2)
        store_row(p, a, p0, p1, p2)
    if move:
        drift_position(x_new, a, xa0, xa1, xa2, p0, p1, p2, drift * inv_mass[a])
    return True, xa0, xa1, xa2, p0, p1, p2


def _advance(state, scratch, topology, springs, nodes, table, effects, heat, run, loads):
    """Advance ``state`` (x, p, Φ in place; η too where a sub-flow changes it) by ``run.n_steps``
    steps of the schedule ``table`` (a :class:`~thermonet.explicit.schedule.StageTable`).

    The closing kick's forces and temperatures are kept in f_keep and theta_keep; with
    ``run.reuse_boundary`` the first kick takes them from there instead of evaluating them (the
    caller vouches that x, η are those of the previous call's end). With ``run.want_sums`` the
    closing kick leaves the end state's diagnostics terms: each spring's U (F(l, θ0) when not
    THERMAL) in energy_buf, min θ and max θ in sums (2,), and the exact node sums (kinetic,
    gravity potential, p, angular momentum about the reference point) in node_accs.

    Returns (steps completed, detected, summed): ``detected`` when a spring left the admissible
    states (see the module docstring); then ``x`` holds the positions where it was found and only
    the first ``steps completed`` steps are known good (x, p, Φ are mid-step: rewind and replay).
    ``summed``: the sums were written (a schedule without a closing kick writes none).

    CONDUCTION (:class:`~thermonet.kernels.records.Heat`): the sweeps of the cycles
    ``K_f(kh/2) ∘ A(h)^k ∘ K_r(kh/2)`` (k = ``run.conduction_every``) run at their boundaries
    (:func:`thermonet.heat.passes.conduction_boundary`), from the springs' θ in theta_keep (valid
    after a spring pass not followed by a drift, or a sweep; else a temperature pass first).

    With LOADS, ``loads`` (:class:`~thermonet.loads.arrays.LoadArrays`): before each kick the
    loads are evaluated at its time, after it their reactions and work are accumulated, and after
    each drift the driven nodes are set to the drift's end time (:mod:`thermonet.loads.elements`).
    """
    x = state.x
    p = state.p
    phi = state.phi
    eta = state.eta
    x_buf = scratch.x_buf
    h = run.h
    n_steps = run.n_steps
    codes = table.code
    n_rows = codes.shape[0]
    carry = table.carry
    cur = x
    nxt = x_buf
    swaps = 0
    pending = 0.0
    # CONDUCTION: the springs' θ and l at cur are in theta_keep and heat.length when theta_valid;
    # a closing kick pending at a cycle boundary is deferred past the sweeps and applied with the
    # next kick in one node pass: ``deferred`` its coefficient, its forces in heat.s_before
    theta_valid = False
    strain_ok = False  # heat.strain holds the strains of heat.length (a spring pass of this call kept both)
    deferred = 0.0
    deferred_time = 0.0
    swept_first = ended_cycle = False  # a sweep ran before the first kick / after the last step
    every = run.conduction_every
    resume_sweep = False  # the previous call ended with a reverse half sweep: continue its update
    # a sweep inside the call leaves its entropy update to the spring pass of the kick that row 0
    # starts with (one pass over the springs instead of two): ``unfinished`` until then
    defer = DEFER_FINISH if THERMAL_WAVES < codes[0] < FIRST_FLOW_SLOT and table.kick[0] != 0.0 else 0
    unfinished = False
    if CONDUCTION and heat.theta_ok[0] >= 1.0:  # continue the previous call's sweeps
        _copy_values(heat.theta, scratch.theta_keep)
        theta_valid = True
        resume_sweep = heat.theta_ok[0] == 2.0
    for step in range(n_steps):
        if CONDUCTION and (run.cycle_step + step) % every == 0:
            # a cycle starts: the last one's reverse half sweep (when it ended in this call) and
            # this one's forward half sweep, back to back
            directions = defer | (FORWARD | REVERSE if step > 0 else (FORWARD | CONTINUE if resume_sweep else FORWARD))
            if pending == 0.0 and not theta_valid:
                temperature_pass(cur, eta, topology, springs, scratch.theta_keep, heat.length)
                strain_ok = False
            bad = conduction_boundary(state, cur, topology, springs, scratch, heat, run, pending, directions, step)
            if bad > 0:  # the pending kick's positions end the previous step: that step was the bad one
                return _stopped(x, x_buf, swaps, heat, step - 1)
            if pending != 0.0:  # (its spring pass kept θ, l and the strains)
                deferred = pending
                if LOADS:
                    deferred_time = stage_time(loads, h, step, 0.0)
                pending = 0.0
                strain_ok = True
            theta_valid = True
            unfinished = defer != 0
            swept_first = swept_first or step == 0
        for r in range(n_rows):
            if codes[r] >= FIRST_FLOW_SLOT:
                if CONDUCTION and deferred != 0.0:  # a sub-flow may read p: apply the kick first
                    _deferred_kick(cur, nxt, p, topology, nodes, scratch, heat, loads, (deferred * h, deferred_time),
                                   np.bool_(False))  # (not the literal False: one compiled signature)
                    deferred = 0.0
                apply_flow(codes[r], effects, table.kick[r] * h, run.t0 + (step + table.drift[r]) * h,
                           cur, p, phi, eta)
                theta_valid = False
                continue
            if codes[r] <= THERMAL_WAVES:
                if WAVES:
                    wave_sweep(heat, phi, eta, table.kick[r] * h)
                    theta_valid = False
                continue
            k1 = pending if r == 0 else 0.0
            k2 = table.kick[r]
            with_force = k1 != 0.0 or k2 != 0.0
            steps = KickDrift(k1 * h, k2 * h, table.drift[r] * h, with_force)
            reuse = run.reuse_boundary and step == 0 and r == 0 and with_force and not swept_first
            if reuse:  # the previous call's closing kick evaluated these at these positions
                if THERMAL and run.track_phi:
                    thermal_kick(phi, scratch.theta_keep, k2 * h)
            elif with_force:
                if CONDUCTION and unfinished:  # (k1 = 0: the pending kick was deferred past the sweeps)
                    bad = finish_refresh_pass(heat, scratch.theta_keep, eta, phi, springs, scratch.s,
                                              (deferred * h, k2 * h), run, strain_ok)
                    unfinished = False
                elif CONDUCTION and theta_valid:
                    bad = refresh_pass(scratch.theta_keep, heat.length, heat.strain, strain_ok, phi, springs, scratch.s,
                                       (k1 * h, k2 * h), run)
                else:
                    bad = spring_pass(cur, eta, phi, topology, springs, scratch, (k1 * h, k2 * h), run,
                                      table.drift[r] == 0.0, heat.length, heat.strain)[0]
                    strain_ok = True  # (kept with l when no drift follows; else θ is not valid either)
                if bad > 0:
                    if CONDUCTION and deferred != 0.0:  # p still misses it: the step is replayed anyway
                        deferred = 0.0
                    # positions at row 0 are the end of the previous step: that step was the bad one
                    return _stopped(x, x_buf, swaps, heat, step - 1 if r == 0 and step > 0 else step)
                if CONDUCTION:  # (a spring pass keeps θ and l: valid until a drift)
                    theta_valid = True
            if table.drift[r] != 0.0:
                theta_valid = False
            if LOADS and with_force:
                cpu_evaluate_loads(loads, stage_time(loads, h, step, loads.kick_time[r]))
            elif LOADS and deferred != 0.0:
                cpu_evaluate_loads(loads, deferred_time)
            if reuse:
                boundary_node_pass(cur, nxt, p, topology, nodes, scratch, steps, np.int64(FORCE_KEPT),
                                   np.bool_(False), (heat.s_before, loads))
            elif CONDUCTION and deferred != 0.0:
                node_pass(cur, nxt, p, topology, nodes, scratch,
                          KickDrift(deferred * h, k2 * h, table.drift[r] * h, True), np.int64(FORCE_DEFERRED), False,
                          (heat.s_before, loads))
                if LOADS:
                    cpu_load_work(cur, heat.s_before, topology, nodes, loads, 0.0, deferred * h)
                deferred = 0.0
            else:
                node_pass(cur, nxt, p, topology, nodes, scratch, steps, np.int64(FORCE_GATHER), False,
                          (heat.s_before, loads))
            if LOADS and with_force:
                cpu_load_work(cur, scratch.s, topology, nodes, loads, k1 * h, k2 * h)
            cur, nxt = nxt, cur
            swaps += 1
            if LOADS and table.drift[r] != 0.0:
                cpu_evaluate_loads(loads, stage_time(loads, h, step, loads.drift_time[r]))
                cpu_drive_positions(cur, loads)
        pending = carry
    if CONDUCTION and (run.cycle_step + n_steps) % every == 0:
        # the call ends a cycle: its reverse half sweep, after the pending closing kick's spring
        # pass; the kick itself after the sweep (the spring sums then from the swept η)
        if pending == 0.0 and not theta_valid:
            temperature_pass(cur, eta, topology, springs, scratch.theta_keep, heat.length)
        bad = conduction_boundary(state, cur, topology, springs, scratch, heat, run, pending, REVERSE | SAVE, n_steps)
        if bad > 0:
            return _stopped(x, x_buf, swaps, heat, n_steps - 1)
        if pending != 0.0:
            deferred = pending
            if LOADS:
                deferred_time = stage_time(loads, h, n_steps, 0.0)
            pending = 0.0
        theta_valid = True
        ended_cycle = True
    summed = False
    if CONDUCTION and deferred != 0.0:  # drift 0: the positions stay; a cycle's end: the call's closing kick
        _deferred_kick(cur, nxt, p, topology, nodes, scratch, heat, loads, (deferred * h, deferred_time),
                       ended_cycle and run.want_sums)
        if ended_cycle and run.want_sums:
            store_sums(scratch.sums, state_spring_sums(cur, eta, topology, springs, scratch.energy_buf,
                                                       heat.theta_start))
            summed = True
    if pending != 0.0:
        bad, theta_min, theta_max = boundary_spring_pass(cur, eta, phi, topology, springs, scratch,
                                                         (0.0, pending * h), run, True, heat.length,
                                                         heat.strain)
        if bad > 0:
            return _stopped(x, x_buf, swaps, heat, n_steps - 1)
        theta_valid = True  # (the closing spring pass keeps θ and l)
        # drift 0: the positions stay in cur
        if LOADS:
            cpu_evaluate_loads(loads, stage_time(loads, h, n_steps, 0.0))
        boundary_node_pass(cur, nxt, p, topology, nodes, scratch, KickDrift(0.0, pending * h, 0.0, True),
                           np.int64(FORCE_GATHER_KEEP), run.want_sums, (heat.s_before, loads))
        if LOADS:
            cpu_load_work(cur, scratch.s, topology, nodes, loads, 0.0, pending * h)
        if run.want_sums:
            store_sums(scratch.sums, (theta_min, theta_max))
            summed = True
    if CONDUCTION:
        if theta_valid:
            _copy_values(scratch.theta_keep, heat.theta)
        heat.theta_ok[0] = (2.0 if ended_cycle else 1.0) if theta_valid else 0.0
    if swaps % 2 == 1:
        copy_rows(x_buf, x)
    return n_steps, False, summed
