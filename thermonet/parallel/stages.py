"""A stage and a closing kick of the distributed step, compiled around the CPU kernel's passes.

They call the passes exactly as the kernel's ``advance`` does (the same argument types, literal
flags included), so the passes' compiled code comes from the disk cache that a run of one process
filled: the processes of a run then compile only these two small functions (once; cached too).
"""

from __future__ import annotations

import numpy as np

from ..explicit.codes import FORCE_GATHER, FORCE_GATHER_KEEP
from ..explicit.passes import store_sums
from ..kernels.records import KickDrift
from ..kernels.specialize import function_fingerprint, specialize

# bound per kernel variant by stage_functions(), as in thermonet.explicit.cpu
spring_pass = node_pass = boundary_spring_pass = boundary_node_pass = None

_OPTIONS = dict(cache=True, error_model="numpy", boundscheck=False, _nrt=False)
_CACHE: dict = {}


def _stage(cur, nxt, state, topology, springs, nodes, scratch, steps, run, extra):
    """One stage row: the spring pass at cur (kicks steps.kick1, steps.kick2 of Φ) unless
    steps.with_force is False, then, unless a spring left the admissible states, the node pass
    (kicks, drift) into nxt. steps: KickDrift; state: StateArrays (p, Φ, η read); extra: (length,
    (s_before, loads)) (a variant without conduction: length, also passed as the strains, is
    not written). Returns the number of inadmissible springs."""
    if steps.with_force:
        bad = spring_pass(cur, state.eta, state.phi, topology, springs, scratch, (steps.kick1, steps.kick2), run,
                          False, extra[0], extra[0])[0]
        if bad > 0:
            return bad
    node_pass(cur, nxt, state.p, topology, nodes, scratch, steps, np.int64(FORCE_GATHER), False, extra[1])
    return 0


def _closing(cur, nxt, state, topology, springs, nodes, scratch, kick, run, extra):
    """A call's closing kick of ``kick`` (a fraction of h times h) at cur, drift 0, keeping its
    forces and temperatures as the CPU kernel's does (with ``run.want_sums``, the θ range of the
    share's springs into scratch.sums). Returns the number of inadmissible springs."""
    bad, theta_min, theta_max = boundary_spring_pass(cur, state.eta, state.phi, topology, springs, scratch,
                                                     (0.0, kick), run, True, extra[0], extra[0])
    if bad > 0:
        return bad
    if run.want_sums:
        store_sums(scratch.sums, (theta_min, theta_max))
    boundary_node_pass(cur, nxt, state.p, topology, nodes, scratch, KickDrift(0.0, kick, 0.0, True),
                       np.int64(FORCE_GATHER_KEEP), run.want_sums, extra[1])
    return 0


def stage_functions(namespace: dict, variant: str):
    """(stage, closing) compiled around the passes of ``namespace`` (a CPU kernel variant's,
    :func:`thermonet.parallel.stepper.splitting_passes`); variant: a name unique to it."""
    if variant not in _CACHE:
        passes = [namespace[k] for k in ("spring_pass", "node_pass", "boundary_spring_pass", "boundary_node_pass")]
        tag = f"{variant}_{function_fingerprint(*(p.py_func for p in passes))}"
        ns = dict(zip(("spring_pass", "node_pass", "boundary_spring_pass", "boundary_node_pass"), passes))
        _CACHE[variant] = (specialize(_stage, tag, ns, **_OPTIONS), specialize(_closing, tag, ns, **_OPTIONS))
    return _CACHE[variant]
