"""The implicit integrators' shared kernels and their registry: the nodes' part of the finish
kernels, the small helpers of the per-spring thermal solves, and :func:`implicit_kernels`, which
compiles a registered scheme's kernels for one model (:mod:`.gtr_alpha`, docs/theory.md §2.1; :mod:`thermonet.implicit.ho4.kernels`,
docs/theory.md §2.2) with the start kernel of :mod:`thermonet.implicit.core.start` (geometry at x⁰, explicit forces, the
predictor).

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
flagged and redone by the scalar solve (iterate to convergence, report the failure) in a third
loop over the block. For the shipped models one correction is exact (the second confirms it),
so the fallback is for custom models and bad states.

Kernels take records (:mod:`thermonet.implicit.core.records`): the topology, the spring parameters, the node
data, the step's start, the scheme's work record (per-spring unknowns and scratch), the
residual's arrays; each kernel unpacks them by position, in their fields' order, at its top. Per-spring arrays are component-major, (k, m) (``dir0[i, e]``), so that the
vectorized loop reads and writes unit-stride rows. Indices are read as unsigned in the spring
passes.

Residual rows are in momentum units. Next to the residual ``R`` a kernel fills ``Rabs``, the sum
of the magnitudes of the terms of each row, so the Newton test can judge ``|R|`` against the size
of what cancelled in it (its round-off floor is then a few ulps). The residual kernels return
max |R| and max Rabs too.

The Newton matrix of every scheme is ``J = D + Σ_e (spring e's block)``, ``D`` the nodal inertia
block and spring e = (a, b) adding ``s_c s_g B_e`` to block (c, g), s_a = +1, s_b = −1. So
``(J v)_c = D_c v_c + s_c Σ_e B_e (v_a − v_b)``: a scheme's matrix-free sweep is one pass over
the springs (``B_e`` from a few per-spring coefficients, ``jc``, and the unit vectors the
residual stored) and one gather per node, a fraction of a residual's cost. A sweep computes the
linear residual ``r = R − J du`` and then ``du += D⁻¹ r`` (r written out only by a sweep that
does not update du: a product for GMRES): Richardson's iteration preconditioned by the inertia,
which dominates J for steps below the explicit stability limit (the contraction per sweep is
about h² times the largest stiffness over mass; measured ≈ 0.02–0.05 on the benchmark lattices
at h = 0.01). Its scratch is ``work.start.sweep`` (m, B), spring-major (the node gather reads a
spring's B values from one cache line).

Per-spring Jacobian blocks are scattered into a CSR value array at the places of
:class:`~thermonet.implicit.core.records.BlockPlaces`. Status codes returned by residual and finish kernels:
0 fine, 1 a spring collapsed (length ≤ 0 or not finite), 2 no positive finite temperature solves
the spring's thermal equations, 3 a non-finite momentum or entropy; with the spring's index.

Adding a scheme: a module with its templates and a ``build(ns, tag, ptag, parallel)`` that
specializes them, registered with :func:`register_scheme`; its integrator module holds the
stepper (see ``implicit/core/stepper.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .status import (BLOCK, COLLAPSED, NO_TEMPERATURE, NOT_FINITE, OK, STATUS_TEXT,  # noqa: F401 (re-exported)
                            _admissible, _first_flagged)
from .start import _adiabatic_stiffness, _start, _start_springs
from ...kernels.specialize import model_fingerprint, model_namespace, specialize, specialize_by_content

# Bound per model by specialize(); listed so the templates read as ordinary code.
temperature = tension = d2F_dl2 = d2F_dl_dtheta = d2F_dtheta2 = None
#: the model's entropy is affine in ln θ (Model.entropy_log_affine): HO4's thermal solve in closed form
LOG_AFFINE = False
#: the time derivatives of the acceleration the start kernel's predictor uses (ImplicitStepper.rate)
RATE = 0
#: the start kernel keeps, per spring, what a scheme's residual reads of the step's start (a
#: scheme registered with ``keeps_start`` and a LOG_AFFINE model; see ho4.thermal._ho4_thermal_closed)
KEEP_START = False
#: rows of the start kernel's ``keep`` (4, m): θ(l⁰, η), T(l⁰, θ(l⁰, η)), F_lθ(l⁰), C
KEEP_ROWS = 4
#: every spring has the same parameters: P is the shared (k, 1) column of System.kernel_parameters,
#: read at column 0 (``pe``) and not streamed per spring
UNIFORM = False
#: the model gives ``energy_quotient`` (Model doc): EM2's discrete gradient in closed form
EXACT_QUOTIENT = False
#: the model's temperature may reach 0 (Model.temperature_can_vanish): a kernel that does not
#: otherwise need θ at a trial length computes it to check it
CAN_VANISH = True

_CACHE: dict = {}
_SCHEMES: dict = {}
#: the kernels' jit options. Without Numba's runtime (NRT) no reference counts are kept: with it,
#: each array that an inlined row or spring function takes is increfed and decrefed at every
#: call, which Numba's pruning keeps wherever that function has a loop or branches of its own
#: (the node rows of a sweep: 80 ns per node, 10× their arithmetic). So the kernels allocate
#: nothing (scratch comes in their records); specialize() keeps NRT for the parallel ones.
OPTIONS = dict(cache=True, error_model="numpy", boundscheck=False, _nrt=False)
INLINE = dict(inline="always", error_model="numpy", boundscheck=False, _nrt=False)

#: a per-spring Newton solve stops after a correction of ln θ this small: its error is then of
#: the order of the correction squared (quadratic convergence), below round-off
THETA_STOP = 1e-9
LOCAL_ITERATIONS = 60
#: Newton corrections of a vectorized thermal solve (warm-started: the first one is exact or
#: leaves an error ~ its square; the second must then be below THETA_STOP)
VECTOR_CORRECTIONS = 2


class ImplicitKernels:
    """The compiled kernels of one scheme for one model (attributes: ``start``, ``keep_start``,
    whether the start kernel fills ``work.start.keep`` (KEEP_ROWS, m), and the scheme's own:
    ``residual``, ``linearize``, ``jacobian``, ``finish``, ``sweep``, the per-spring thermal
    solves ``thermal`` and ``thermal_vector``, and any others the scheme builds)."""

    def __init__(self, **kernels):
        self.__dict__.update(kernels)


def register_scheme(name: str, build, keeps_start: bool = False, extrapolates: bool = False) -> None:
    """Make scheme ``name`` known to :func:`implicit_kernels`. ``build(ns, tag, ptag, parallel)``
    returns a dict of its compiled kernels, specializing its templates with the model namespace
    ``ns`` (which it may extend) and the cache tags ``tag`` (model) and ``ptag`` (model and
    threading); ``keeps_start``: the start kernel keeps per spring what the scheme's residual
    reads of the step's start (KEEP_START), for LOG_AFFINE models; ``extrapolates``: its
    predictor (rate 2) extrapolates from the previous step's stage acceleration (EXTRAPOLATE,
    :mod:`thermonet.implicit.core.start`; StartWork.history)."""
    _SCHEMES[name] = (build, bool(keeps_start), bool(extrapolates))


def implicit_kernels(model, scheme: str, parallel: bool = False, uniform: bool = False, rate: int = 0) -> ImplicitKernels:
    """Kernels for ``scheme`` ("gtr" or "ho4", or another registered one) compiled for ``model``
    (cached on disk); the residual, linearization, start and finish kernels multi-threaded when
    ``parallel``; reading the parameters as one shared (k, 1) column when ``uniform``
    (System.kernel_parameters); the start kernel's predictor with the acceleration's first
    ``rate`` time derivatives (a compile-time constant: the spring loops then carry no branches
    they do not take)."""
    key = (scheme, model_fingerprint(model), bool(parallel), bool(uniform), int(rate))
    if key not in _CACHE:
        if scheme not in _SCHEMES:
            raise ValueError(f"unknown implicit scheme {scheme!r}; known: {', '.join(sorted(_SCHEMES))}")
        build, keeps_start, extrapolates = _SCHEMES[scheme]
        tag = f"{model.name}_{key[1]}{'_uniform' if uniform else ''}"
        ptag = f"{tag}_{'par' if parallel else 'ser'}"
        ns = model_namespace(model)
        ns["RATE"] = int(rate)
        ns["LOG_AFFINE"] = bool(getattr(model, "entropy_log_affine", False))
        ns["KEEP_START"] = keeps_start and ns["LOG_AFFINE"]
        ns["UNIFORM"] = bool(uniform)
        ns["EXTRAPOLATE"] = extrapolates and rate == 2
        ns["EXACT_QUOTIENT"] = getattr(model, "energy_quotient", None) is not None
        ns["CAN_VANISH"] = bool(getattr(model, "temperature_can_vanish", False))
        ns["energy_quotient"] = model.energy_quotient if ns["EXACT_QUOTIENT"] else _no_energy_quotient
        ns["adiabatic_stiffness"] = specialize(_adiabatic_stiffness, tag, ns, **INLINE)
        # (its spring blocks: serial, shared by the serial and the threaded start kernels)
        ns["start_springs"] = specialize_by_content(_start_springs, f"{tag}_rate{int(rate)}", ns, **OPTIONS)
        start = specialize(_start, f"{ptag}_rate{int(rate)}{'_keep' if ns['KEEP_START'] else ''}"
                           f"{'_extrapolate' if ns['EXTRAPOLATE'] else ''}", ns, parallel=parallel, **OPTIONS)
        ns["finish_nodes"] = specialize(_finish_nodes, ptag, ns, parallel=parallel, **OPTIONS)
        _CACHE[key] = ImplicitKernels(start=start, keep_start=ns["KEEP_START"], **build(ns, tag, ptag, parallel))
    return _CACHE[key]


@njit(cache=True, inline="always")
def _no_energy_quotient(l, l1, eta, theta, T, l0, P, e):
    """Stands in for a model without ``energy_quotient`` (its kernels never call it)."""
    return math.nan, math.nan


# ---------------------------------------------------------------------------------------------
# helpers of the per-spring solves and spring passes

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
def scatter_spring_block(data, places, e, B, b):
    """Add spring e's Jacobian block B[:b, :b] into the CSR values ``data`` at its four places
    (BlockPlaces), with sign s_c s_g (s_a = +1, s_b = −1); none where an end is anchored."""
    node_base, node_stride, spring_base, spring_stride, block = places
    for q in range(4):
        base = spring_base[e, q]
        if base < 0:
            continue
        sign = 1.0 if (q == 0 or q == 3) else -1.0
        stride = spring_stride[e, q]
        for i in range(b):
            for j in range(b):
                data[base + i * stride + j] += sign * B[i, j]


# Every kernel below is two loops, each parallel when compiled with parallel=True: a spring
# loop (over blocks of springs) writes per-spring results (lengths, temperatures, the spring's
# force contribution ``fs``) and a node loop gathers them over the node's incident springs (CSR
# ``inc_ptr``/``inc_spring``). No two threads write the same element, each node sums its springs
# in a fixed order, and the blocks do not depend on the number of threads, so neither do the
# results. A spring loop cannot return early: a failing spring stores its status in ``code``
# and the smallest failing index is kept by a min-reduction. (The schemes' kernels are built the
# same way.)


def _finish_nodes(step, topo, node, fs, u, stride, offset, new):
    """The nodes' part of every finish kernel, into ``new`` (StateArrays): x¹ = x⁰ + u[stride k +
    offset + i] for free node k, p¹ = p⁰ (+ h m g) − Σ± fs over the incident springs (fs: the
    per-spring impulses of the step, (≥ 3, m)). Returns (status, −1)."""
    x0, p, eta, h = step
    edges, free_index, ends, inc_ptr, inc_spring, inc_sign = topo
    masses, inv_mass, anchored, gravity, with_gravity, reference = node
    x_new, p_new, phi_new, eta_new = new
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
