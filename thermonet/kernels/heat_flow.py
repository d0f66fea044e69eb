"""The heat-flow sub-flows, one definition each, for every target (spec-heat §1–2).

Like :mod:`thermonet.kernels.subflows`, plain Python that each target compiles (``njit`` inline
on the CPU, device functions for CUDA). They work on a working array ``theta`` (m,) of spring
temperatures, kept equal to θ(l, η) at the current positions: a conduction exchange updates both
θ and η (``η += C ln(θ'/θ)``, exact for the constant heat capacities of both shipped models), so
consecutive conduction sweeps need no temperature pass in between.

- :func:`pair_exchange`: springs e and f alone exchange heat for the sweep's time τ, exactly:
  ``Q = c_r (1 − exp(−κ τ / c_r)) (θ_f − θ_e)``, ``c_r = C_e C_f / (C_e + C_f)`` (the factor is
  precomputed per pair for the run's τ). ``U_e + U_f`` is unchanged; the pair's entropy rises by
  ``C_e ln(θ_e'/θ_e) + C_f ln(θ_f'/θ_f) ≥ 0``, added to the first spring's production log.
- :func:`boundary_exchange`: the baths and sources of one spring, in order (reversed in the
  second half step): a bath end ``θ ← θ_b + (θ − θ_b) exp(−g τ / C)``, a source
  ``θ ← θ + P τ / C``; each entry logs the heat it gave and the entropy it brought (Q/θ_b for a
  bath; C ln(θ'/θ) for a source), a bath's production (C ln(θ'/θ) − Q/θ_b ≥ 0) goes to the
  spring's log.
- :func:`wave_exchange`: the Green–Naghdi type II flow of one pair at fixed Φ:
  ``J = τ k* (Φ_e − Φ_f)``, ``η_e −= J``, ``η_f += J`` (total entropy exact).
"""

from __future__ import annotations

import hashlib
import inspect
import math
import sys

# Bound per kernel by the factories (a time function's value at t, see thermonet.timefunctions).
evaluate = None

BATH = 0
SOURCE = 1


def pair_exchange(k, first, second, factor, capacity, inv_capacity, theta, eta, produced):
    """Exact heat exchange of pair k (springs first[k], second[k]) over the sweep's τ."""
    e = first[k]
    f = second[k]
    te = theta[e]
    tf = theta[f]
    q = factor[k] * (tf - te)
    te_new = te + q * inv_capacity[e]
    tf_new = tf - q * inv_capacity[f]
    de = capacity[e] * math.log(te_new / te)
    df = capacity[f] * math.log(tf_new / tf)
    theta[e] = te_new
    theta[f] = tf_new
    eta[e] += de
    eta[f] += df
    produced[e] += de + df


def boundary_exchange(j, heat, tau, t, reverse, theta, eta, logs):
    """The bath and source entries of boundary spring j (heat.bound_spring[j]), in order, or in
    reverse order when ``reverse``, over τ at time t. logs: (produced, entry_heat, entry_flux),
    the record's arrays passed on their own (a parallel loop must not write through the record)."""
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
            ds = c * math.log(te_new / te)
            flux = heat_in / value
            produced[e] += ds - flux
        else:
            heat_in = value * tau
            te_new = te + heat_in * heat.inv_capacity[e]
            ds = c * math.log(te_new / te)
            flux = ds
        entry_heat[q] += heat_in
        entry_flux[q] += flux
        theta[e] = te_new
        eta[e] += ds


def wave_exchange(k, first, second, wave, tau, phi, eta):
    """Green–Naghdi exchange of pair k over τ at fixed Φ."""
    e = first[k]
    f = second[k]
    flow = tau * wave[k] * (phi[e] - phi[f])
    eta[e] -= flow
    eta[f] += flow


#: the functions above, in the order a kernel factory binds them
SHARED = ("pair_exchange", "boundary_exchange", "wave_exchange")


def source_digest() -> str:
    """A short hash of this module's source (part of the kernels' cache names)."""
    return hashlib.sha256(inspect.getsource(sys.modules[__name__]).encode()).hexdigest()[:8]
