"""Per-spring fields (length, temperature, tension, internal energy) for diagnostics and output,
an output frame's spring fields written straight into the user's numbering, and element-wise
maps of one model function. Run at the diagnostics and output cadences, outside the loop."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from .fastmath import log
from . import subflows
from .subflows import bind_subflows
from .blocks import BLOCK, squared_lengths
from .specialize import MODEL_FUNCTIONS, kernel_namespace, model_fingerprint, specialize

# Bound per model by specialize(); THERMAL False: every spring at its reference temperature
# (parameter row REFERENCE_TEMPERATURE) and "energy" is the free energy F(l, θ0).
tension = scalar = spring_temperature = spring_energy = None
THERMAL = True
REFERENCE_TEMPERATURE = 0

_CACHE: dict = {}
_OPTIONS = dict(cache=True, error_model="numpy")


def spring_field_kernel(model, thermal: bool = True, parallel: bool = False):
    """``spring_fields(x, eta, l0, P, edges, length, theta, tension, energy)`` for ``model``:
    fills the four (m,) output arrays from positions x (n, 3) and entropies eta (m,)
    (eta unused and may be empty when not ``thermal``); multi-threaded when ``parallel``."""
    return _spring_pass(_spring_fields, model, thermal, parallel)


class FrameFields(NamedTuple):
    """The spring fields a frame pass writes, each (m,) in the user's numbering, or (0,) for a
    field not wanted (the names of :data:`thermonet.output_fields.SPRING_FIELDS`)."""

    temperature: np.ndarray
    tension: np.ndarray
    strain: np.ndarray
    entropy: np.ndarray
    thermal_displacement: np.ndarray


def frame_spring_kernel(model, thermal: bool = True, parallel: bool = False):
    """``frame_springs(x, eta, phi, springs, edges, order, scratch, fields, theta_internal)`` for
    ``model``: one blocked pass that computes each spring's length, temperature, tension and
    strain (:func:`log_strain`) from positions x (n, 3) and entropies eta (m,), and writes them,
    with eta and the thermal displacement phi (m,), to user spring ``order[e]`` of the output
    arrays of ``fields`` (a :class:`FrameFields`; each (m,), or (0,) for a field not wanted).
    springs: a :class:`~thermonet.kernels.records.Springs` (rest lengths, parameters). theta_internal: (m,) the temperatures in the internal numbering too, or (0,).
    scratch: (4, m) float64. edges: (m, 2) uint32; order: (m,) int64. Values equal
    :func:`spring_field_kernel`'s (and :func:`log_strain`'s) bit for bit: the same operations."""
    return _spring_pass(_frame_springs, model, thermal, parallel)


def _spring_pass(template, model, thermal: bool, parallel: bool):
    """``template`` compiled for ``model``, thermal coupling on or off, threaded or not (cached)."""
    key = (template.__name__, model_fingerprint(model), bool(thermal), bool(parallel))
    if key not in _CACHE:
        ns = kernel_namespace(model, thermal)
        tag = (f"{model.name}_{key[1]}_{'thermal' if thermal else 'mech'}_{'par' if parallel else 'ser'}"
               f"_s{subflows.source_digest()}")
        bind_subflows(ns, tag, njit(inline="always", error_model="numpy", boundscheck=False))
        _CACHE[key] = specialize(template, tag, ns, parallel=bool(parallel), **_OPTIONS)
    return _CACHE[key]


def log_strain(lengths: np.ndarray, rest_lengths: np.ndarray) -> np.ndarray:
    """(m,) logarithmic strains ln(l / l0), with the same log as an output frame's (thermonet's
    vectorizable log, within about an ulp of NumPy's), so that the two agree bit for bit."""
    key = ("log_strain",)
    if key not in _CACHE:
        _CACHE[key] = specialize(_log_strain, "any", {}, **_OPTIONS)
    lengths = np.ascontiguousarray(lengths, dtype=np.float64)
    out = np.empty_like(lengths)
    _CACHE[key](lengths, np.ascontiguousarray(rest_lengths, dtype=np.float64), out)
    return out


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
            eta_e = eta[e] if THERMAL else 0.0
            th = spring_temperature(l, eta_e, l0[e], P, e)
            energy[e] = spring_energy(l, eta_e, th, l0[e], P, e)
            theta[e] = th
            tens[e] = tension(l, th, l0[e], P, e)


def _mapped(l, s, l0, P, out):
    for e in range(l.shape[0]):
        out[e] = scalar(l[e], s[e], l0[e], P, e)


def _frame_springs(x, eta, phi, springs, edges, order, scratch, fields, theta_internal):
    """See :func:`frame_spring_kernel`. Blocked like :func:`_spring_fields`: per block the gather
    (squared lengths), the arithmetic over contiguous scratch rows (which vectorizes), then one
    loop scattering every wanted field to its user position."""
    l0, P = springs.rest, springs.P
    theta, tens, strain = fields.temperature, fields.tension, fields.strain
    entropy, thermal_displacement = fields.entropy, fields.thermal_displacement
    m = edges.shape[0]
    with_theta = theta.shape[0] > 0
    with_tension = tens.shape[0] > 0
    with_strain = strain.shape[0] > 0
    with_entropy = entropy.shape[0] > 0
    with_phi = thermal_displacement.shape[0] > 0
    with_internal = theta_internal.shape[0] > 0
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        n = min(BLOCK, m - lo)
        squared_lengths(x, edges, lo, n, scratch[0], lo)
        for i in range(n):
            e = np.uint64(lo + i)
            l = math.sqrt(scratch[0, e])
            th = spring_temperature(l, eta[e] if THERMAL else 0.0, l0[e], P, e)
            scratch[1, e] = th
            scratch[2, e] = tension(l, th, l0[e], P, e)
            if with_strain:
                scratch[3, e] = log(l / l0[e])
        for i in range(n):
            e = np.uint64(lo + i)
            u = order[e]
            if with_theta:
                theta[u] = scratch[1, e]
            if with_internal:
                theta_internal[e] = scratch[1, e]
            if with_tension:
                tens[u] = scratch[2, e]
            if with_strain:
                strain[u] = scratch[3, e]
            if with_entropy:
                entropy[u] = eta[e]
            if with_phi:
                thermal_displacement[u] = phi[e]


def _log_strain(l, l0, out):
    for e in range(l.shape[0]):
        out[e] = log(l[e] / l0[e])
