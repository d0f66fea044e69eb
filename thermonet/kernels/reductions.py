"""Fused reductions for one diagnostics row: one pass over springs, one over nodes, no
per-spring temporaries. Multi-threaded for large nets (sums then depend on the thread count in
their last bits; the state never does)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from . import subflows
from .subflows import bind_subflows
from .blocks import BLOCK, squared_lengths
from .specialize import kernel_namespace, model_fingerprint, specialize

# Bound per model by specialize(); see thermonet.explicit.cpu for THERMAL / REFERENCE_TEMPERATURE /
# UNIFORM.
spring_temperature = spring_energy = None
THERMAL = True
REFERENCE_TEMPERATURE = 0
UNIFORM = False

_CACHE: dict = {}


@njit(inline="always", error_model="numpy", boundscheck=False)
def node_diagnostic_terms(x0, x1, x2, p0, p1, p2, mass, gravity, ref):
    """One free node's terms of a diagnostics row: kinetic energy, gravity potential −m g·x, p,
    and (x − ref) × p (shared by the fused closing kick and the stand-alone reduction)."""
    r0 = x0 - ref[0]
    r1 = x1 - ref[1]
    r2 = x2 - ref[2]
    return (0.5 * (p0 * p0 + p1 * p1 + p2 * p2) / mass,
            -(mass * (gravity[0] * x0 + gravity[1] * x1 + gravity[2] * x2)),
            r1 * p2 - r2 * p1, r2 * p0 - r0 * p2, r0 * p1 - r1 * p0)


def diagnostic_sums_kernel(model, thermal: bool, parallel: bool, uniform: bool = False):
    """``spring_sums(x, eta, l0, P, edges_uint32) -> (Σ U, θ_min, θ_max)`` and
    ``node_sums(x, p, masses, anchored, ref, gravity) -> (K, V, px, py, pz, Lx, Ly, Lz)``;
    P a shared (k, 1) column when ``uniform`` (as the stepping kernels read it)."""
    key = (model_fingerprint(model), bool(thermal), bool(parallel), bool(uniform))
    if key not in _CACHE:
        ns = kernel_namespace(model, thermal, uniform)
        tag = (f"{model.name}_{key[0]}_{'thermal' if thermal else 'mech'}_{'par' if parallel else 'ser'}"
               f"{'_uniform' if uniform else ''}_s{subflows.source_digest()}")
        bind_subflows(ns, tag, njit(inline="always", error_model="numpy", boundscheck=False))
        opts = dict(cache=True, error_model="numpy", parallel=bool(parallel))
        _CACHE[key] = (specialize(_spring_sums, tag, ns, **opts), specialize(_node_sums, tag, ns, **opts))
    return _CACHE[key]


def _spring_sums(x, eta, l0, P, edges):
    """Σ_e U(l_e, η_e) (Σ F(l_e, θ0) when not THERMAL), min and max of θ_e.

    edges: (m, 2) uint32. Blocked like the stepping kernel's spring pass: gather the squared
    lengths of a block, evaluate θ and U in a loop over contiguous arrays (which vectorizes),
    then sum the block in order (a float sum inside the vectorized loop would keep it scalar).
    """
    m = edges.shape[0]
    energy = 0.0
    theta_min = math.inf
    theta_max = -math.inf
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        n = min(BLOCK, m - lo)
        length = np.empty(BLOCK)
        theta = np.empty(BLOCK)
        energy_block = np.empty(BLOCK)
        squared_lengths(x, edges, lo, n, length, 0)
        for i in range(n):
            e = np.uint64(lo + i)
            c = np.uint64(0) if UNIFORM else e
            l = math.sqrt(length[i])
            eta_e = eta[e] if THERMAL else 0.0
            th = spring_temperature(l, eta_e, l0[e], P, c)
            theta[i] = th
            energy_block[i] = spring_energy(l, eta_e, th, l0[e], P, c)
        block_sum = 0.0
        block_min = math.inf
        block_max = -math.inf
        for i in range(n):
            block_sum += energy_block[i]
            block_min = min(block_min, theta[i])
            block_max = max(block_max, theta[i])
        energy += block_sum
        theta_min = min(theta_min, block_min)
        theta_max = max(theta_max, block_max)
    return energy, theta_min, theta_max


def _node_sums(x, p, masses, anchored, ref, gravity):
    """Kinetic energy, gravity potential −Σ m g·x, Σ p and Σ (x − ref) × p over free nodes."""
    kinetic = 0.0
    potential = 0.0
    px = 0.0
    py = 0.0
    pz = 0.0
    lx = 0.0
    ly = 0.0
    lz = 0.0
    for a in prange(x.shape[0]):
        if not anchored[a]:
            p0 = p[a, 0]
            p1 = p[a, 1]
            p2 = p[a, 2]
            k, v, l0_, l1_, l2_ = node_diagnostic_terms(x[a, 0], x[a, 1], x[a, 2], p0, p1, p2, masses[a], gravity, ref)
            kinetic += k
            potential += v
            px += p0
            py += p1
            pz += p2
            lx += l0_
            ly += l1_
            lz += l2_
    return kinetic, potential, px, py, pz, lx, ly, lz
