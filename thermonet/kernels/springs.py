"""Per-spring fields (length, temperature, tension, internal energy) for diagnostics and output,
and element-wise maps of one model function. Run at the diagnostics cadence, outside the loop."""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from .splitting import BLOCK, squared_lengths
from .specialize import MODEL_FUNCTIONS, model_fingerprint, model_namespace, specialize

# Bound per model by specialize(); THERMAL False: every spring at its reference temperature
# (parameter row REFERENCE_TEMPERATURE) and "energy" is the free energy F(l, θ0).
temperature = tension = internal_energy = free_energy = scalar = None
THERMAL = True
REFERENCE_TEMPERATURE = 0

_CACHE: dict = {}
_OPTIONS = dict(cache=True, error_model="numpy")


def spring_field_kernel(model, thermal: bool = True, parallel: bool = False):
    """``spring_fields(x, eta, l0, P, edges, length, theta, tension, energy)`` for ``model``:
    fills the four (m,) output arrays from positions x (n, 3) and entropies eta (m,)
    (eta unused and may be empty when not ``thermal``); multi-threaded when ``parallel``."""
    key = ("fields", model_fingerprint(model), bool(thermal), bool(parallel))
    if key not in _CACHE:
        ns = model_namespace(model)
        ns["THERMAL"] = bool(thermal)
        ns["REFERENCE_TEMPERATURE"] = model.parameter_index(model.reference_temperature)
        tag = f"{model.name}_{key[1]}_{'thermal' if thermal else 'mech'}_{'par' if parallel else 'ser'}"
        _CACHE[key] = specialize(_spring_fields, tag, ns, parallel=bool(parallel), **_OPTIONS)
    return _CACHE[key]


def map_springs(model, function: str):
    """A compiled loop ``f(l, s, l0, P, out)`` applying ``model.<function>`` to every spring:
    l, s, l0, out are (m,) arrays (s is θ or η, as the function expects), P is (k, m)."""
    if function not in MODEL_FUNCTIONS:
        raise ValueError(f"not a model function: {function}")
    key = (function, model_fingerprint(model))
    if key not in _CACHE:
        ns = {"scalar": getattr(model, function)}
        _CACHE[key] = specialize(_mapped, f"{model.name}_{function}_{key[1]}", ns, **_OPTIONS)
    return _CACHE[key]


def _spring_fields(x, eta, l0, P, edges, length, theta, tens, energy):
    """Blocked like the stepping kernel's spring pass: gather squared lengths into ``length``,
    then a loop over contiguous arrays (which vectorizes) for l, θ, T and U. edges: (m, 2) uint32."""
    m = edges.shape[0]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        n = min(BLOCK, m - lo)
        squared_lengths(x, edges, lo, n, length, lo)
        for i in range(n):
            e = np.uint64(lo + i)
            l = math.sqrt(length[e])
            length[e] = l
            if THERMAL:
                th = temperature(l, eta[e], l0[e], P, e)
                energy[e] = internal_energy(l, eta[e], l0[e], P, e)
            else:
                th = P[REFERENCE_TEMPERATURE, e]
                energy[e] = free_energy(l, th, l0[e], P, e)
            theta[e] = th
            tens[e] = tension(l, th, l0[e], P, e)


def _mapped(l, s, l0, P, out):
    for e in range(l.shape[0]):
        out[e] = scalar(l[e], s[e], l0[e], P, e)
