"""What a run that left the admissible states did wrong, in words, for the error message.

The explicit kernel only counts springs outside the admissible states (it must stay cheap);
when it stops, this module finds the first such spring (user numbering) at the positions where
it was found and names the quantity: a non-finite position, a stretch l/l0 beyond the bounds, a
temperature θ ≤ 0, or a non-finite tension; :func:`blowup_failure` wraps that as the
:class:`~thermonet.integrators.base.StepFailure` the CPU and CUDA steppers raise.
"""

from __future__ import annotations

import math

import numpy as np

from .integrators.base import StepFailure
from .kernels.springs import map_springs
from .stability import stability_interval

#: default admissible stretches l/l0 of the blow-up detector (open interval)
STRETCH_BOUNDS = (1e-4, 1e4)

#: what the messages recommend for steps above a stability limit: the integrator without one
UNLIMITED = "em2"


def remedy(integrator, h: float) -> str:
    """What helps a run of ``integrator`` with step ``h`` that blew up or went above its stability
    limit, in words: a smaller h, and, for an integrator with a stability limit (the explicit
    ones, and GTR-1/2 and HO4, whose limits are hω < 2 and 2√2), EM2, which has none (energy is
    exact at any step; the fast modes lose accuracy, not stability). For EM2 itself: a smaller h
    (its failures are Newton's) or retries as substeps."""
    smaller = f"a smaller h than {h:g} (`thermonet info` estimates the stable step)"
    if getattr(integrator, "unconditionally_stable", False):
        return (f"Try a smaller h than {h:g}, or let {integrator.name} retry failed steps as substeps "
                f"(integrator option retry)")
    limited = "" if integrator.explicit else f" ({integrator.name} has a stability limit too)"
    if not math.isfinite(stability_interval(integrator)):
        return f"Try {smaller}"
    return (f"Try {smaller}, or, for steps above the stability limit{limited}, the integrator {UNLIMITED}, "
            f"which has none (energy exact at any step; fast modes lose accuracy, not stability)")


def diagnose(system, positions: np.ndarray, entropy: np.ndarray | None) -> dict:
    """The first inadmissible spring (user numbering) at ``positions`` (n, 3), internal numbering.

    Returns a dict with ``spring``, ``nodes`` (user numbering) and ``problem`` (a phrase), or an
    empty dict when every spring is admissible.
    """
    lay = system.layout
    edges = system.edges
    d = positions[edges[:, 1]] - positions[edges[:, 0]]
    with np.errstate(all="ignore"):
        length = np.sqrt(np.einsum("ij,ij->i", d, d))
        l0, P = system.rest_lengths, system.parameters
        stretch = length / l0
        m = system.n_springs
        theta = np.empty(m)
        if system.thermal:
            map_springs(system.model, "temperature")(length, entropy, l0, P, theta)
        else:
            theta[:] = P[system.model.parameter_index(system.model.reference_temperature)]
        tension = np.empty(m)
        map_springs(system.model, "tension")(length, theta, l0, P, tension)
    lo, hi = system.stretch_bounds
    checks = [
        (~np.isfinite(length), lambda e: "a non-finite length (a node's position or momentum is not finite)"),
        (stretch <= lo, lambda e: f"stretch l/l0 = {stretch[e]:.3g} at or below the bound {lo:g} (collapsing)"),
        (stretch >= hi, lambda e: f"stretch l/l0 = {stretch[e]:.3g} at or above the bound {hi:g}"),
    ]
    if system.thermal:
        checks.append((~(theta > 0), lambda e: f"temperature θ = {theta[e]:.6g}, not > 0"))
    checks.append((~np.isfinite(tension / length), lambda e: f"a non-finite tension ({tension[e]:.6g})"))
    for mask, phrase in checks:
        if mask.any():
            internal = np.flatnonzero(mask)
            user = lay.spring_order[internal]
            k = int(np.argmin(user))
            e = int(internal[k])
            nodes = [int(lay.node_order[a]) for a in edges[e]]
            return {"spring": int(user[k]), "nodes": nodes, "problem": phrase(e)}
    return {}


def blowup_failure(system, positions, entropy, steps_done: int) -> StepFailure:
    """The :class:`StepFailure` of a kernel that stopped on an inadmissible spring at
    ``positions`` (internal numbering), naming the spring: the caller rewinds and replays
    ``steps_done`` steps."""
    found = diagnose(system, positions, entropy)
    where = (f"spring {found['spring']} (nodes {found['nodes'][0]}–{found['nodes'][1]}) has {found['problem']}"
             if found else "a spring left the admissible states")
    return StepFailure(where, steps_done=int(steps_done), details={"rewind": True, **found})
