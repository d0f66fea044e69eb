"""The heat-flow sub-flows, one definition each, for every target (spec-heat §1–2).

Like :mod:`thermonet.kernels.subflows`, plain Python that each target compiles (``njit`` inline
on the CPU, device functions for CUDA). A conduction sweep works on the springs' temperatures
θ (m,) at the current positions; its exchanges are linear in θ and need no logarithm:

- :func:`pair_exchange`: springs e and f alone exchange heat for the sweep's time τ, exactly:
  ``Q = c_r (1 − exp(−κ τ / c_r)) (θ_f − θ_e)``, ``c_r = C_e C_f / (C_e + C_f)`` (the factor is
  precomputed per pair for the run's τ, divided by each spring's C). ``U_e + U_f`` is unchanged; the pair's entropy rises
  (``C_e ln(θ_e'/θ_e) + C_f ln(θ_f'/θ_f) ≥ 0``: Q never passes the common temperature).
- :func:`boundary_exchange`: the baths and sources of one spring, in order (reversed in the
  second half step): a bath end ``θ ← θ_b + (θ − θ_b) exp(−g τ / C)``, a source
  ``θ ← θ + P τ / C``; each entry logs the heat it gave and the entropy it brought (Q/θ_b for a
  bath; C ln(θ'/θ) for a source).
- :func:`finish_spring`: after a half step's sweep, ``η += C ln(θ'/θ)`` per spring (one
  logarithm per spring, exact for the constant heat capacities of both shipped models); the
  entropy produced is that change less what the entries brought, and sums over the net to the
  pairs' and bath ends' productions.
- :func:`wave_exchange`: the Green–Naghdi type II flow of one pair at fixed Φ:
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

BATH = 0
SOURCE = 1


def pair_exchange(k, first, second, gain, theta):
    """Exact heat exchange of pair k (springs first[k], second[k]) over the sweep's τ, in θ;
    gain: (2, P), the pair's factor over C_first and over C_second."""
    # unsigned indices: no negative-index wraparound in the loop (the sweep runs 2× faster)
    i = np.uint64(k)
    e = np.uint32(first[i])
    f = np.uint32(second[i])
    difference = theta[f] - theta[e]
    theta[e] += gain[0, i] * difference
    theta[f] -= gain[1, i] * difference


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
            te_new = value + (te - value) * math.exp(-heat.entry_rate[q] * tau)
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
    """After the sweeps of a half step: spring e's entropy follows its temperature at fixed
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


#: the functions above, in the order a kernel factory binds them
SHARED = ("pair_exchange", "boundary_exchange", "finish_spring", "wave_exchange")


def source_digest() -> str:
    """A short hash of this module's source (part of the kernels' cache names)."""
    return hashlib.sha256(inspect.getsource(sys.modules[__name__]).encode()).hexdigest()[:8]
