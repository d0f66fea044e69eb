"""Fused Numba kernels for the explicit integrators, all written as kick/drift splittings.

Every explicit integrator of thermonet is a sequence ``K(k0) D(d0) K(k1) … D(d_{S−1}) K(k_S)``
of sub-flows with coefficients (fractions of h):

- kick ``K(k)``: at the current positions x, per spring θ = θ(l, η) and T = T(l, θ);
  ``p += k h f(x, θ)`` and ``Φ += k h θ`` (entropy η is untouched, so it is conserved exactly);
- drift ``D(d)``: ``x += d h M⁻¹ p``.

One *stage* is a kick followed by a drift and costs two passes over memory:

1. per spring, in blocks of ``BLOCK`` springs (parallel over blocks): a scalar loop gathers the
   squared lengths |x_b − x_a|² into ``s``; a second loop over the same block, now reading only
   contiguous arrays, computes l, θ, T/l into ``s`` and updates Φ. The second loop carries all the
   arithmetic (sqrt, the model's exp/log, divisions) and LLVM vectorizes it, which it does not do
   for a loop that also gathers; the block is still in L1 when the second loop reads it back.
2. per node (parallel over nodes): gather ``f_a = Σ_e s_e (x_b − x_a)`` over the incident springs
   (CSR lists), kick, drift into a second position buffer (others still read the old one).

Indices are read as unsigned (zero-copy views of the int32 arrays): Numba wraps negative signed
indices around with a compare-and-select per access, which costs about a third of the gather
pass and blocks vectorization; an unsigned index has no negative case.

Blow-up detection costs one comparison chain per spring in the vectorized loop: a spring whose
stretch l/l0 leaves (stretch_min, stretch_max), whose T/l is not finite (a non-finite position
gives that too) or, with thermal coupling, whose θ is not > 0 is counted; a stage that counts
any stops the kernel at once, before the node pass. ``advance`` then returns how many steps were
completed before the step in which it happened, with ``x`` holding the positions it was found
at; the caller rewinds to the last good step (see ``Simulation``).

The last kick of one step and the first kick of the next act at the same positions and share one
force evaluation; they are still applied as two separate additions, so a run cut into chunks at
any step boundary gives bit-for-bit the same numbers as one long call. A call ends with the
closing kick of its last step; it keeps that kick's forces and temperatures (``f_keep``,
``theta_keep``), and a following call from the same state (``reuse_boundary``, the caller's
promise) starts from them instead of evaluating them again: without that, every observer stop of a
run (a diagnostics row every 10 steps, say) would cost one more force evaluation, a whole CO2 step.
With ``want_sums`` the closing kick also reduces a diagnostics row's sums (internal energy and
the temperature range in its spring pass, kinetic and gravity energy and the momenta in its node
pass, at the synchronized state the call ends in) into ``sums``, so a row costs a few flops per
spring instead of two more passes over memory (:func:`thermonet.kernels.reductions` is the
stand-alone version, for states no call ends in). Every spring and every
node is computed by one thread with a fixed summation order, so results do not depend on the
number of threads.

When every spring has the same model parameters (a common case), :func:`kernel_parameters`
returns a ``(k, 1)`` array and the kernels are compiled with ``UNIFORM``: the model functions are
called with column ``e = 0``, so the loop reads the parameters once instead of ``8 k`` bytes per
spring and force evaluation.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .specialize import model_fingerprint, model_namespace, specialize

# Bound per model by specialize(); listed so the templates read as ordinary code. THERMAL,
# REFERENCE_TEMPERATURE and UNIFORM are compile-time constants: with THERMAL False the kernel is
# the purely mechanical one (every spring at its reference temperature, parameter row
# REFERENCE_TEMPERATURE; no η, θ or Φ is read or written); with UNIFORM, P is (k, 1) and shared.
temperature = tension = internal_energy = free_energy = spring_pass = node_pass = None
boundary_spring_pass = boundary_node_pass = thermal_kick = copy_rows = None
THERMAL = True
CLOSING = False
REFERENCE_TEMPERATURE = 0
UNIFORM = False

#: springs per block of the spring pass: small enough that a block of s, η, l0, Φ stays in L1
BLOCK = 512

_CACHE: dict = {}

_OPTIONS = dict(cache=True, error_model="numpy", boundscheck=False)


def kernel_parameters(P: np.ndarray) -> tuple[np.ndarray, bool]:
    """The parameter array the kernels should read, and whether it is shared by all springs.

    P: (k, m) per-spring parameters. Returns ``(P[:, :1] copy, True)`` when every row is
    constant, else ``(P, False)``; pass the flag to :func:`splitting_kernels` as ``uniform``.
    """
    P = np.ascontiguousarray(P, dtype=np.float64)
    if P.shape[1] > 0 and bool(np.all(P == P[:, :1])):
        return np.ascontiguousarray(P[:, :1]), True
    return P, False


def splitting_kernels(model, parallel: bool, thermal: bool = True, uniform: bool = False):
    """``advance(...)`` compiled for ``model`` (multi-threaded when ``parallel``; purely mechanical
    when not ``thermal``, in which case ``phi`` and ``eta`` may be empty arrays; for a ``(k, 1)``
    parameter array shared by all springs when ``uniform``, see :func:`kernel_parameters`)."""
    key = (model_fingerprint(model), bool(parallel), bool(thermal), bool(uniform))
    if key not in _CACHE:
        tag = (f"{model.name}_{key[0]}_{'par' if parallel else 'ser'}_{'thermal' if thermal else 'mech'}"
               f"{'_uniform' if uniform else ''}")
        ns = model_namespace(model)
        ns["THERMAL"] = bool(thermal)
        ns["REFERENCE_TEMPERATURE"] = model.parameter_index(model.reference_temperature)
        ns["UNIFORM"] = bool(uniform)
        ns["CLOSING"] = False
        ns["spring_pass"] = specialize(_spring_pass, tag, ns, parallel=parallel, **_OPTIONS)
        ns["node_pass"] = specialize(_node_pass, tag, ns, parallel=parallel, **_OPTIONS)
        boundary = dict(ns, CLOSING=True)
        ns["boundary_spring_pass"] = specialize(_spring_pass, tag + "_boundary", boundary, parallel=parallel,
                                                **_OPTIONS)
        ns["boundary_node_pass"] = specialize(_node_pass, tag + "_boundary", boundary, parallel=parallel,
                                              **_OPTIONS)
        ns["thermal_kick"] = specialize(_thermal_kick, tag, ns, parallel=parallel, **_OPTIONS)
        ns["copy_rows"] = specialize(_copy_rows, tag, ns, parallel=parallel, **_OPTIONS)
        _CACHE[key] = specialize(_advance, tag, ns, **_OPTIONS)
    return _CACHE[key]


@njit(inline="always", error_model="numpy", boundscheck=False)
def squared_lengths(x, edges, lo, n, out, base):
    """out[base + i] = |x_b − x_a|² of springs lo … lo + n − 1: the gather half of a blocked
    spring pass (kept apart from the arithmetic so that the arithmetic loop vectorizes).
    edges: (m, 2) uint32."""
    for i in range(n):
        e = np.uint64(lo + i)
        a = edges[e, 0]
        b = edges[e, 1]
        dx = x[b, 0] - x[a, 0]
        dy = x[b, 1] - x[a, 1]
        dz = x[b, 2] - x[a, 2]
        out[base + i] = dx * dx + dy * dy + dz * dz


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


def _spring_pass(x, eta, l0, P, edges, s, phi, phi_h1, phi_h2, track_phi, stretch_min, stretch_max,
                 theta_keep, keep, energy_buf, want_sums):
    """Per spring e: s[e] = T/l at x; Φ[e] += (phi_h1 + phi_h2) θ as two additions; θ into
    theta_keep[e] when ``keep`` (THERMAL only); with ``want_sums`` the spring's internal energy
    (free energy at θ0 when not THERMAL) into energy_buf[e] and the block sums below.

    edges: (m, 2) uint32. P: (k, m), or (k, 1) when UNIFORM. Returns (the number of springs
    outside the admissible states (stretch bounds, non-finite T/l, θ ≤ 0), Σ energy, min θ,
    max θ); the sums are 0, inf, −inf without ``want_sums``. Compiled twice: with CLOSING for
    the calls' first and last kicks, and without (keep and sums compiled out) for every other.
    """
    m = edges.shape[0]
    bad = 0
    energy = 0.0
    theta_min = math.inf
    theta_max = -math.inf
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        n = min(BLOCK, m - lo)
        squared_lengths(x, edges, lo, n, s, lo)
        for i in range(n):
            e = np.uint64(lo + i)
            c = np.uint64(0) if UNIFORM else e
            l = math.sqrt(s[e])
            rest = l0[e]
            if THERMAL:
                theta = temperature(l, eta[e], rest, P, c)
            else:
                theta = P[REFERENCE_TEMPERATURE, c]
            force = tension(l, theta, rest, P, c) / l
            s[e] = force
            outside = (l <= stretch_min * rest) | (l >= stretch_max * rest) | (not (abs(force) < math.inf))
            if THERMAL:
                outside = outside | (not (theta > 0.0))
            bad += outside
            if CLOSING:
                if THERMAL and keep:
                    theta_keep[e] = theta
                if want_sums:
                    if THERMAL:
                        energy_buf[e] = internal_energy(l, eta[e], rest, P, c)
                    else:
                        energy_buf[e] = free_energy(l, theta, rest, P, c)
            if THERMAL and track_phi:
                if phi_h1 != 0.0:
                    phi[e] += phi_h1 * theta
                phi[e] += phi_h2 * theta
        if CLOSING:
            if want_sums:  # in order, after the vectorized loop (a sum inside it would keep it scalar)
                block_sum = 0.0
                block_min = math.inf
                block_max = -math.inf
                for i in range(n):
                    e = np.uint64(lo + i)
                    block_sum += energy_buf[e]
                    th = theta_keep[e] if THERMAL else P[REFERENCE_TEMPERATURE, np.uint64(0) if UNIFORM else e]
                    block_min = min(block_min, th)
                    block_max = max(block_max, th)
                energy += block_sum
                theta_min = min(theta_min, block_min)
                theta_max = max(theta_max, block_max)
    return bad, energy, theta_min, theta_max


def _node_pass(x, x_new, p, s, inc_ptr, inc_spring, inc_other, masses, inv_mass, anchored,
               kick1, kick2, drift, with_force, gravity, with_gravity, f_keep, force_source, ref, want_sums):
    """Per node a: f = Σ s_e (x_b − x_a) (+ m g); p += kick1 f; p += kick2 f; x_new = x + drift p/m.

    inc_spring, inc_other: (2m,) uint32. force_source: 0 gather f; 1 gather f and keep it in
    f_keep (n, 3) (a call's closing kick, whose drift is 0: x_new is then not written, the
    positions stay in x); 2 take f from f_keep. Returns, with ``want_sums``, the sums over free
    nodes at (x, the new p) of kinetic energy, gravity potential −Σ m g·x, p and (x − ref) × p
    (else 0).
    """
    move = not (CLOSING and force_source == 1)
    kinetic = 0.0
    potential = 0.0
    px = 0.0
    py = 0.0
    pz = 0.0
    lx = 0.0
    ly = 0.0
    lz = 0.0
    for a in prange(x.shape[0]):
        xa0 = x[a, 0]
        xa1 = x[a, 1]
        xa2 = x[a, 2]
        if anchored[a]:
            if move:
                x_new[a, 0] = xa0
                x_new[a, 1] = xa1
                x_new[a, 2] = xa2
            continue
        p0 = p[a, 0]
        p1 = p[a, 1]
        p2 = p[a, 2]
        if with_force:
            if CLOSING and force_source == 2:
                f0 = f_keep[a, 0]
                f1 = f_keep[a, 1]
                f2 = f_keep[a, 2]
            else:
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
                if CLOSING and force_source == 1:
                    f_keep[a, 0] = f0
                    f_keep[a, 1] = f1
                    f_keep[a, 2] = f2
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
        if move:
            w = drift * inv_mass[a]
            x_new[a, 0] = xa0 + w * p0
            x_new[a, 1] = xa1 + w * p1
            x_new[a, 2] = xa2 + w * p2
        if CLOSING and want_sums:
            k, v, l0_, l1_, l2_ = node_diagnostic_terms(xa0, xa1, xa2, p0, p1, p2, masses[a], gravity, ref)
            kinetic += k
            potential += v
            px += p0
            py += p1
            pz += p2
            lx += l0_
            ly += l1_
            lz += l2_
    return kinetic, potential, px, py, pz, lx, ly, lz


def _thermal_kick(phi, theta, coefficient):
    """Φ += coefficient θ, per spring (the thermal half of a kick whose θ is known)."""
    for e in prange(phi.shape[0]):
        phi[e] += coefficient * theta[e]


def _copy_rows(source, target):
    """target[:] = source for (n, 3) arrays, rows in parallel."""
    for a in prange(source.shape[0]):
        target[a, 0] = source[a, 0]
        target[a, 1] = source[a, 1]
        target[a, 2] = source[a, 2]


def _advance(x, x_buf, p, phi, eta, s, l0, P, edges, inc_ptr, inc_spring, inc_other, masses, inv_mass,
             anchored, kicks, drifts, h, n_steps, track_phi, gravity, with_gravity, stretch_min, stretch_max,
             f_keep, theta_keep, reuse_boundary, energy_buf, ref, sums, want_sums):
    """Advance (x, p, Φ) in place by ``n_steps`` steps of the scheme (kicks (S+1,), drifts (S,)).

    The closing kick's forces and temperatures are kept in f_keep (n, 3) and theta_keep (m,)
    (empty when not THERMAL); with ``reuse_boundary`` the first kick takes them from there
    instead of evaluating them (the caller vouches that x, η are those of the previous call's end).
    With ``want_sums`` the closing kick writes the end state's diagnostics sums into sums (11,):
    Σ U (Σ F(l, θ0) when not THERMAL), min θ, max θ, kinetic, gravity potential, p (3),
    angular momentum about ref (3); energy_buf (m,) is their scratch.

    Returns (steps completed, detected, summed): ``detected`` when a spring left the admissible
    states (see the module docstring); then ``x`` holds the positions where it was found and only
    the first ``steps completed`` steps are known good (x, p, Φ are mid-step: rewind and replay).
    ``summed``: the sums were written (a scheme without a closing kick writes none).

    x, x_buf, p: (n, 3); phi, eta, s, l0: (m,); P: (k, m), or (k, 1) for the UNIFORM variant;
    edges: (m, 2) int32; inc_*: CSR incidence (inc_ptr (n+1,) int64, inc_spring and inc_other
    (2m,) int32); masses, inv_mass: (n,) (inv_mass 0 on anchors); anchored: (n,) bool;
    gravity: (3,) acceleration, used when with_gravity. x_buf and s are scratch.
    """
    edges_u = edges.view(np.uint32)
    inc_spring_u = inc_spring.view(np.uint32)
    inc_other_u = inc_other.view(np.uint32)
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
            reuse = reuse_boundary and step == 0 and i == 0 and with_force
            if reuse:  # the previous call's closing kick evaluated these at these positions
                if THERMAL and track_phi:
                    thermal_kick(phi, theta_keep, k2 * h)
            elif with_force:
                bad = spring_pass(cur, eta, l0, P, edges_u, s, phi, k1 * h, k2 * h, track_phi,
                                  stretch_min, stretch_max, theta_keep, False, energy_buf, False)[0]
                if bad > 0:
                    if swaps % 2 == 1:
                        copy_rows(x_buf, x)
                    # positions at stage 0 are the end of the previous step: that step was the bad one
                    return (step - 1 if i == 0 and step > 0 else step), True, False
            if reuse:
                boundary_node_pass(cur, nxt, p, s, inc_ptr, inc_spring_u, inc_other_u, masses, inv_mass, anchored,
                                   k1 * h, k2 * h, drifts[i] * h, with_force, gravity, with_gravity, f_keep, 2,
                                   ref, False)
            else:
                node_pass(cur, nxt, p, s, inc_ptr, inc_spring_u, inc_other_u, masses, inv_mass, anchored,
                          k1 * h, k2 * h, drifts[i] * h, with_force, gravity, with_gravity, f_keep, 0, ref, False)
            cur, nxt = nxt, cur
            swaps += 1
        pending = kicks[n_stages]
    summed = False
    if pending != 0.0:
        bad, energy, theta_min, theta_max = boundary_spring_pass(cur, eta, l0, P, edges_u, s, phi, 0.0,
                                                                 pending * h, track_phi, stretch_min, stretch_max,
                                                                 theta_keep, True, energy_buf, want_sums)
        if bad > 0:
            if swaps % 2 == 1:
                copy_rows(x_buf, x)
            return n_steps - 1, True, False
        node_sums = boundary_node_pass(cur, nxt, p, s, inc_ptr, inc_spring_u, inc_other_u, masses, inv_mass,
                                       anchored, 0.0, pending * h, 0.0, True, gravity, with_gravity, f_keep, 1, ref,
                                       want_sums)  # drift 0: the positions stay in cur
        if want_sums:
            sums[0] = energy
            sums[1] = theta_min
            sums[2] = theta_max
            for q in range(8):
                sums[3 + q] = node_sums[q]
            summed = True
    if swaps % 2 == 1:
        copy_rows(x_buf, x)
    return n_steps, False, summed
