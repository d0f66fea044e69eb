"""The heat-flow sub-flows, one definition each, for every target (the CPU passes of
:mod:`thermonet.heat.passes`, the CUDA phases of :mod:`thermonet.heat.cuda`).

Like :mod:`thermonet.kernels.subflows`, plain Python that each target compiles (``njit`` inline
on the CPU, device functions for CUDA). A conduction sweep works on the springs' temperatures
θ (m,) at the current positions; its exchanges are linear in θ and need no logarithm:

- :func:`star_block`: the node-star exchanges of one block of junction nodes, node after node
  (in reverse order for the second half of a symmetric step). At junction i every spring e
  relaxes exactly toward the junction's temperature J, at its own rate g_e/C_e:
  ``θ_e ← J + (θ_e − J) exp(−g_e τ / C_e)``, with ``J = Σ a θ / Σ a``,
  ``a_e = C_e (1 − exp(−g_e τ / C_e))`` — the J that keeps ``Σ C θ`` at the node. The new θ are
  a mix of the old with non-negative weights, rows summing to one and ``Σ_e C_e A_ef = C_f``: the
  node's internal energy is unchanged and its entropy ``Σ C ln θ`` cannot fall (Jensen), at any
  τ. It is the exact flow of the node's junction system ``C_e θ̇_e = g_e (J − θ_e)`` when the
  rates g/C at the node are equal, and second order (local error O(τ³)) otherwise.
- :func:`boundary_exchange`: the baths and sources of one spring, in order (reversed in the
  second half step): a bath end ``θ ← θ_b + (θ − θ_b) exp(−g τ / C)`` (the same exchange with J
  imposed), a source ``θ ← θ + P τ / C``; each entry logs the heat it gave and the entropy it
  brought (Q/θ_b for a bath; C ln(θ'/θ) for a source).
- :func:`finish_spring`: after the sweeps at a step boundary, ``η += C ln(θ'/θ)`` per spring (one
  logarithm per spring, exact for the constant heat capacities of both shipped models); the
  entropy produced is that change less what the entries brought.
- :func:`wave_exchange`: the Green–Naghdi type II flow of one spring pair at fixed Φ:
  ``J = τ k* (Φ_e − Φ_f)``, ``η_e −= J``, ``η_f += J`` (total entropy exact).
"""

from __future__ import annotations

import hashlib
import inspect
import math
import sys

import numpy as np

# Bound per kernel by the factories (a time function's value at t, see thermonet.timefunctions;
# log: the CPU binds thermonet.kernels.fastmath's, which vectorizes).
evaluate = None
log = math.log

#: kinds of boundary entries
BATH = 0
SOURCE = 1


def star_node(i, heat, theta):
    """The exchange of junction node i over the sweep's τ: its springs relax toward the junction
    temperature that keeps their energy (see the module docstring). heat.weight, heat.decay:
    (2m,) a and exp(−g τ/C) of the spring of each incidence (in inc_spring's order: read in
    sequence) for this τ, or (1,) when every spring has the same (heat.factor_mask[0] then 0:
    every incidence reads element 0, and a sweep reads no factor from memory);
    heat.node_scale: (n,) 1 / Σ a over each node's incidences."""
    lo = heat.inc_ptr[i]
    hi = heat.inc_ptr[i + 1]
    inc_spring = heat.inc_spring
    weight = heat.weight
    mask = heat.factor_mask[0]
    total = 0.0
    if mask == 0:
        # the shared factors held in registers (the same products, the same bits): read through
        # the mask, they would be loaded again after every store to theta, which may alias them
        # (a quarter of the sweep's time on the CPU)
        w = weight[0]
        d = heat.decay[0]
        for j in range(lo, hi):
            total += w * theta[inc_spring[np.uint64(j)]]
        junction = total * heat.node_scale[i]
        for j in range(lo, hi):
            e = inc_spring[np.uint64(j)]
            theta[e] = junction + (theta[e] - junction) * d
        return
    for j in range(lo, hi):
        ju = np.uint64(j)
        total += weight[ju & mask] * theta[inc_spring[ju]]
    junction = total * heat.node_scale[i]
    decay = heat.decay
    for j in range(lo, hi):
        ju = np.uint64(j)
        e = inc_spring[ju]
        theta[e] = junction + (theta[e] - junction) * decay[ju & mask]


def star_block(b, heat, reverse, theta):
    """The nodes of block b (heat.block_node[heat.block_ptr[b]:heat.block_ptr[b + 1]]) one after
    the other, last to first when ``reverse``."""
    lo = heat.block_ptr[b]
    hi = heat.block_ptr[b + 1]
    for k in range(hi - lo):
        q = hi - 1 - k if reverse else lo + k
        star_node(heat.block_node[q], heat, theta)


def boundary_exchange(j, heat, tau, t, reverse, theta, logs):
    """The bath and source entries of boundary spring j (heat.bound_spring[j]), in order, or in
    reverse order when ``reverse``, over τ at time t. logs: (produced, entry_heat, entry_flux),
    the record's arrays passed on their own (a parallel loop must not write through the record).
    The entropy an entry brings is taken off the spring's production here; the sweep's finish
    (:func:`finish_spring`) adds the spring's whole entropy change."""
    produced, entry_heat, entry_flux = logs
    e = heat.bound_spring[j]
    lo = heat.bound_ptr[j]
    hi = heat.bound_ptr[j + 1]
    c = heat.capacity[e]
    for i in range(hi - lo):
        q = hi - 1 - i if reverse else lo + i
        value = evaluate(heat.fn_kind, heat.fn_params, heat.fn_ptr, heat.fn_times, heat.fn_values,
                         heat.entry_fn[q], t)
        te = theta[e]
        if heat.entry_kind[q] == BATH:
            te_new = value + (te - value) * heat.entry_decay[q]  # exp(−g τ / C), made with the record
            heat_in = c * (te_new - te)
            flux = heat_in / value
        else:
            heat_in = value * tau
            te_new = te + heat_in * heat.inv_capacity[e]
            flux = c * math.log(te_new / te)
        entry_heat[q] += heat_in
        entry_flux[q] += flux
        produced[e] -= flux
        theta[e] = te_new


def finish_spring(e, theta, theta_start, eta, capacity, produced):
    """After the sweeps at a step boundary: spring e's entropy follows its temperature at fixed
    length, ``Δη = C ln(θ'/θ)`` (exact for a constant heat capacity), and the change is logged
    as produced (the bath and source entries took off what they brought)."""
    change = capacity[e] * log(theta[e] / theta_start[e])
    eta[e] += change
    produced[e] += change


def wave_exchange(k, first, second, wave, tau, phi, eta):
    """Green–Naghdi exchange of pair k over τ at fixed Φ."""
    i = np.uint64(k)
    e = np.uint32(first[i])
    f = np.uint32(second[i])
    flow = tau * wave[i] * (phi[e] - phi[f])
    eta[e] -= flow
    eta[f] += flow


def reverse_half(half, sweeps):
    """Whether half sweep ``half`` (0 … 2j − 1) of a cycle boundary swept ``sweeps`` = j times runs
    in reverse: they alternate, the first j ending a cycle with a reverse one, the last j starting
    the next with a forward one (j = 1: reverse, forward; j = 2: forward, reverse | forward,
    reverse). Every backend's sweep order follows it."""
    return (half + sweeps) % 2 == 1


#: the functions above, in the order a kernel factory binds them (callees first)
SHARED = ("star_node", "star_block", "boundary_exchange", "finish_spring", "wave_exchange", "reverse_half")


def source_digest() -> str:
    """A short hash of this module's source (part of the kernels' cache names)."""
    return hashlib.sha256(inspect.getsource(sys.modules[__name__]).encode()).hexdigest()[:8]
