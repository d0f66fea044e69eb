"""The small passes of the explicit schedule (templates specialized per kernel variant by
:func:`thermonet.explicit.cpu.splitting_kernels`, which binds ``flow_pass_*``, ``update`` and
``copy_rows``): the thermal half of a kick, the extra sub-flows' passes, a diagnostics row's sums,
and the kernel's way out when a spring left the admissible states."""

from __future__ import annotations

from numba import njit, prange

flow_pass_0 = flow_pass_1 = flow_pass_2 = flow_pass_3 = update = copy_rows = None
CONDUCTION = False


def _thermal_kick(phi, theta, coefficient):
    """Φ += coefficient θ, per spring (the thermal half of a kick whose θ is known)."""
    for e in prange(phi.shape[0]):
        phi[e] += coefficient * theta[e]


def _flow_pass(data, tau, t, x, p, phi, eta):
    """One extra sub-flow over tau at time t: ``update(i, data, tau, t, x, p, phi, eta)`` for
    every element i of range(len(data[0])), in parallel."""
    for i in prange(data[0].shape[0]):
        update(i, data, tau, t, x, p, phi, eta)


@njit(inline="always")
def _no_flow(data, tau, t, x, p, phi, eta):
    """An empty flow slot."""
    return None


def _apply_flow(slot, effects, tau, t, x, p, phi, eta):
    """Run the sub-flow in ``slot`` with its data ``effects[slot]`` (effects: a 4-tuple of data
    tuples, one per slot)."""
    if slot == 0:
        flow_pass_0(effects[0], tau, t, x, p, phi, eta)
    elif slot == 1:
        flow_pass_1(effects[1], tau, t, x, p, phi, eta)
    elif slot == 2:
        flow_pass_2(effects[2], tau, t, x, p, phi, eta)
    else:
        flow_pass_3(effects[3], tau, t, x, p, phi, eta)


@njit(inline="always", error_model="numpy", boundscheck=False)
def store_sums(sums, theta_range):
    """A diagnostics row's temperature range (min θ, max θ) into sums (2,) (its sums are exact:
    the springs' energies in scratch.energy_buf, the node sums in scratch.node_accs)."""
    sums[0] = theta_range[0]
    sums[1] = theta_range[1]


def _stopped(x, x_buf, swaps, heat, steps_done):
    """What ``advance`` returns when a spring left the admissible states: the positions where it
    was found back in x, the heat sweeps' saved temperatures no longer valid."""
    if swaps % 2 == 1:
        copy_rows(x_buf, x)
    if CONDUCTION:
        heat.theta_ok[0] = 0.0
    return steps_done, True, False
