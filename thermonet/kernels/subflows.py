"""The explicit integrators' sub-flows, one definition each, for every target.

Each function here is plain Python that the CPU kernels (:mod:`thermonet.explicit.cpu`,
compiled with ``njit(inline="always")``) and the CUDA kernels (:mod:`thermonet.explicit.cuda.kernels`,
compiled as device functions, or run as Python under the simulator) call by global name. They
are rebound per model like any kernel template (:func:`thermonet.kernels.specialize.rebind`):
``temperature`` and ``tension`` are the model's, ``THERMAL`` and ``REFERENCE_TEMPERATURE``
compile-time constants. A target decides only how elements are distributed (blocks and
``prange`` on the CPU, one thread per element on the GPU); what happens to one spring or one
node is written once, here.

The sub-flows of a kick/drift splitting:

- **kick** ``K(k)`` at fixed x: per spring θ = θ(l, η) and T/l (:func:`spring_force`), Φ += k h θ
  (:func:`advance_thermal_displacement`); per node f = Σ_e (T/l)_e (x_b − x_a) + m g
  (:func:`gather_force`), p += k h f (:func:`kick_momentum`). η is never written, so every
  splitting conserves each spring's entropy bit for bit.
- **drift** ``D(d)`` at fixed p: x += d h M⁻¹ p (:func:`drift_position`).

Further sub-flows (conduction, driven nodes, external forces, ...) are :class:`SubFlow` records
scheduled between these (see :mod:`thermonet.explicit.schedule`); the kernels run them
through the same element-wise passes on every target.
"""

from __future__ import annotations

import hashlib
import inspect
import math
import sys

import numpy as np

# Bound per model by the kernels' factories; listed so the functions read as ordinary code.
temperature = tension = internal_energy = free_energy = None
THERMAL = True
REFERENCE_TEMPERATURE = 0


def squared_length(x, edges, e):
    """|x_b − x_a|² of spring e = (a, b). x: (n, 3); edges: (m, 2) uint32."""
    a = edges[e, 0]
    b = edges[e, 1]
    dx = x[b, 0] - x[a, 0]
    dy = x[b, 1] - x[a, 1]
    dz = x[b, 2] - x[a, 2]
    return dx * dx + dy * dy + dz * dz


def spring_temperature(l, eta_e, rest, P, c):
    """θ = θ(l, η) of a spring of length l and entropy eta_e (the reference temperature, parameter
    row ``REFERENCE_TEMPERATURE``, when not THERMAL). P: (k, m) parameters, c the spring's column
    (0 when all springs share one)."""
    if THERMAL:
        return temperature(l, eta_e, rest, P, c)
    return P[REFERENCE_TEMPERATURE, c]


def spring_energy(l, eta_e, theta, rest, P, c):
    """A spring's energy in a diagnostics row: its internal energy U(l, η) when THERMAL, else its
    free energy F(l, θ) at the reference temperature theta."""
    if THERMAL:
        return internal_energy(l, eta_e, rest, P, c)
    return free_energy(l, theta, rest, P, c)


def spring_force(l, eta_e, rest, P, c):
    """(θ, T/l): :func:`spring_temperature` and the tension over the length."""
    theta = spring_temperature(l, eta_e, rest, P, c)
    return theta, tension(l, theta, rest, P, c) / l


def outside_admissible(l, rest, force, theta, stretch_min, stretch_max):
    """Whether a spring has left the admissible states: its stretch l/rest outside
    (stretch_min, stretch_max), T/l not finite (a non-finite position gives that too), or with
    THERMAL θ not > 0. Branch-free, so the spring loop that calls it still vectorizes."""
    outside = (l <= stretch_min * rest) | (l >= stretch_max * rest) | (not (abs(force) < math.inf))
    if THERMAL:
        outside = outside | (not (theta > 0.0))
    return outside


def advance_thermal_displacement(phi, e, theta, step1, step2):
    """The thermal half of a kick: Φ_e += step1 θ, then Φ_e += step2 θ (two kicks meeting at a
    step boundary stay two additions, so chunked runs give the same bits). phi: (m,)."""
    if step1 != 0.0:
        phi[e] += step1 * theta
    phi[e] += step2 * theta


def gather_force(a, x, s, inc_ptr, inc_spring, inc_other, masses, gravity, with_gravity):
    """Force on node a: Σ_e s_e (x_b − x_a) over its incident springs in CSR order (+ m_a g).

    x: (n, 3); s: (m,) T/l per spring; inc_ptr: (n+1,) int64; inc_spring, inc_other: (2m,)
    uint32; masses: (n,); gravity: (3,), added when with_gravity. Returns (f0, f1, f2).
    """
    xa0 = x[a, 0]
    xa1 = x[a, 1]
    xa2 = x[a, 2]
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    for j in range(inc_ptr[a], inc_ptr[a + 1]):
        ju = np.uint64(j)
        se = s[inc_spring[ju]]
        b = inc_other[ju]
        f0 += se * (x[b, 0] - xa0)
        f1 += se * (x[b, 1] - xa1)
        f2 += se * (x[b, 2] - xa2)
    if with_gravity:
        f0 += masses[a] * gravity[0]
        f1 += masses[a] * gravity[1]
        f2 += masses[a] * gravity[2]
    return f0, f1, f2


def kick_momentum(p0, p1, p2, f0, f1, f2, step1, step2):
    """p + step1 f + step2 f, as two additions (see :func:`advance_thermal_displacement`)."""
    if step1 != 0.0:
        p0 += step1 * f0
        p1 += step1 * f1
        p2 += step1 * f2
    return p0 + step2 * f0, p1 + step2 * f1, p2 + step2 * f2


def drift_position(x_new, a, x0, x1, x2, p0, p1, p2, step_over_mass):
    """x_new[a] = x_a + step_over_mass p_a (step_over_mass = d h / m_a, 0 on anchors)."""
    store_row(x_new, a, x0 + step_over_mass * p0, x1 + step_over_mass * p1, x2 + step_over_mass * p2)


def load_row(v, a):
    """(v[a, 0], v[a, 1], v[a, 2]) of an (n, 3) array."""
    return v[a, 0], v[a, 1], v[a, 2]


def store_row(v, a, v0, v1, v2):
    """v[a] = (v0, v1, v2) for an (n, 3) array."""
    v[a, 0] = v0
    v[a, 1] = v1
    v[a, 2] = v2


#: the functions above, in the order a kernel factory binds them (callees first)
SHARED = ("load_row", "store_row", "squared_length", "spring_temperature", "spring_energy", "spring_force",
          "outside_admissible",
          "advance_thermal_displacement", "gather_force", "kick_momentum", "drift_position")


def source_digest() -> str:
    """A short hash of this module's source: part of every compiled kernel's cache name, so an
    edited sub-flow is recompiled rather than loaded from a cache built from the old one."""
    return hashlib.sha256(inspect.getsource(sys.modules[__name__]).encode()).hexdigest()[:8]


def bind_subflows(ns: dict, tag: str, compile_) -> None:
    """Bind this module's functions (:data:`SHARED`) into ``ns`` (a kernel namespace holding the
    model and the compile-time constants), each compiled by ``compile_`` for its target."""
    from .specialize import rebind

    module = sys.modules[__name__]
    for name in SHARED:
        ns[name] = compile_(rebind(getattr(module, name), tag, ns))
