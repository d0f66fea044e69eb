"""The passes of a conducting step over processes, compiled around the CPU kernel's own.

:mod:`thermonet.parallel.conduction` drives a call of the explicit step with conduction as the
CPU kernel's ``advance`` does (:mod:`thermonet.explicit.cpu`), between messages. These small
functions call that kernel variant's passes with the argument expressions its ``advance`` uses
(literal flags included), so the passes come from the disk cache a run of one process filled.
"""

from __future__ import annotations

import numpy as np
from numba import prange

from ..explicit.codes import FORCE_DEFERRED, FORCE_GATHER, FORCE_GATHER_KEEP
from ..kernels.records import KickDrift
from ..kernels.specialize import function_fingerprint, specialize

# bound per kernel variant by heat_stage_functions() (a conducting variant's passes)
spring_pass = node_pass = boundary_spring_pass = boundary_node_pass = refresh_pass = None

_OPTIONS = dict(cache=True, error_model="numpy", boundscheck=False, _nrt=False)
_CACHE: dict = {}
_NAMES = ("spring_pass", "node_pass", "boundary_spring_pass", "boundary_node_pass", "refresh_pass")


def _forces(cur, state, topology, springs, scratch, kept, kicks, run, keep, refresh):
    """A kick's spring pass at cur: from the kept θ and lengths after a sweep (``refresh``: no
    θ(l, η), as the kernel's refresh pass) or from the positions (keeping θ, l and the strain
    when ``keep``: a kick not followed by a drift). kept: (lengths, strains (m,), whether the
    strains are those of the lengths); kicks: (k1 h, k2 h) of Φ. Returns the inadmissible
    springs."""
    length, strain, strain_ok = kept
    if refresh:
        return refresh_pass(scratch.theta_keep, length, strain, strain_ok, state.phi, springs, scratch.s,
                            (kicks[0], kicks[1]), run)
    return spring_pass(cur, state.eta, state.phi, topology, springs, scratch, (kicks[0], kicks[1]), run, keep,
                       length, strain)[0]


def _before_sweep(cur, state, topology, springs, before, kept, pending, run):
    """The spring pass of a closing kick left pending at a conduction boundary (its T/l into
    before.s, the kick deferred past the sweep; θ, l and the strain kept into kept = (lengths,
    strains)). Returns the inadmissible springs."""
    return spring_pass(cur, state.eta, state.phi, topology, springs, before, (0.0, pending * run.h), run, True,
                       kept[0], kept[1])[0]


def _kick_drift(cur, nxt, state, topology, nodes, scratch, steps, s_before, loads, deferred, kick, drift, h):
    """A stage's node pass into nxt: with the forces of s, or (``deferred`` ≠ 0) first the kick
    deferred past the sweep with those of s_before, then this stage's kick of s."""
    if deferred != 0.0:
        node_pass(cur, nxt, state.p, topology, nodes, scratch, KickDrift(deferred * h, kick * h, drift * h, True),
                  np.int64(FORCE_DEFERRED), False, (s_before, loads))
    else:
        node_pass(cur, nxt, state.p, topology, nodes, scratch, steps, np.int64(FORCE_GATHER), False, (s_before, loads))


def _deferred_alone(cur, nxt, state, topology, nodes, scratch, s_before, loads, tau):
    """The kick deferred past a call's last sweep, by itself (drift 0: the positions stay in cur)."""
    node_pass(cur, nxt, state.p, topology, nodes, scratch, KickDrift(tau, 0.0, 0.0, True), np.int64(FORCE_DEFERRED),
              False, (s_before, loads))


def _closing(cur, nxt, state, topology, springs, nodes, scratch, kept, s_before, loads, pending, run):
    """A call's closing kick of ``pending`` (a fraction of h) at cur, drift 0, keeping θ, l and
    the strain (kept = (lengths, strains)). Returns the inadmissible springs."""
    h = run.h
    bad = boundary_spring_pass(cur, state.eta, state.phi, topology, springs, scratch, (0.0, pending * h), run, True,
                               kept[0], kept[1])[0]
    if bad > 0:
        return bad
    boundary_node_pass(cur, nxt, state.p, topology, nodes, scratch, KickDrift(0.0, pending * h, 0.0, True),
                       np.int64(FORCE_GATHER_KEEP), run.want_sums, (s_before, loads))
    return 0


def heat_stage_functions(namespace: dict, variant: str):
    """(forces, before_sweep, kick_drift, deferred_alone, closing) compiled around the passes of
    ``namespace`` (a conducting CPU kernel variant's); variant: a name unique to it."""
    if variant not in _CACHE:
        ns = {k: namespace[k] for k in _NAMES}
        tag = f"{variant}_{function_fingerprint(*(ns[k].py_func for k in _NAMES))}"
        _CACHE[variant] = tuple(specialize(f, tag, ns, **_OPTIONS)
                                for f in (_forces, _before_sweep, _kick_drift, _deferred_alone, _closing))
    return _CACHE[variant]


# ------------------------------------------------------------------------------------------------
# the phases of a conduction sweep divided among the processes (thermonet.parallel.sweep)
star_block = boundary_exchange = finish_spring = None  # bound per variant
_PHASE_NAMES = ("star_block", "boundary_exchange", "finish_spring")


def _colour_phase(heat, theta, colour, reverse):
    """The blocks of one colour (heat: a process's part of the sweep, local indices), each block's
    nodes last to first when ``reverse``: :func:`thermonet.heat.passes._conduction_sweep`'s loop."""
    ptr = heat.star_colour_ptr
    for b in prange(ptr[colour], ptr[colour + 1]):
        star_block(b, heat, reverse, theta)


def _boundary_phase(heat, theta, tau, t, reverse):
    """The baths and sources of the process's boundary springs over τ at time t."""
    logs = (heat.produced, heat.entry_heat, heat.entry_flux)
    for j in prange(heat.bound_spring.shape[0]):
        boundary_exchange(j, heat, tau, t, reverse, theta, logs)


def _finish(theta, theta_start, eta, capacity, produced, m):
    """Each of the first m springs' entropy update after the sweep (:func:`finish_spring`)."""
    for e in prange(m):
        finish_spring(e, theta, theta_start, eta, capacity, produced)


def sweep_phase_functions(namespace: dict, variant: str, parallel: bool):
    """(colour_phase, boundary_phase, finish) compiled around a conducting variant's exchange
    functions (:mod:`thermonet.heat.exchange`); variant: a name unique to it."""
    key = (variant, "phases")
    if key not in _CACHE:
        ns = {k: namespace[k] for k in _PHASE_NAMES}
        tag = f"{variant}_{function_fingerprint(*(ns[k].py_func for k in _PHASE_NAMES))}"
        _CACHE[key] = tuple(specialize(f, tag, ns, parallel=parallel, **_OPTIONS)
                            for f in (_colour_phase, _boundary_phase, _finish))
    return _CACHE[key]
