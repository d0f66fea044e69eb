"""Numba templates for the implicit integrators' step equations (spec §2.1 GTR-α, §2.2 HO4):
the mechanical residuals, the values of their exact sparse Jacobian (assembled, or as per-spring
coefficients for a matrix-free product, :mod:`.implicit_operator`), and the update that turns
converged unknowns into the next state.

The unknowns are per free node: the displacement over the step ``d = x¹ − x⁰`` for GTR-α
(block of 3), and ``d^½ = x^½ − x⁰, d¹ = x¹ − x⁰`` for HO4 (block of 6). Working with
displacements, not positions, keeps the inertial terms ``M d / h`` free of the cancellation
``M (x¹ − x⁰) / h`` would suffer at small h. Block k of the unknown vector ``u`` belongs to the
node ``a`` with ``free_index[a] == k``; anchored nodes have ``free_index == −1`` and no unknowns.

The thermal unknowns (θ̄ for GTR-α; θ⁰, θ¹ — equivalently Φ^½, Φ¹ — for HO4) enter only the
equations of their own spring, so each residual evaluation solves them exactly (to round-off)
per spring given the spring's lengths, and the Jacobian carries their derivatives with respect
to those lengths (implicit function theorem). This condensation is exact: the converged step
satisfies every equation of the monolithic system. Within a Newton solve the previous iterate's
temperatures, moved along those derivatives, seed the per-spring solves.

The per-spring solves are vectorized: every spring pass is blocked like the explicit kernel's
(:mod:`.splitting`): per block of ``BLOCK`` springs a scalar loop gathers the node data, then a
loop over contiguous arrays does the arithmetic, which LLVM vectorizes. In that loop every
thermal solve makes a fixed number of Newton corrections (``VECTOR_CORRECTIONS``, no early
exit); a spring whose last correction is not below ``THETA_STOP`` (a cold start of a model that
is not affine in the right variable, a wild iterate), or whose state is not admissible, is
flagged and redone by the scalar solve (``*_thermal``: iterate to convergence, report the
failure) in a third loop over the block. For the shipped models one correction is exact (the
second confirms it), so the fallback is for custom models and bad states. Where the entropy is
affine in ln θ (``Model.entropy_log_affine``, model "hencky"), HO4's solve is in closed form
(:func:`_ho4_thermal_exact`): no corrections, no seeds.

Per-spring arrays are stored component-major, (k, m) (``dir0[i, e]``), so that the vectorized
loop reads and writes unit-stride rows. Indices are read as unsigned in the spring passes.

Residual rows are in momentum units. Next to the residual ``R`` a kernel fills ``Rabs``, the sum
of the magnitudes of the terms of each row, so the Newton test can judge ``|R|`` against the size
of what cancelled in it (its round-off floor is then a few ulps). The residual kernels return
max |R| and max Rabs too.

Per-spring Jacobian blocks are scattered into a CSR value array: for spring e = (a, b) the
``spring_base[e, q]`` (q = aa, ab, ba, bb) is the data index of the block's (0, 0) entry and
``spring_stride[e, q]`` the distance between its rows; −1 where an end is anchored. Nodal mass
blocks use ``node_base``/``node_stride``. Status codes returned by residual and finish kernels:
0 fine, 1 a spring collapsed (length ≤ 0 or not finite), 2 no positive finite temperature solves
the spring's thermal equations, 3 a non-finite momentum or entropy; with the spring's index.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .fastmath import exp as exp_
from .specialize import model_fingerprint, model_namespace, specialize

# Bound per model by specialize(); listed so the templates read as ordinary code.
entropy = temperature = tension = d2F_dl2 = d2F_dl_dtheta = d2F_dtheta2 = None
adiabatic_stiffness = gtr_thermal = ho4_thermal = gtr_thermal_vector = ho4_thermal_vector = gtr_correct = ho4_correct = ho4_derivatives = finish_nodes = None
ho4_thermal_exact = ho4_thermal_closed = ho4_temperature_derivatives = None
#: the model's entropy is affine in ln θ (Model.entropy_log_affine): HO4's thermal solve in closed form
LOG_AFFINE = False
#: the time derivatives of the acceleration the start kernel's predictor uses (ImplicitStepper.rate)
RATE = 0
#: the start kernel keeps, per spring, what HO4's closed-form thermal solve needs of the step's
#: start (HO4 with a LOG_AFFINE model; see _ho4_thermal_closed)
KEEP_START = False
#: rows of the start kernel's ``keep`` (4, m): θ(l⁰, η), T(l⁰, θ(l⁰, η)), F_lθ(l⁰), C
KEEP_ROWS = 4
#: every spring has the same parameters: P is the shared (k, 1) column of System.kernel_parameters,
#: read at column 0 (``pe``) and not streamed per spring
UNIFORM = False
#: the residual's index helpers, bound per variant (a kernel compiled with a conditional index
#: ran 25 % slower): in the full kernel ``listed(indices, j)`` is j, ``listed_count(indices, n)``
#: is n and ``first_flagged_listed`` is :func:`_first_flagged`; in the SUBSET kernel, which
#: recomputes only the listed springs and node rows, indices[j], len(indices) and the same over
#: the listed entries
listed = listed_count = first_flagged_listed = None

_CACHE: dict = {}
_OPTIONS = dict(cache=True, error_model="numpy", boundscheck=False)
_INLINE = dict(inline="always", error_model="numpy", boundscheck=False)

#: a per-spring Newton solve stops after a correction of ln θ this small: its error is then of
#: the order of the correction squared (quadratic convergence), below round-off
THETA_STOP = 1e-9
LOCAL_ITERATIONS = 60
#: springs per block of a spring pass (as the explicit kernel's)
BLOCK = 512
#: Newton corrections of a vectorized thermal solve (warm-started: the first one is exact or
#: leaves an error ~ its square; the second must then be below THETA_STOP)
VECTOR_CORRECTIONS = 2

OK, COLLAPSED, NO_TEMPERATURE, NOT_FINITE = 0, 1, 2, 3
STATUS_TEXT = {
    COLLAPSED: "spring collapsed (length not positive or not finite)",
    NO_TEMPERATURE: "no positive finite temperature solves the spring's thermal equations",
    NOT_FINITE: "non-finite momentum or entropy after the step",
}


class ImplicitKernels:
    """The compiled kernels of one scheme for one model (attributes: the kernel functions, and
    ``keep_start``: whether the start kernel fills its ``keep`` argument, (KEEP_ROWS, m))."""

    def __init__(self, **kernels):
        self.__dict__.update(kernels)


def implicit_kernels(model, scheme: str, parallel: bool = False, uniform: bool = False, rate: int = 0) -> ImplicitKernels:
    """Kernels for ``scheme`` ("gtr" or "ho4") compiled for ``model`` (cached on disk); the
    residual, linearization, start and finish kernels multi-threaded when ``parallel``; reading
    the parameters as one shared (k, 1) column when ``uniform`` (System.kernel_parameters); the
    start kernel's predictor with the acceleration's first ``rate`` time derivatives (a
    compile-time constant: the spring loops then carry no branches they do not take)."""
    key = (scheme, model_fingerprint(model), bool(parallel), bool(uniform), int(rate))
    if key not in _CACHE:
        tag = f"{model.name}_{key[1]}{'_uniform' if uniform else ''}"
        ptag = f"{tag}_{'par' if parallel else 'ser'}"
        ns = model_namespace(model)
        ns["RATE"] = int(rate)
        ns["LOG_AFFINE"] = bool(getattr(model, "entropy_log_affine", False))
        ns["KEEP_START"] = scheme == "ho4" and ns["LOG_AFFINE"]
        ns["UNIFORM"] = bool(uniform)
        ns["adiabatic_stiffness"] = specialize(_adiabatic_stiffness, tag, ns, **_INLINE)
        start = specialize(_start, f"{ptag}_rate{int(rate)}{'_keep' if ns['KEEP_START'] else ''}", ns,
                           parallel=parallel, **_OPTIONS)
        ns["finish_nodes"] = specialize(_finish_nodes, ptag, ns, parallel=parallel, **_OPTIONS)
        if scheme == "gtr":
            ns["gtr_correct"] = specialize(_gtr_correct, tag, ns, **_INLINE)
            ns["gtr_thermal"] = specialize(_gtr_thermal, tag, ns, **_OPTIONS)
            ns["gtr_thermal_vector"] = specialize(_gtr_thermal_vector, tag, ns, **_INLINE)
            _CACHE[key] = ImplicitKernels(
                start=start,
                keep_start=False,
                residual=specialize(_gtr_residual, ptag, ns, parallel=parallel, **_OPTIONS),
                linearize=specialize(_gtr_linearize, ptag, ns, parallel=parallel, **_OPTIONS),
                jacobian=specialize(_gtr_jacobian, tag, ns, **_OPTIONS),
                finish=specialize(_gtr_finish, ptag, ns, parallel=parallel, **_OPTIONS),
                thermal=ns["gtr_thermal"],
                # the two per-spring solves, callable alone (tests)
                thermal_vector=specialize(_gtr_thermal_vector, f"{tag}_alone", ns, **_OPTIONS),
            )
        elif scheme == "ho4":
            ns["ho4_derivatives"] = specialize(_ho4_derivatives, tag, ns, **_INLINE)
            ns["ho4_temperature_derivatives"] = specialize(_ho4_temperature_derivatives, tag, ns, **_INLINE)
            ns["ho4_correct"] = specialize(_ho4_correct, tag, ns, **_INLINE)
            ns["ho4_thermal_closed"] = specialize(_ho4_thermal_closed, tag, ns, **_INLINE)
            ns["ho4_thermal_exact"] = specialize(_ho4_thermal_exact, tag, ns, **_INLINE)
            ns["ho4_thermal"] = specialize(_ho4_thermal, tag, ns, **_OPTIONS)
            ns["ho4_thermal_vector"] = specialize(_ho4_thermal_vector, tag, ns, **_INLINE)
            subset = dict(ns, listed=_listed_entry, listed_count=_listed_count,
                          first_flagged_listed=_first_flagged_entry)
            ns.update(listed=_listed_position, listed_count=_all_count, first_flagged_listed=_first_flagged_position)
            _CACHE[key] = ImplicitKernels(
                start=start,
                keep_start=ns["KEEP_START"],
                residual=specialize(_ho4_residual, ptag, ns, parallel=parallel, **_OPTIONS),
                residual_subset=specialize(_ho4_residual, f"{ptag}_subset", subset, parallel=parallel, **_OPTIONS),
                linearize=specialize(_ho4_linearize, ptag, ns, parallel=parallel, **_OPTIONS),
                jacobian=specialize(_ho4_jacobian, tag, ns, **_OPTIONS),
                finish=specialize(_ho4_finish, ptag, ns, parallel=parallel, **_OPTIONS),
                thermal=ns["ho4_thermal"],
                # the two per-spring solves, callable alone (tests)
                thermal_vector=specialize(_ho4_thermal_vector, f"{tag}_alone", ns, **_OPTIONS),
            )
        else:
            raise ValueError(f"unknown implicit scheme {scheme!r}")
    return _CACHE[key]


# ---------------------------------------------------------------------------------------------
# shared

# The per-spring thermal solves are Newton's method in ln θ (the θ-Newton correction δθ applied
# as θ ← θ exp(−δθ/θ)): temperatures stay positive without step halving, and for an entropy
# that is affine in ln θ (model "hencky") it is exact in one step.
MAX_LOG_STEP = 20.0
SIXTH = 1.0 / 6.0


@njit(cache=True, inline="always")
def _log_step(s):
    """Newton correction of ln θ, bounded so exp() cannot overflow on a wild iterate."""
    if s > MAX_LOG_STEP:
        return MAX_LOG_STEP
    if s < -MAX_LOG_STEP:
        return -MAX_LOG_STEP
    return s


@njit(cache=True, inline="always")
def _usable(t):
    """A warm-start temperature that can seed a thermal solve."""
    return t > 0.0 and t < math.inf


@njit(cache=True, inline="always")
def _admissible(t):
    """Positive and finite, written without branches (for the vectorized loops)."""
    return (t > 0.0) & (t < math.inf)


@njit(cache=True, inline="always")
def _listed_position(indices, j):
    """j: the index of a full kernel's loop (its ``listed``)."""
    return j


@njit(cache=True, inline="always")
def _listed_entry(indices, j):
    """indices[j]: the index of a SUBSET kernel's loop (its ``listed``)."""
    return indices[j]


@njit(cache=True, inline="always")
def _all_count(indices, n):
    """n: a full kernel's loop length (its ``listed_count``)."""
    return n


@njit(cache=True, inline="always")
def _listed_count(indices, n):
    """len(indices): a SUBSET kernel's loop length (its ``listed_count``)."""
    return indices.shape[0]


@njit(cache=True, inline="always")
def _first_flagged_position(flag, indices, lo, n, none):
    """:func:`_first_flagged` (a full kernel's ``first_flagged_listed``)."""
    return _first_flagged(flag, lo, n, none)


@njit(cache=True, inline="always")
def _first_flagged_entry(flag, indices, lo, n, none):
    """The smallest e = indices[lo + i], 0 ≤ i < n, with flag[e] != 0, else ``none`` (a SUBSET
    kernel's ``first_flagged_listed``)."""
    bad = none
    for i in range(n):
        if flag[indices[lo + i]] != 0:
            bad = min(bad, indices[lo + i])
    return bad


@njit(cache=True, inline="always")
def _first_flagged(flag, lo, n, none):
    """The smallest index lo ≤ e < lo + n with flag[e] != 0, else ``none``."""
    for i in range(n):
        if flag[lo + i] != 0:
            return lo + i
    return none


# Every kernel below is two loops, each parallel when compiled with parallel=True: a spring
# loop (over blocks of springs) writes per-spring results (lengths, temperatures, the spring's
# force contribution ``fs``) and a node loop gathers them over the node's incident springs (CSR
# ``inc_ptr``/``inc_spring``). No two threads write the same element, each node sums its springs
# in a fixed order, and the blocks do not depend on the number of threads, so neither do the
# results. A spring loop cannot return early: a failing spring stores its status in ``code``
# and the smallest failing index is kept by a min-reduction.


def _adiabatic_stiffness(l, eta, l0, P, e):
    """dT/dl at constant entropy η: F_ll − F_lθ²/F_θθ at (l, θ(l, η))."""
    th = temperature(l, eta, l0, P, e)
    flt = d2F_dl_dtheta(l, th, l0, P, e)
    return d2F_dl2(l, th, l0, P, e) - flt * flt / d2F_dtheta2(l, th, l0, P, e)


#: the predictor's ä term is used at a node only where h²/8 |ä| ≤ SNAP_TRUST (|a| + h/2 |ȧ|)
SNAP_TRUST = 0.1
#: relative length step of the forward difference for d²T/dl² along an adiabat (the model gives
#: second derivatives of F only): its error ~ STIFFNESS_STEP, its round-off ~ 1e-16/STIFFNESS_STEP,
#: both far below what a predictor term needs (a central difference costs one more evaluation)
STIFFNESS_STEP = 1e-5


def _start(x0, p, inv_mass, eta, l0, P, edges, inc_ptr, inc_spring, inc_sign, free_index, gravity, with_gravity,
           len0, dir0, fs, ws, nodal, code, keep, h, coef, pred):
    """Lengths len0 (m,) and unit vectors dir0 (3, m) at x0 (n, 3), and the explicit predictor
    of the step's unknowns into pred (B n_free,): per free node and sub-block j (B = 3 × rows
    of coef), pred = coef[j, 0] v + coef[j, 1] a + coef[j, 2] ȧ + coef[j, 3] ä with v = p/m,
    a = f/m (+ g) the acceleration at (x0, θ(l0, η)) and its first (``RATE`` ≥ 1) and second
    (``RATE`` 2) time derivatives along the exact (adiabatic) flow at (x0, p0) (else 0), for a
    Taylor-like predictor. Scratch: fs (6, m), ws (6, m) (``RATE`` 2), nodal (n, 6) (``RATE``
    2), code (m,). With KEEP_START, keep (KEEP_ROWS, m) receives per spring θ(l⁰, η),
    T(l⁰, θ(l⁰, η)), F_lθ(l⁰) and the log-affine coefficient C = −θ F_θθ (HO4's closed-form
    thermal solve reads them at every residual of the step). Returns (status, spring).

    Per spring f = T n, T = T(l, θ(l, η)) along the adiabat with T' = dT/dl (adiabatic
    stiffness), l̇ = n·v, ṅ = (v − n l̇)/l (v, α: relative velocity and acceleration of the ends):
    ḟ = T' l̇ n + T ṅ;  f̈ = T'' l̇² n + T' l̈ n + 2 T' l̇ ṅ + T n̈ with l̈ = n·α + (|v|² − l̇²)/l,
    n̈ = (α − n l̈ − 2 ṅ l̇)/l; T'' by a forward difference of T'. ä needs the nodes' a: a second
    spring pass and node pass."""
    m = edges.shape[0]
    bad = m
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        n = min(BLOCK, m - lo)
        for i in range(n):  # gather: spring vector and relative velocity
            e = np.uint64(lo + i)
            a = edges[e, 0]
            b = edges[e, 1]
            dir0[0, e] = x0[b, 0] - x0[a, 0]
            dir0[1, e] = x0[b, 1] - x0[a, 1]
            dir0[2, e] = x0[b, 2] - x0[a, 2]
            if RATE > 0:
                fs[3, e] = p[b, 0] * inv_mass[b] - p[a, 0] * inv_mass[a]
                fs[4, e] = p[b, 1] * inv_mass[b] - p[a, 1] * inv_mass[a]
                fs[5, e] = p[b, 2] * inv_mass[b] - p[a, 2] * inv_mass[a]
        for i in range(n):  # arithmetic (vectorized)
            e = np.uint64(lo + i)
            pe = np.uint64(0) if UNIFORM else np.uint64(e)
            dx = dir0[0, e]
            dy = dir0[1, e]
            dz = dir0[2, e]
            l = math.sqrt(dx * dx + dy * dy + dz * dz)
            il = 1.0 / l
            nx = dx * il
            ny = dy * il
            nz = dz * il
            len0[e] = l
            dir0[0, e] = nx
            dir0[1, e] = ny
            dir0[2, e] = nz
            rest = l0[e]
            th = temperature(l, eta[e], rest, P, pe)
            T = tension(l, th, rest, P, pe)
            fs[0, e] = T * nx
            fs[1, e] = T * ny
            fs[2, e] = T * nz
            if KEEP_START:
                keep[0, e] = th
                keep[1, e] = T
                keep[2, e] = d2F_dl_dtheta(l, th, rest, P, pe)
                keep[3, e] = -th * d2F_dtheta2(l, th, rest, P, pe)
            if RATE > 0:
                vx = fs[3, e]
                vy = fs[4, e]
                vz = fs[5, e]
                ldot = nx * vx + ny * vy + nz * vz
                flt = d2F_dl_dtheta(l, th, rest, P, pe)
                Tl = d2F_dl2(l, th, rest, P, pe) - flt * flt / d2F_dtheta2(l, th, rest, P, pe)
                Tdot = Tl * ldot
                q = T / l
                fs[3, e] = Tdot * nx + q * (vx - nx * ldot)
                fs[4, e] = Tdot * ny + q * (vy - ny * ldot)
                fs[5, e] = Tdot * nz + q * (vz - nz * ldot)
                if RATE > 1:
                    dl = STIFFNESS_STEP * l
                    ws[0, e] = vx
                    ws[1, e] = vy
                    ws[2, e] = vz
                    ws[3, e] = T
                    ws[4, e] = Tl
                    ws[5, e] = (adiabatic_stiffness(l + dl, eta[e], rest, P, pe) - Tl) / dl
            lok = (l > 0.0) & (l < math.inf)
            code[e] = OK if (lok & _admissible(th)) else (NO_TEMPERATURE if lok else COLLAPSED)
        bad = min(bad, _first_flagged(code, lo, n, m))
    if bad < m:
        return code[bad], bad
    J = coef.shape[0]
    for a in prange(x0.shape[0]):
        k = free_index[a]
        if k < 0:
            if RATE > 1:
                for i in range(6):
                    nodal[a, i] = 0.0
            continue
        f0 = 0.0
        f1 = 0.0
        f2 = 0.0
        r0 = 0.0
        r1 = 0.0
        r2 = 0.0
        for j in range(inc_ptr[a], inc_ptr[a + 1]):
            e = inc_spring[j]
            sg = inc_sign[j]
            f0 += sg * fs[0, e]
            f1 += sg * fs[1, e]
            f2 += sg * fs[2, e]
            if RATE > 0:
                r0 += sg * fs[3, e]
                r1 += sg * fs[4, e]
                r2 += sg * fs[5, e]
        w = inv_mass[a]
        for i in range(3):
            f = f0 if i == 0 else (f1 if i == 1 else f2)
            r = r0 if i == 0 else (r1 if i == 1 else r2)
            v = w * p[a, i]
            acc = w * f + (gravity[i] if with_gravity else 0.0)
            jerk = w * r
            if RATE > 1:  # the prediction waits for ä
                nodal[a, i] = acc
                nodal[a, 3 + i] = jerk
                continue
            for s in range(J):
                pred[3 * J * k + 3 * s + i] = coef[s, 0] * v + coef[s, 1] * acc + coef[s, 2] * jerk
    if RATE < 2:
        return 0, -1
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        n = min(BLOCK, m - lo)
        for i in range(n):  # gather: relative acceleration
            e = np.uint64(lo + i)
            a = edges[e, 0]
            b = edges[e, 1]
            fs[0, e] = nodal[b, 0] - nodal[a, 0]
            fs[1, e] = nodal[b, 1] - nodal[a, 1]
            fs[2, e] = nodal[b, 2] - nodal[a, 2]
        for i in range(n):  # f̈ (vectorized)
            e = np.uint64(lo + i)
            l = len0[e]
            nx = dir0[0, e]
            ny = dir0[1, e]
            nz = dir0[2, e]
            vx = ws[0, e]
            vy = ws[1, e]
            vz = ws[2, e]
            ax = fs[0, e]
            ay = fs[1, e]
            az = fs[2, e]
            T = ws[3, e]
            Tl = ws[4, e]
            Tll = ws[5, e]
            ldot = nx * vx + ny * vy + nz * vz
            mx = (vx - nx * ldot) / l  # ṅ
            my = (vy - ny * ldot) / l
            mz = (vz - nz * ldot) / l
            lddot = nx * ax + ny * ay + nz * az + (vx * vx + vy * vy + vz * vz - ldot * ldot) / l
            radial = Tll * ldot * ldot + Tl * lddot - T * lddot / l
            side = 2.0 * (Tl - T / l) * ldot
            q = T / l
            fs[3, e] = radial * nx + side * mx + q * ax
            fs[4, e] = radial * ny + side * my + q * ay
            fs[5, e] = radial * nz + side * mz + q * az
    for a in prange(x0.shape[0]):
        k = free_index[a]
        if k < 0:
            continue
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        for j in range(inc_ptr[a], inc_ptr[a + 1]):
            e = inc_spring[j]
            sg = inc_sign[j]
            s0 += sg * fs[3, e]
            s1 += sg * fs[4, e]
            s2 += sg * fs[5, e]
        w = inv_mass[a]
        # the series a + τ ȧ + τ²/2 ä (τ ≤ h) is trusted with its ä term only where that term
        # is small next to the others (ω h ≲ 1 locally); a step near the stability limit keeps
        # the third-order guess
        lower = 0.0
        top = 0.0
        for i in range(3):
            lower = max(lower, abs(nodal[a, i]) + 0.5 * h * abs(nodal[a, 3 + i]))
            top = max(top, 0.125 * h * h * w * abs(s0 if i == 0 else (s1 if i == 1 else s2)))
        use = top <= SNAP_TRUST * lower
        for i in range(3):
            sn = w * (s0 if i == 0 else (s1 if i == 1 else s2)) if use else 0.0
            v = w * p[a, i]
            acc = nodal[a, i]
            jerk = nodal[a, 3 + i]
            for s in range(J):
                pred[3 * J * k + 3 * s + i] = (coef[s, 0] * v + coef[s, 1] * acc + coef[s, 2] * jerk
                                               + coef[s, 3] * sn)
    return 0, -1


def _finish_nodes(x0, u, p, fs, edges, free_index, inc_ptr, inc_spring, inc_sign, masses, h, gravity, with_gravity,
                  stride, offset, x_new, p_new):
    """The nodes' part of both finish kernels: x¹ = x⁰ + u[stride k + offset + i] for free node k,
    p¹ = p⁰ (+ h m g) − Σ± fs over the incident springs (fs: the per-spring impulses of the step,
    (≥ 3, m)). Returns (status, −1)."""
    n = x0.shape[0]
    bad_node = n
    for a in prange(n):
        k = free_index[a]
        if k < 0:
            for i in range(3):
                x_new[a, i] = x0[a, i]
                p_new[a, i] = p[a, i]
            continue
        F0 = 0.0
        F1 = 0.0
        F2 = 0.0
        for j in range(inc_ptr[a], inc_ptr[a + 1]):
            e = inc_spring[j]
            sg = -inc_sign[j]
            F0 += sg * fs[0, e]
            F1 += sg * fs[1, e]
            F2 += sg * fs[2, e]
        for i in range(3):
            F = F0 if i == 0 else (F1 if i == 1 else F2)
            x_new[a, i] = x0[a, i] + u[stride * k + offset + i]
            q = p[a, i] + (h * masses[a] * gravity[i] if with_gravity else 0.0) - F
            p_new[a, i] = q
            if not (abs(q) < math.inf):
                bad_node = min(bad_node, a)
    if bad_node < n:
        return NOT_FINITE, -1
    return 0, -1


# ---------------------------------------------------------------------------------------------
# GTR-α (spec §2.1): unknown d = x¹ − x⁰ per free node; θ̄ condensed per spring.
#   R_c = m_c d_c / h − α h f_c(x⁰, θ̄) − p_c                                         (48a)
#   α Γ(l⁰, θ̄) + (1 − α) Γ(l¹, θ̄) = η                                     per spring (48c)


def _gtr_thermal(la, lb, eta, l0, P, e, alpha, guess):
    """θ̄ with α Γ(la, θ̄) + (1 − α) Γ(lb, θ̄) = η, its derivative dθ̄/dlb, and success (1, else
    0: an integer, which Numba's alias analysis of a parallel loop treats as immutable).

    Newton in ln θ from ``guess`` when usable, else from θ(α la + (1 − α) lb, η) (the answer
    itself when α is 0 or 1). The scalar solve: iterates to convergence."""
    beta = 1.0 - alpha
    th = guess if _usable(guess) else temperature(alpha * la + beta * lb, eta, l0, P, e)
    if not _usable(th):
        return th, 0.0, 0
    done = False
    for _ in range(LOCAL_ITERATIONS):
        G = alpha * entropy(la, th, l0, P, e) + beta * entropy(lb, th, l0, P, e) - eta
        Gt = -(alpha * d2F_dtheta2(la, th, l0, P, e) + beta * d2F_dtheta2(lb, th, l0, P, e))
        step = _log_step(G / (Gt * th))
        th = th * math.exp(-step)
        if abs(step) <= THETA_STOP:
            done = True
            break
    if not (done and _usable(th)):
        return th, 0.0, 0
    Gt = -(alpha * d2F_dtheta2(la, th, l0, P, e) + beta * d2F_dtheta2(lb, th, l0, P, e))
    return th, beta * d2F_dl_dtheta(lb, th, l0, P, e) / Gt, 1


def _gtr_correct(la, lb, eta, l0, P, e, alpha, th):
    """One Newton correction of :func:`_gtr_thermal` (branch-free): (new θ̄, the ln θ step)."""
    beta = 1.0 - alpha
    G = alpha * entropy(la, th, l0, P, e) + beta * entropy(lb, th, l0, P, e) - eta
    Gt = -(alpha * d2F_dtheta2(la, th, l0, P, e) + beta * d2F_dtheta2(lb, th, l0, P, e))
    s = G / (Gt * th)
    step = min(max(s, -MAX_LOG_STEP), MAX_LOG_STEP)
    return th * exp_(-step), s


def _gtr_thermal_vector(la, lb, eta, l0, P, e, alpha, guess):
    """The vectorized loop's solve of :func:`_gtr_thermal`: VECTOR_CORRECTIONS corrections from
    the same start; success when the last one is below THETA_STOP. Same returns."""
    beta = 1.0 - alpha
    th = guess if _admissible(guess) else temperature(alpha * la + beta * lb, eta, l0, P, e)
    th, s = gtr_correct(la, lb, eta, l0, P, e, alpha, th)
    th, s = gtr_correct(la, lb, eta, l0, P, e, alpha, th)
    ok = 1 if (abs(s) <= THETA_STOP) & _admissible(th) else 0
    Gt = -(alpha * d2F_dtheta2(la, th, l0, P, e) + beta * d2F_dtheta2(lb, th, l0, P, e))
    return th, beta * d2F_dl_dtheta(lb, th, l0, P, e) / Gt, ok


def _gtr_residual(x0, u, p, eta, l0, P, edges, free_index, inc_ptr, inc_spring, inc_sign, masses, alpha, h, gravity,
                  with_gravity, len0, dir0, len1, dir1, theta, dtheta, warm, fs, guess, code, R, Rabs):
    """R, Rabs (3 n_free,) at unknowns u (3 n_free,); fills len1 (m,), dir1 (3, m), θ̄ and
    dθ̄/dl¹ (m,) for the Jacobian and the finish. With ``warm``, the θ̄ of the previous call
    (at nearby u), moved along dθ̄/dl¹, seeds each thermal solve. fs (≥ 3, m), guess, code (m,)
    scratch. Returns (status, spring, max |R|, max Rabs)."""
    m = edges.shape[0]
    bad = m
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        n = min(BLOCK, m - lo)
        for i in range(n):  # gather: the spring vector at x¹
            e = np.uint64(lo + i)
            a = edges[e, 0]
            b = edges[e, 1]
            ka = free_index[a]
            kb = free_index[b]
            dx = x0[b, 0] - x0[a, 0]
            dy = x0[b, 1] - x0[a, 1]
            dz = x0[b, 2] - x0[a, 2]
            if kb >= 0:
                dx += u[3 * kb]
                dy += u[3 * kb + 1]
                dz += u[3 * kb + 2]
            if ka >= 0:
                dx -= u[3 * ka]
                dy -= u[3 * ka + 1]
                dz -= u[3 * ka + 2]
            fs[0, e] = dx
            fs[1, e] = dy
            fs[2, e] = dz
        for i in range(n):  # arithmetic and thermal solve (vectorized)
            e = np.uint64(lo + i)
            pe = np.uint64(0) if UNIFORM else np.uint64(e)
            dx = fs[0, e]
            dy = fs[1, e]
            dz = fs[2, e]
            l1 = math.sqrt(dx * dx + dy * dy + dz * dz)
            # read unconditionally: a conditional read of len1 before its store made LLVM's
            # runtime alias check always fail (the loop ran its scalar version)
            g = theta[e] + dtheta[e] * (l1 - len1[e])
            g = g if warm else -1.0
            guess[e] = g
            len1[e] = l1
            i1 = 1.0 / l1
            dir1[0, e] = dx * i1
            dir1[1, e] = dy * i1
            dir1[2, e] = dz * i1
            la = len0[e]
            th, dth, ok = gtr_thermal_vector(la, l1, eta[e], l0[e], P, pe, alpha, g)
            theta[e] = th
            dtheta[e] = dth
            c = alpha * h * tension(la, th, l0[e], P, pe)
            fs[0, e] = c * dir0[0, e]
            fs[1, e] = c * dir0[1, e]
            fs[2, e] = c * dir0[2, e]
            code[e] = OK if ((ok != 0) & (l1 > 0.0) & (l1 < math.inf)) else NO_TEMPERATURE
        for i in range(n):  # the scalar solve where the vectorized one did not converge
            e = lo + i
            pe = np.uint64(0) if UNIFORM else np.uint64(e)
            if code[e] == OK:
                continue
            l1 = len1[e]
            if not (l1 > 0.0 and l1 < math.inf):
                code[e] = COLLAPSED
                continue
            la = len0[e]
            th, dth, ok = gtr_thermal(la, l1, eta[e], l0[e], P, pe, alpha, guess[e])
            if not ok:
                continue
            code[e] = OK
            theta[e] = th
            dtheta[e] = dth
            c = alpha * h * tension(la, th, l0[e], P, pe)
            for j in range(3):
                fs[j, e] = c * dir0[j, e]
        bad = min(bad, _first_flagged(code, lo, n, m))
    if bad < m:
        return code[bad], bad, math.inf, math.inf
    rmax = 0.0
    smax = 0.0
    for a in prange(x0.shape[0]):
        k = free_index[a]
        if k < 0:
            continue
        w = masses[a] / h
        # the node's rows and their magnitudes in registers, written once (the same sums in the
        # same order as accumulating in R, Rabs)
        inertia = w * u[3 * k + 0]
        g = alpha * h * masses[a] * gravity[0] if with_gravity else 0.0
        r0 = inertia - p[a, 0] - g
        s0 = abs(inertia) + abs(p[a, 0]) + abs(g)
        inertia = w * u[3 * k + 1]
        g = alpha * h * masses[a] * gravity[1] if with_gravity else 0.0
        r1 = inertia - p[a, 1] - g
        s1 = abs(inertia) + abs(p[a, 1]) + abs(g)
        inertia = w * u[3 * k + 2]
        g = alpha * h * masses[a] * gravity[2] if with_gravity else 0.0
        r2 = inertia - p[a, 2] - g
        s2 = abs(inertia) + abs(p[a, 2]) + abs(g)
        for j in range(inc_ptr[a], inc_ptr[a + 1]):
            e = inc_spring[j]
            sg = -inc_sign[j]
            v0 = fs[0, e]
            v1 = fs[1, e]
            v2 = fs[2, e]
            r0 += sg * v0
            s0 += abs(v0)
            r1 += sg * v1
            s1 += abs(v1)
            r2 += sg * v2
            s2 += abs(v2)
        R[3 * k + 0] = r0
        Rabs[3 * k + 0] = s0
        R[3 * k + 1] = r1
        Rabs[3 * k + 1] = s1
        R[3 * k + 2] = r2
        Rabs[3 * k + 2] = s2
        rmax = max(rmax, abs(r0))
        smax = max(smax, s0)
        rmax = max(rmax, abs(r1))
        smax = max(smax, s1)
        rmax = max(rmax, abs(r2))
        smax = max(smax, s2)
    return 0, -1, rmax, smax


def _gtr_linearize(alpha, h, l0, P, len0, theta, dtheta, jc):
    """Per-spring coefficient of the Jacobian at the last residual's point (matrix-free use):
    spring e's block is jc[e] n⁰ n¹ᵀ, jc[e] = α h F_lθ(l⁰, θ̄) dθ̄/dl¹ (m,)."""
    m = len0.shape[0]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        for i in range(min(BLOCK, m - lo)):
            e = np.uint64(lo + i)
            pe = np.uint64(0) if UNIFORM else np.uint64(e)
            jc[e] = alpha * h * d2F_dl_dtheta(len0[e], theta[e], l0[e], P, pe) * dtheta[e]


def _gtr_jacobian(free_index, masses, alpha, h, l0, P, edges, len0, dir0, dir1, theta, dtheta,
                  node_base, node_stride, spring_base, spring_stride, data):
    """Values of ∂R/∂u at the last residual's point into the CSR value array ``data``.

    ∂R_c/∂d_g = δ_cg m_c/h I + α h s_c s_g F_lθ(l⁰, θ̄) (dθ̄/dl¹) n⁰ n¹ᵀ, s_a = +1, s_b = −1."""
    data[:] = 0.0
    for a in range(free_index.shape[0]):
        k = free_index[a]
        if k < 0:
            continue
        w = masses[a] / h
        for i in range(3):
            data[node_base[k] + i * node_stride[k] + i] += w
    B = np.zeros((3, 3))
    for e in range(edges.shape[0]):
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        c = alpha * h * d2F_dl_dtheta(len0[e], theta[e], l0[e], P, pe) * dtheta[e]
        if c == 0.0:
            continue
        for i in range(3):
            for j in range(3):
                B[i, j] = c * dir0[i, e] * dir1[j, e]
        for q in range(4):
            base = spring_base[e, q]
            if base < 0:
                continue
            sign = 1.0 if (q == 0 or q == 3) else -1.0
            stride = spring_stride[e, q]
            for i in range(3):
                for j in range(3):
                    data[base + i * stride + j] += sign * B[i, j]


def _gtr_finish(x0, u, p, phi, eta, l0, P, edges, free_index, inc_ptr, inc_spring, inc_sign, masses, alpha, h, gravity,
                with_gravity, len0, dir0, len1, dir1, theta, fs, code, x_new, p_new, phi_new, eta_new):
    """The next state from converged unknowns: x¹ = x⁰ + d; Φ¹ = Φ⁰ + h θ̄;
    η¹ = α Γ(l⁰, θ̄) + (1 − α) Γ(l¹, θ̄) measured (48d); and
    p¹ = p⁰ + h [α f(x⁰, θ̄) + (1 − α) f(x¹, θ̄)], which is (48b) given (48a) and, forces being
    central pairs, conserves linear momentum to round-off whatever the solver residual.
    fs must hold the last residual's per-spring terms (that residual was evaluated at u).
    Returns (status, spring)."""
    m = edges.shape[0]
    bad = m
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        n = min(BLOCK, m - lo)
        for i in range(n):  # vectorized
            e = np.uint64(lo + i)
            pe = np.uint64(0) if UNIFORM else np.uint64(e)
            th = theta[e]
            phi_new[e] = phi[e] + h * th
            l1 = len1[e]
            eta1 = alpha * entropy(len0[e], th, l0[e], P, pe) + (1.0 - alpha) * entropy(l1, th, l0[e], P, pe)
            eta_new[e] = eta1
            th1 = temperature(l1, eta1, l0[e], P, pe)
            c1 = (1.0 - alpha) * h * tension(l1, th, l0[e], P, pe)
            fs[0, e] += c1 * dir1[0, e]  # fs holds α h T(l⁰, θ̄) n⁰ from the last residual
            fs[1, e] += c1 * dir1[1, e]
            fs[2, e] += c1 * dir1[2, e]
            code[e] = (OK if _admissible(th1) else NO_TEMPERATURE) if abs(eta1) < math.inf else NOT_FINITE
        bad = min(bad, _first_flagged(code, lo, n, m))
    if bad < m:
        return code[bad], bad
    return finish_nodes(x0, u, p, fs, edges, free_index, inc_ptr, inc_spring, inc_sign, masses, h, gravity, with_gravity,
                        3, 0, x_new, p_new)


# ---------------------------------------------------------------------------------------------
# HO4 (spec §2.2): unknowns d^½, d¹ per free node; θ⁰, θ¹ condensed per spring (θ^½ = mean).
#   R1_c = m_c (8 d^½ − d¹)_c / (3h) − (h/6) f⁰_c − p_c                                 (58a)
#   R2_c = m_c (d¹ − 2 d^½)_c / h − (h/4) f^½_c                              (57a) × h/4
#   Γ⁰ = Γ¹,  (3Γ⁰ + 4Γ^½ − Γ¹)/6 = η                                 per spring (57b), (58c)


def _ho4_derivatives(la, lh, lb, l0, P, e, t0, t1):
    """dθ⁰/dl^½, dθ⁰/dl¹, dθ¹/dl^½, dθ¹/dl¹ at a solution (θ⁰, θ¹) of (57b), (58c)."""
    th = 0.5 * (t0 + t1)
    g0 = -d2F_dtheta2(la, t0, l0, P, e)
    gh = -d2F_dtheta2(lh, th, l0, P, e)
    g1 = -d2F_dtheta2(lb, t1, l0, P, e)
    # implicit derivatives of the 2×2 system (57b), (58c) in (θ⁰, θ¹), with Γ_l = −F_lθ:
    # ∂(G1, G2)/∂l^½ = (0, 4Γ_l(lh, θ^½)/6); ∂(G1, G2)/∂l¹ = (−Γ_l(lb, θ¹), −Γ_l(lb, θ¹)/6)
    J00 = g0
    J01 = -g1
    J10 = (3.0 * g0 + 2.0 * gh) * SIXTH
    J11 = (2.0 * gh - g1) * SIXTH
    inv_det = 1.0 / (J00 * J11 - J01 * J10)
    qh = -4.0 * SIXTH * d2F_dl_dtheta(lh, th, l0, P, e)
    w1 = d2F_dl_dtheta(lb, t1, l0, P, e)
    q1a = w1
    q1b = w1 * SIXTH
    d0h = J01 * qh * inv_det
    d1h = -(J00 * qh) * inv_det
    d01 = -(J11 * q1a - J01 * q1b) * inv_det
    d11 = -(J00 * q1b - J10 * q1a) * inv_det
    return d0h, d01, d1h, d11


def _ho4_thermal(la, lh, lb, eta, l0, P, e, guess, warm):
    """θ⁰, θ¹ solving Γ(la, θ⁰) = Γ(lb, θ¹) and (3Γ(la, θ⁰) + 4Γ(lh, θ^½) − Γ(lb, θ¹))/6 = η,
    θ^½ = (θ⁰ + θ¹)/2; returns (G, θ⁰, θ¹, dθ⁰/dl^½, dθ⁰/dl¹, dθ¹/dl^½, dθ¹/dl¹, success 1 or 0).

    The unknown is the common value G = Γ⁰ = Γ¹ (so θ⁰ = θ(la, G), θ¹ = θ(lb, G) satisfy (57b)
    exactly), and (58c) becomes the scalar equation (2G + 4Γ(lh, θ^½))/6 = η, solved by Newton
    from ``guess`` when ``warm``, else from G = η. For an entropy affine in ln θ (model "hencky")
    Γ(lh, θ^½) − G does not depend on G, so one correction is exact. The scalar solve: iterates
    to convergence."""
    G = guess if (warm and abs(guess) < math.inf) else eta
    t0 = temperature(la, G, l0, P, e)
    t1 = temperature(lb, G, l0, P, e)
    if not (_usable(t0) and _usable(t1)):
        return G, t0, t1, 0.0, 0.0, 0.0, 0.0, 0
    done = False
    for _ in range(LOCAL_ITERATIONS):
        G, s0, s1, big = ho4_correct(la, lh, lb, eta, l0, P, e, G, t0, t1)
        if big <= THETA_STOP:
            # dθ = −dG/Γ_θ to second order (the neglected term is ~ big², below round-off)
            t0 *= 1.0 - s0 + 0.5 * s0 * s0
            t1 *= 1.0 - s1 + 0.5 * s1 * s1
            done = True
            break
        t0 = temperature(la, G, l0, P, e)
        t1 = temperature(lb, G, l0, P, e)
    if not (done and _usable(t0) and _usable(t1)):
        return G, t0, t1, 0.0, 0.0, 0.0, 0.0, 0
    d0h, d01, d1h, d11 = ho4_derivatives(la, lh, lb, l0, P, e, t0, t1)
    return G, t0, t1, d0h, d01, d1h, d11, 1


def _ho4_correct(la, lh, lb, eta, l0, P, e, G, t0, t1):
    """One Newton correction of the scalar equation of :func:`_ho4_thermal` (branch-free):
    (new G, the changes of ln θ⁰ and ln θ¹ it causes, the larger of their magnitudes).
    Written with few divisions: they are most of a vectorized solve's cost."""
    th = 0.5 * (t0 + t1)
    r = (2.0 * G + 4.0 * entropy(lh, th, l0, P, e)) * SIXTH - eta
    g0 = -d2F_dtheta2(la, t0, l0, P, e)  # Γ_θ, so dθ/dG = 1/Γ_θ
    gh = -d2F_dtheta2(lh, th, l0, P, e)
    g1 = -d2F_dtheta2(lb, t1, l0, P, e)
    q0 = 1.0 / (g0 * t0)
    q1 = 1.0 / (g1 * t1)
    dG = 6.0 * r / (2.0 + 2.0 * gh * (q0 * t0 + q1 * t1))
    # the change of ln θ⁰ and ln θ¹ this causes, bounded so exp() cannot overflow
    s0 = dG * q0
    s1 = dG * q1
    big = max(abs(s0), abs(s1))
    dG = dG * (MAX_LOG_STEP / big) if big > MAX_LOG_STEP else dG
    return G - dG, s0, s1, big


def _ho4_thermal_closed(A, B, C, lh, eta, l0, P, e):
    """The solution of :func:`_ho4_thermal`'s equations in closed form, for an entropy affine in
    ln θ, Γ(l, θ) = a(l) + C ln θ (LOG_AFFINE), from A = θ(l⁰, η) and B = θ(l¹, η): then
    θ(l, G) = θ(l, η) exp((G − η)/C) and Γ(l, s θ) = Γ(l, θ) + C ln s, so with S = Γ(l^½,
    (A + B)/2), Γ(l^½, θ^½) = S + G − η and (58c) reads (2G + 4(S + G − η))/6 = η: G = η +
    2(η − S)/3, θ⁰ = A E, θ¹ = B E with E = exp((G − η)/C). Returns (G, θ⁰, θ¹)."""
    G = eta + (2.0 / 3.0) * (eta - entropy(lh, 0.5 * (A + B), l0, P, e))
    E = exp_((G - eta) / C)
    return G, A * E, B * E


def _ho4_thermal_exact(la, lh, lb, eta, l0, P, e):
    """:func:`_ho4_thermal`'s returns from :func:`_ho4_thermal_closed` (LOG_AFFINE), A, B and
    C = −A F_θθ(l⁰, A) computed here (the residual kernel reads A and C from the start kernel's
    ``keep``); success unless a temperature is not admissible."""
    A = temperature(la, eta, l0, P, e)
    B = temperature(lb, eta, l0, P, e)
    G, t0, t1 = ho4_thermal_closed(A, B, -A * d2F_dtheta2(la, A, l0, P, e), lh, eta, l0, P, e)
    ok = 1 if _admissible(t0) & _admissible(t1) else 0
    d0h, d01, d1h, d11 = ho4_derivatives(la, lh, lb, l0, P, e, t0, t1)
    return G, t0, t1, d0h, d01, d1h, d11, ok


def _ho4_thermal_vector(la, lh, lb, eta, l0, P, e, guess, warm):
    """The vectorized loop's solve of :func:`_ho4_thermal`: in closed form where the model
    allows (:func:`_ho4_thermal_exact`), else VECTOR_CORRECTIONS corrections from the same start,
    the last applied to θ to second order as there; success when the last is below THETA_STOP.
    Same returns."""
    if LOG_AFFINE:
        return ho4_thermal_exact(la, lh, lb, eta, l0, P, e)
    G = guess if (warm & (abs(guess) < math.inf)) else eta
    t0 = temperature(la, G, l0, P, e)
    t1 = temperature(lb, G, l0, P, e)
    G, s0, s1, big = ho4_correct(la, lh, lb, eta, l0, P, e, G, t0, t1)
    t0 = temperature(la, G, l0, P, e)
    t1 = temperature(lb, G, l0, P, e)
    G, s0, s1, big = ho4_correct(la, lh, lb, eta, l0, P, e, G, t0, t1)
    t0 *= 1.0 - s0 + 0.5 * s0 * s0
    t1 *= 1.0 - s1 + 0.5 * s1 * s1
    ok = 1 if (big <= THETA_STOP) & _admissible(t0) & _admissible(t1) else 0
    d0h, d01, d1h, d11 = ho4_derivatives(la, lh, lb, l0, P, e, t0, t1)
    return G, t0, t1, d0h, d01, d1h, d11, ok


def _ho4_residual(x0, u, p, eta, l0, P, edges, free_index, inc_ptr, inc_spring, inc_sign, masses, h, gravity, with_gravity,
                  len0, dir0, keep, lenh, dirh, len1, dir1, th0, th1, dth, gs, warm, fs, guess, code, R, Rabs, peak,
                  springs, nodes):
    """R, Rabs (6 n_free,) at unknowns u (6 n_free,), and peak (2, n_free) each free node's largest
    |R| and Rabs (for the local steps' node selection); fills lengths/unit vectors (3, m) at x^½
    and x¹, θ⁰, θ¹ (m,), dth (4, m) = dθ⁰/dl^½, dθ⁰/dl¹, dθ¹/dl^½, dθ¹/dl¹ and gs (m,) = Γ⁰ =
    Γ¹. With ``warm``, the previous call's gs (at nearby u), moved along its length derivatives,
    seeds the thermal solves. With LOG_AFFINE (closed-form solves: no seeds) dth and gs are not
    written; the linearization and the Jacobian recompute the derivatives from the lengths and
    temperatures (they are called less often), and the solve and the force at x⁰ use what the
    start kernel kept of the step's start (``keep``, KEEP_START): T(l⁰, θ⁰) = T(l⁰, A) +
    F_lθ(l⁰) (θ⁰ − A), exact for a LOG_AFFINE model, whose tension is affine in θ.
    fs (6, m), guess, code (m,) scratch; fs holds each spring's force terms afterwards. The
    SUBSET variant computes only the springs listed in ``springs`` (int64) and the rows of the
    free nodes listed in ``nodes`` (int64), in the same arithmetic and order as a full call:
    after u changed at a few nodes, the listed springs are those at these nodes and the listed
    nodes those at these springs' ends, and the rest keep the values of the last call (in the
    full kernel both lists are empty and unused). Returns (status, spring, max |R|, max Rabs),
    the maxima over the rows computed."""
    none = edges.shape[0]
    m = listed_count(springs, none)
    bad = none
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        n = min(BLOCK, m - lo)
        for i in range(n):  # gather: the spring vectors at x^½ and x¹
            e = np.uint64(listed(springs, lo + i))
            a = edges[e, 0]
            b = edges[e, 1]
            ka = free_index[a]
            kb = free_index[b]
            ex = x0[b, 0] - x0[a, 0]
            ey = x0[b, 1] - x0[a, 1]
            ez = x0[b, 2] - x0[a, 2]
            hx = ex
            hy = ey
            hz = ez
            if kb >= 0:
                hx += u[6 * kb]
                hy += u[6 * kb + 1]
                hz += u[6 * kb + 2]
                ex += u[6 * kb + 3]
                ey += u[6 * kb + 4]
                ez += u[6 * kb + 5]
            if ka >= 0:
                hx -= u[6 * ka]
                hy -= u[6 * ka + 1]
                hz -= u[6 * ka + 2]
                ex -= u[6 * ka + 3]
                ey -= u[6 * ka + 4]
                ez -= u[6 * ka + 5]
            fs[0, e] = hx
            fs[1, e] = hy
            fs[2, e] = hz
            fs[3, e] = ex
            fs[4, e] = ey
            fs[5, e] = ez
        for i in range(n):  # arithmetic and thermal solve (vectorized)
            e = np.uint64(listed(springs, lo + i))
            pe = np.uint64(0) if UNIFORM else np.uint64(e)
            hx = fs[0, e]
            hy = fs[1, e]
            hz = fs[2, e]
            ex = fs[3, e]
            ey = fs[4, e]
            ez = fs[5, e]
            lh = math.sqrt(hx * hx + hy * hy + hz * hz)
            l1 = math.sqrt(ex * ex + ey * ey + ez * ez)
            la = len0[e]
            rest = l0[e]
            if not LOG_AFFINE:  # a seed (the closed form needs none): G = Γ(l⁰, θ⁰) moved along dG/dl
                g = gs[e] - d2F_dtheta2(la, th0[e], rest, P, pe) * (dth[0, e] * (lh - lenh[e]) + dth[1, e] * (l1 - len1[e]))
                guess[e] = g
            lenh[e] = lh
            ih = 1.0 / lh
            dirh[0, e] = hx * ih
            dirh[1, e] = hy * ih
            dirh[2, e] = hz * ih
            len1[e] = l1
            i1 = 1.0 / l1
            dir1[0, e] = ex * i1
            dir1[1, e] = ey * i1
            dir1[2, e] = ez * i1
            if LOG_AFFINE:
                A = keep[0, e]
                G, t0, t1 = ho4_thermal_closed(A, temperature(l1, eta[e], rest, P, pe), keep[3, e], lh, eta[e],
                                               rest, P, pe)
                ok = 1 if _admissible(t0) & _admissible(t1) else 0
                c0 = h / 6.0 * (keep[1, e] + keep[2, e] * (t0 - A))
            else:
                G, t0, t1, d0h, d01, d1h, d11, ok = ho4_thermal_vector(la, lh, l1, eta[e], rest, P, pe, g, warm)
                # the warm seed and its derivatives (else recomputed where needed)
                gs[e] = G
                dth[0, e] = d0h
                dth[1, e] = d01
                dth[2, e] = d1h
                dth[3, e] = d11
                c0 = h / 6.0 * tension(la, t0, rest, P, pe)
            th0[e] = t0
            th1[e] = t1
            ch = h / 4.0 * tension(lh, 0.5 * (t0 + t1), rest, P, pe)
            fs[0, e] = c0 * dir0[0, e]
            fs[1, e] = c0 * dir0[1, e]
            fs[2, e] = c0 * dir0[2, e]
            fs[3, e] = ch * dirh[0, e]
            fs[4, e] = ch * dirh[1, e]
            fs[5, e] = ch * dirh[2, e]
            lok = (lh > 0.0) & (lh < math.inf) & (l1 > 0.0) & (l1 < math.inf)
            code[e] = OK if ((ok != 0) & lok) else NO_TEMPERATURE
        for i in range(n):  # the scalar solve where the vectorized one did not converge
            e = listed(springs, lo + i)
            pe = np.uint64(0) if UNIFORM else np.uint64(e)
            if code[e] == OK:
                continue
            lh = lenh[e]
            l1 = len1[e]
            if not (lh > 0.0 and lh < math.inf and l1 > 0.0 and l1 < math.inf):
                code[e] = COLLAPSED
                continue
            la = len0[e]
            seed = guess[e]
            if LOG_AFFINE:  # no seed was written: start from η
                seed = eta[e]
            G, t0, t1, d0h, d01, d1h, d11, ok = ho4_thermal(la, lh, l1, eta[e], l0[e], P, pe, seed, warm)
            if not LOG_AFFINE:
                gs[e] = G
            if not ok:
                continue
            code[e] = OK
            th0[e] = t0
            th1[e] = t1
            if not LOG_AFFINE:
                dth[0, e] = d0h
                dth[1, e] = d01
                dth[2, e] = d1h
                dth[3, e] = d11
            c0 = h / 6.0 * tension(la, t0, l0[e], P, pe)
            ch = h / 4.0 * tension(lh, 0.5 * (t0 + t1), l0[e], P, pe)
            for j in range(3):
                fs[j, e] = c0 * dir0[j, e]
                fs[3 + j, e] = ch * dirh[j, e]
        bad = min(bad, first_flagged_listed(code, springs, lo, n, none))
    if bad < none:
        return code[bad], bad, math.inf, math.inf
    rmax = 0.0
    smax = 0.0
    for j_node in prange(listed_count(nodes, x0.shape[0])):
        a = listed(nodes, j_node)
        k = free_index[a]
        if k < 0:
            continue
        w = masses[a] / h
        # the node's rows and their magnitudes in registers, written once (the same sums in the
        # same order as accumulating in R, Rabs)
        g0 = h / 6.0 * masses[a] * gravity[0] if with_gravity else 0.0
        gh = h / 4.0 * masses[a] * gravity[0] if with_gravity else 0.0
        i1 = w * (8.0 * u[6 * k + 0] - u[6 * k + 3]) / 3.0
        i2 = w * (u[6 * k + 3] - 2.0 * u[6 * k + 0])
        r0 = i1 - p[a, 0] - g0
        s0 = abs(i1) + abs(p[a, 0]) + abs(g0)
        r3 = i2 - gh
        s3 = abs(i2) + abs(gh)
        g0 = h / 6.0 * masses[a] * gravity[1] if with_gravity else 0.0
        gh = h / 4.0 * masses[a] * gravity[1] if with_gravity else 0.0
        i1 = w * (8.0 * u[6 * k + 1] - u[6 * k + 4]) / 3.0
        i2 = w * (u[6 * k + 4] - 2.0 * u[6 * k + 1])
        r1 = i1 - p[a, 1] - g0
        s1 = abs(i1) + abs(p[a, 1]) + abs(g0)
        r4 = i2 - gh
        s4 = abs(i2) + abs(gh)
        g0 = h / 6.0 * masses[a] * gravity[2] if with_gravity else 0.0
        gh = h / 4.0 * masses[a] * gravity[2] if with_gravity else 0.0
        i1 = w * (8.0 * u[6 * k + 2] - u[6 * k + 5]) / 3.0
        i2 = w * (u[6 * k + 5] - 2.0 * u[6 * k + 2])
        r2 = i1 - p[a, 2] - g0
        s2 = abs(i1) + abs(p[a, 2]) + abs(g0)
        r5 = i2 - gh
        s5 = abs(i2) + abs(gh)
        for j in range(inc_ptr[a], inc_ptr[a + 1]):
            e = inc_spring[j]
            sg = -inc_sign[j]
            v0 = fs[0, e]
            v1 = fs[1, e]
            v2 = fs[2, e]
            v3 = fs[3, e]
            v4 = fs[4, e]
            v5 = fs[5, e]
            r0 += sg * v0
            s0 += abs(v0)
            r1 += sg * v1
            s1 += abs(v1)
            r2 += sg * v2
            s2 += abs(v2)
            r3 += sg * v3
            s3 += abs(v3)
            r4 += sg * v4
            s4 += abs(v4)
            r5 += sg * v5
            s5 += abs(v5)
        R[6 * k + 0] = r0
        Rabs[6 * k + 0] = s0
        R[6 * k + 1] = r1
        Rabs[6 * k + 1] = s1
        R[6 * k + 2] = r2
        Rabs[6 * k + 2] = s2
        R[6 * k + 3] = r3
        Rabs[6 * k + 3] = s3
        R[6 * k + 4] = r4
        Rabs[6 * k + 4] = s4
        R[6 * k + 5] = r5
        Rabs[6 * k + 5] = s5
        big = max(max(abs(r0), abs(r1)), max(max(abs(r2), abs(r3)), max(abs(r4), abs(r5))))
        if not (abs(r0) + abs(r1) + abs(r2) + abs(r3) + abs(r4) + abs(r5) < math.inf):
            big = math.inf  # a NaN row (max() passes over NaN) shows in the norm as not finite
        scale = max(max(s0, s1), max(max(s2, s3), max(s4, s5)))
        peak[0, k] = big
        peak[1, k] = scale
        rmax = max(rmax, big)
        smax = max(smax, scale)
    return 0, -1, rmax, smax


def _ho4_temperature_derivatives(dth, e, la, lh, lb, l0, P, pe, t0, t1):
    """dθ⁰/dl^½, dθ⁰/dl¹, dθ¹/dl^½, dθ¹/dl¹ of spring e at the last residual's point: computed
    again where the residual does not store them (LOG_AFFINE), else read from dth (4, m)."""
    if LOG_AFFINE:
        return ho4_derivatives(la, lh, lb, l0, P, pe, t0, t1)
    return dth[0, e], dth[1, e], dth[2, e], dth[3, e]


def _ho4_linearize(h, l0, P, len0, lenh, len1, th0, th1, dth, jc):
    """Per-spring coefficients of the Jacobian at the last residual's point (matrix-free use),
    jc (5, m): spring e's block (rows R1, R2; columns d^½, d¹) is
      [[a₁ n⁰ n^½ᵀ, a₂ n⁰ n¹ᵀ], [(k − t) n^½ n^½ᵀ + t I, c n^½ n¹ᵀ]],   jc[:, e] = (a₁, a₂, k − t, t, c)
    with the terms of :func:`_ho4_jacobian`."""
    m = len0.shape[0]
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        for i in range(min(BLOCK, m - lo)):
            e = np.uint64(lo + i)
            pe = np.uint64(0) if UNIFORM else np.uint64(e)
            t0 = th0[e]
            t1 = th1[e]
            th = 0.5 * (t0 + t1)
            lh = lenh[e]
            rest = l0[e]
            d0h, d01, d1h, d11 = ho4_temperature_derivatives(dth, e, len0[e], lh, len1[e], rest, P, pe, t0, t1)
            c0 = h / 6.0 * d2F_dl_dtheta(len0[e], t0, rest, P, pe)
            flt = d2F_dl_dtheta(lh, th, rest, P, pe)
            axial = h / 4.0 * (d2F_dl2(lh, th, rest, P, pe) + flt * 0.5 * (d0h + d1h))
            lateral = h / 4.0 * tension(lh, th, rest, P, pe) / lh
            jc[0, e] = c0 * d0h
            jc[1, e] = c0 * d01
            jc[2, e] = axial - lateral
            jc[3, e] = lateral
            jc[4, e] = h / 4.0 * flt * 0.5 * (d01 + d11)


def _ho4_jacobian(free_index, masses, h, l0, P, edges, len0, dir0, lenh, dirh, len1, dir1, th0, th1, dth,
                  node_base, node_stride, spring_base, spring_stride, data):
    """Values of ∂R/∂u at the last residual's point into the CSR value array ``data``.

    Node block (rows R1, R2; columns d^½, d¹): m/h [[8/3, −1/3], [−2, 1]] ⊗ I. Spring block,
    added with sign s_c s_g (s_a = +1, s_b = −1):
      ∂R1/∂x^σ = h/6 F_lθ(l⁰, θ⁰) dθ⁰/dl^σ n⁰ n^σᵀ
      ∂R2/∂x^½ = h/4 [(F_ll + F_lθ dθ^½/dl^½) n^½ n^½ᵀ + T/l (I − n^½ n^½ᵀ)] at (l^½, θ^½)
      ∂R2/∂x¹  = h/4 F_lθ(l^½, θ^½) dθ^½/dl¹ n^½ n¹ᵀ."""
    data[:] = 0.0
    for a in range(free_index.shape[0]):
        k = free_index[a]
        if k < 0:
            continue
        w = masses[a] / h
        base = node_base[k]
        st = node_stride[k]
        for i in range(3):
            data[base + i * st + i] += 8.0 / 3.0 * w
            data[base + i * st + 3 + i] += -w / 3.0
            data[base + (3 + i) * st + i] += -2.0 * w
            data[base + (3 + i) * st + 3 + i] += w
    B = np.zeros((6, 6))
    for e in range(edges.shape[0]):
        pe = np.uint64(0) if UNIFORM else np.uint64(e)
        t0 = th0[e]
        th = 0.5 * (t0 + th1[e])
        lh = lenh[e]
        d0h, d01, d1h, d11 = ho4_temperature_derivatives(dth, e, len0[e], lh, len1[e], l0[e], P, pe, t0, th1[e])
        c0 = h / 6.0 * d2F_dl_dtheta(len0[e], t0, l0[e], P, pe)
        flt = d2F_dl_dtheta(lh, th, l0[e], P, pe)
        dthh_h = 0.5 * (d0h + d1h)
        dthh_1 = 0.5 * (d01 + d11)
        axial = h / 4.0 * (d2F_dl2(lh, th, l0[e], P, pe) + flt * dthh_h)
        lateral = h / 4.0 * tension(lh, th, l0[e], P, pe) / lh
        c21 = h / 4.0 * flt * dthh_1
        for i in range(3):
            for j in range(3):
                B[i, j] = c0 * d0h * dir0[i, e] * dirh[j, e]
                B[i, 3 + j] = c0 * d01 * dir0[i, e] * dir1[j, e]
                nn = dirh[i, e] * dirh[j, e]
                B[3 + i, j] = (axial - lateral) * nn + (lateral if i == j else 0.0)
                B[3 + i, 3 + j] = c21 * dirh[i, e] * dir1[j, e]
        for q in range(4):
            base = spring_base[e, q]
            if base < 0:
                continue
            sign = 1.0 if (q == 0 or q == 3) else -1.0
            stride = spring_stride[e, q]
            for i in range(6):
                for j in range(6):
                    data[base + i * stride + j] += sign * B[i, j]


def _ho4_finish(x0, u, p, phi, eta, l0, P, edges, free_index, inc_ptr, inc_spring, inc_sign, masses, h, gravity, with_gravity,
                len0, dir0, lenh, dirh, len1, dir1, th0, th1, fs, code, x_new, p_new, phi_new, eta_new):
    """The next state from converged unknowns: x¹ = x⁰ + d¹; Φ¹ = Φ⁰ + h (θ⁰ + θ¹)/2;
    η¹ = (−Γ⁰ + 4Γ^½ + 3Γ¹)/6 measured (58d); and p¹ = p⁰ + h (f⁰ + 4 f^½ + f¹)/6, which is
    (58b) given (58a) and (57a) and conserves linear momentum to round-off whatever the solver
    residual. fs must hold the last residual's per-spring terms (that residual was evaluated at
    u). Returns (status, spring)."""
    m = edges.shape[0]
    bad = m
    for blk in prange((m + BLOCK - 1) // BLOCK):
        lo = blk * BLOCK
        n = min(BLOCK, m - lo)
        for i in range(n):  # vectorized
            e = np.uint64(lo + i)
            pe = np.uint64(0) if UNIFORM else np.uint64(e)
            t0 = th0[e]
            t1 = th1[e]
            th = 0.5 * (t0 + t1)
            phi_new[e] = phi[e] + h * th
            rest = l0[e]
            l1 = len1[e]
            G0 = entropy(len0[e], t0, rest, P, pe)
            Gh = entropy(lenh[e], th, rest, P, pe)
            G1 = entropy(l1, t1, rest, P, pe)
            eta1 = (-G0 + 4.0 * Gh + 3.0 * G1) / 6.0
            eta_new[e] = eta1
            th_end = temperature(l1, eta1, rest, P, pe)
            c1 = h / 6.0 * tension(l1, t1, rest, P, pe)
            # fs holds (h/6) T⁰ n⁰ and (h/4) T^½ n^½ from the last residual
            fs[0, e] = fs[0, e] + 8.0 / 3.0 * fs[3, e] + c1 * dir1[0, e]
            fs[1, e] = fs[1, e] + 8.0 / 3.0 * fs[4, e] + c1 * dir1[1, e]
            fs[2, e] = fs[2, e] + 8.0 / 3.0 * fs[5, e] + c1 * dir1[2, e]
            code[e] = (OK if _admissible(th_end) else NO_TEMPERATURE) if abs(eta1) < math.inf else NOT_FINITE
        bad = min(bad, _first_flagged(code, lo, n, m))
    if bad < m:
        return code[bad], bad
    return finish_nodes(x0, u, p, fs, edges, free_index, inc_ptr, inc_spring, inc_sign, masses, h, gravity, with_gravity,
                        6, 3, x_new, p_new)
