"""Fused Numba kernels for the explicit integrators, all written as kick/drift splittings.

Every explicit integrator of thermonet is a sequence ``K(k0) D(d0) K(k1) D(d1) … D(d_{S−1}) K(k_S)``
of sub-flows with coefficients (fractions of h):

- kick ``K(k)``: at the current positions x, per spring θ = θ(l, η) and T = T(l, θ);
  ``p += k h f(x, θ)`` and ``Φ += k h θ`` (entropy η is untouched, so it is conserved exactly);
- drift ``D(d)``: ``x += d h M⁻¹ p``.

One *stage* is a kick followed by a drift and costs two passes over memory:

1. per spring (parallel over springs, no scattered writes so it vectorizes): length, θ, T/l into
   ``s``, Φ update;
2. per node (parallel over nodes): gather ``f_a = Σ_e s_e (x_b − x_a)`` over the incident springs
   (CSR lists), kick, drift into a second position buffer (others still read the old one).

The last kick of one step and the first kick of the next act at the same positions and share one
force evaluation; they are still applied as two separate additions, so a run cut into chunks at
any step boundary gives bit-for-bit the same numbers as one long call. Node sums run in a fixed
order, so results do not depend on the number of threads.
"""

from __future__ import annotations

import math

from numba import prange

from .specialize import model_fingerprint, model_namespace, specialize

# Bound per model by specialize(); listed so the templates read as ordinary code. THERMAL and
# REFERENCE_TEMPERATURE are compile-time constants: with THERMAL False the kernel is the purely
# mechanical one (every spring at its reference temperature, parameter row REFERENCE_TEMPERATURE;
# no η, θ or Φ is read or written).
temperature = tension = spring_pass = node_pass = None
THERMAL = True
REFERENCE_TEMPERATURE = 0

_CACHE: dict = {}

_OPTIONS = dict(cache=True, error_model="numpy", boundscheck=False)


def splitting_kernels(model, parallel: bool, thermal: bool = True):
    """``advance(...)`` compiled for ``model`` (multi-threaded when ``parallel``; purely mechanical
    when not ``thermal``, in which case ``phi`` and ``eta`` may be empty arrays)."""
    key = (model_fingerprint(model), bool(parallel), bool(thermal))
    if key not in _CACHE:
        tag = f"{model.name}_{key[0]}_{'par' if parallel else 'ser'}_{'thermal' if thermal else 'mech'}"
        ns = model_namespace(model)
        ns["THERMAL"] = bool(thermal)
        ns["REFERENCE_TEMPERATURE"] = model.parameter_index(model.reference_temperature)
        ns["spring_pass"] = specialize(_spring_pass, tag, ns, parallel=parallel, **_OPTIONS)
        ns["node_pass"] = specialize(_node_pass, tag, ns, parallel=parallel, **_OPTIONS)
        _CACHE[key] = specialize(_advance, tag, ns, **_OPTIONS)
    return _CACHE[key]


def _spring_pass(x, eta, l0, P, edges, s, phi, phi_h1, phi_h2, track_phi):
    """Per spring e: s[e] = T/l at x; Φ[e] += (phi_h1 + phi_h2) θ as two additions."""
    for e in prange(edges.shape[0]):
        a = edges[e, 0]
        b = edges[e, 1]
        dx = x[b, 0] - x[a, 0]
        dy = x[b, 1] - x[a, 1]
        dz = x[b, 2] - x[a, 2]
        l = math.sqrt(dx * dx + dy * dy + dz * dz)
        if THERMAL:
            theta = temperature(l, eta[e], l0[e], P, e)
        else:
            theta = P[REFERENCE_TEMPERATURE, e]
        s[e] = tension(l, theta, l0[e], P, e) / l
        if THERMAL and track_phi:
            if phi_h1 != 0.0:
                phi[e] += phi_h1 * theta
            phi[e] += phi_h2 * theta


def _node_pass(x, x_new, p, s, inc_ptr, inc_spring, inc_other, masses, inv_mass, anchored,
               kick1, kick2, drift, with_force, gravity, with_gravity):
    """Per node a: f = Σ s_e (x_b − x_a) (+ m g); p += kick1 f; p += kick2 f; x_new = x + drift p/m."""
    for a in prange(x.shape[0]):
        xa0 = x[a, 0]
        xa1 = x[a, 1]
        xa2 = x[a, 2]
        if anchored[a]:
            x_new[a, 0] = xa0
            x_new[a, 1] = xa1
            x_new[a, 2] = xa2
            continue
        p0 = p[a, 0]
        p1 = p[a, 1]
        p2 = p[a, 2]
        if with_force:
            f0 = 0.0
            f1 = 0.0
            f2 = 0.0
            for j in range(inc_ptr[a], inc_ptr[a + 1]):
                se = s[inc_spring[j]]
                b = inc_other[j]
                f0 += se * (x[b, 0] - xa0)
                f1 += se * (x[b, 1] - xa1)
                f2 += se * (x[b, 2] - xa2)
            if with_gravity:
                f0 += masses[a] * gravity[0]
                f1 += masses[a] * gravity[1]
                f2 += masses[a] * gravity[2]
            if kick1 != 0.0:
                p0 += kick1 * f0
                p1 += kick1 * f1
                p2 += kick1 * f2
            p0 += kick2 * f0
            p1 += kick2 * f1
            p2 += kick2 * f2
            p[a, 0] = p0
            p[a, 1] = p1
            p[a, 2] = p2
        w = drift * inv_mass[a]
        x_new[a, 0] = xa0 + w * p0
        x_new[a, 1] = xa1 + w * p1
        x_new[a, 2] = xa2 + w * p2


def _advance(x, x_buf, p, phi, eta, s, l0, P, edges, inc_ptr, inc_spring, inc_other, masses, inv_mass,
             anchored, kicks, drifts, h, n_steps, track_phi, gravity, with_gravity):
    """Advance (x, p, Φ) in place by ``n_steps`` steps of the scheme (kicks (S+1,), drifts (S,)).

    x, x_buf, p: (n, 3); phi, eta, s, l0: (m,); P: (k, m); edges: (m, 2) int32; inc_*: CSR
    incidence; masses, inv_mass: (n,) (inv_mass 0 on anchors); anchored: (n,) bool;
    gravity: (3,) acceleration, used when with_gravity. x_buf and s are scratch.
    """
    n_stages = drifts.shape[0]
    cur = x
    nxt = x_buf
    swaps = 0
    pending = 0.0
    for step in range(n_steps):
        for i in range(n_stages):
            k1 = pending if i == 0 else 0.0
            k2 = kicks[i]
            with_force = k1 != 0.0 or k2 != 0.0
            if with_force:
                spring_pass(cur, eta, l0, P, edges, s, phi, k1 * h, k2 * h, track_phi)
            node_pass(cur, nxt, p, s, inc_ptr, inc_spring, inc_other, masses, inv_mass, anchored,
                      k1 * h, k2 * h, drifts[i] * h, with_force, gravity, with_gravity)
            cur, nxt = nxt, cur
            swaps += 1
        pending = kicks[n_stages]
    if pending != 0.0:
        spring_pass(cur, eta, l0, P, edges, s, phi, 0.0, pending * h, track_phi)
        node_pass(cur, nxt, p, s, inc_ptr, inc_spring, inc_other, masses, inv_mass, anchored,
                  0.0, pending * h, 0.0, True, gravity, with_gravity)
        cur, nxt = nxt, cur
        swaps += 1
    if swaps % 2 == 1:
        x[:, :] = x_buf
