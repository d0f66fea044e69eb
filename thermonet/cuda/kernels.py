"""CUDA kernels of one kick/drift stage and of the diagnostics sums, compiled per model.

The stage is :mod:`thermonet.kernels.splitting`'s, as two launches:

1. :func:`_spring_kernel`, one thread per spring e: ``s[e] = T/l`` at x and ``Φ[e] += k h θ``
   (the two kicks that meet at a step boundary as two separate additions, as on the CPU);
2. :func:`_node_kernel`, one thread per node a: gathers ``f_a = Σ s_e (x_b − x_a)`` over its
   CSR incidence list in the CPU's order, kicks ``p`` and drifts into a second position buffer
   (other threads still read the old one).

No atomics: every spring and node is written by one thread with the CPU's summation order, so a
step differs from the CPU's only where the GPU compiler contracts ``a*b + c`` into one fused
multiply-add (round-off; the entropy η is never written, momentum sums cancel as on the CPU).

Like :func:`thermonet.kernels.specialize.specialize`, a template calls the model's functions by
global name (``temperature``, ``tension``, ...) and is rebound per model. On a GPU those globals
are the model's own ``@njit`` functions, which numba-cuda recompiles as device functions
(``@njit`` helpers they call, and ``@intrinsic`` ones such as :mod:`thermonet.kernels.fastmath`,
included), so a user model written the documented way runs unchanged. Under the simulator the
kernels run as Python and receive simulator arrays, which compiled ``@njit`` functions cannot
take: there the globals are thin adapters passing the underlying NumPy array instead.

Diagnostics: each sum kernel runs a fixed grid (:data:`REDUCE_BLOCKS` blocks of
:data:`REDUCE_THREADS` threads) with a grid-stride loop and a shared-memory tree per block; :func:`_finish_kernel`
reduces the per-block partials in one block. The order is fixed by the launch, so sums are
reproducible from run to run, but differ from the CPU's sequential sums in their last bits.
"""

from __future__ import annotations

import math

import numpy as np
from numba import cuda, float64, njit

from ..kernels.specialize import model_fingerprint, model_namespace, rebind
from . import simulator_enabled

# Bound per model by cuda_kernels(); see thermonet.kernels.splitting for their meaning.
temperature = tension = internal_energy = free_energy = None
THERMAL = True
REFERENCE_TEMPERATURE = 0
UNIFORM = False
#: threads per block of the stage kernels. The simulator runs each block as Python threads, and
#: its cost grows with blocks and with barriers: few blocks there, tiny reduction trees.
THREADS = 256
SIMULATOR_THREADS = 32
#: threads per block of the diagnostics sums, a compile-time constant of their shared-memory trees
#: (a power of two), and their (grid-stride) blocks
REDUCE_THREADS = 256
REDUCE_BLOCKS = 256
SIMULATOR_REDUCE_THREADS = 4
SIMULATOR_REDUCE_BLOCKS = 2

#: columns of the spring sums and the operation reducing each: 0 sum, 1 min, 2 max
SPRING_SUMS = ("internal", "entropy", "theta_min", "theta_max")
SPRING_OPS = (0, 0, 1, 2)
NODE_SUMS = ("kinetic", "potential", "px", "py", "pz", "Lx", "Ly", "Lz")
NODE_OPS = (0,) * 8

_CACHE: dict = {}


class CudaKernels:
    """The compiled kernels of one model variant and their launch geometry."""

    def __init__(self, spring, node, steps, spring_sums, node_sums, finish, threads, reduce_threads, reduce_blocks):
        self.spring, self.node, self.steps = spring, node, steps
        self.spring_sums, self.node_sums, self.finish = spring_sums, node_sums, finish
        self.threads, self.reduce_threads, self.reduce_blocks = threads, reduce_threads, reduce_blocks

    def blocks(self, n: int) -> int:
        """Blocks of one-thread-per-item launches over n items."""
        return (n + self.threads - 1) // self.threads


def cuda_kernels(model, thermal: bool = True, uniform: bool = False) -> CudaKernels:
    """The CUDA kernels for ``model`` (purely mechanical when not ``thermal``; parameters shared
    by all springs, a ``(k, 1)`` array, when ``uniform``: see
    :func:`thermonet.kernels.splitting.kernel_parameters`)."""
    sim = simulator_enabled()
    key = (model_fingerprint(model), bool(thermal), bool(uniform), sim)
    if key not in _CACHE:
        ns = model_namespace(model)
        if sim:
            ns = {name: _simulator_adapter(fn) for name, fn in ns.items()}
        reduce_threads = SIMULATOR_REDUCE_THREADS if sim else REDUCE_THREADS
        ns.update(THERMAL=bool(thermal), UNIFORM=bool(uniform), REDUCE_THREADS=reduce_threads,
                  REFERENCE_TEMPERATURE=model.parameter_index(model.reference_temperature))
        tag = (f"{model.name}_{key[0]}_{'thermal' if thermal else 'mech'}{'_uniform' if uniform else ''}"
               f"_r{reduce_threads}")
        jit = cuda.jit if sim else cuda.jit(cache=True)
        inline = (lambda fn: fn) if sim else njit(inline="always")
        for name, template in _SHARED:  # in order: later ones call earlier ones
            ns[name] = inline(rebind(template, tag, ns))  # shared by the two-launch and the fused path

        def compile_(template):
            return jit(rebind(template, tag, ns))

        _CACHE[key] = CudaKernels(
            compile_(_spring_kernel), compile_(_node_kernel), compile_(_steps_kernel), compile_(_spring_sums_kernel),
            compile_(_node_sums_kernel), compile_(_finish_kernel), SIMULATOR_THREADS if sim else THREADS,
            reduce_threads, SIMULATOR_REDUCE_BLOCKS if sim else REDUCE_BLOCKS)
    return _CACHE[key]


def _simulator_adapter(fn):
    """``fn`` callable from simulated kernel code: its array argument P as the NumPy array."""
    def call(l, s, l0, P, e):
        return fn(l, s, l0, np.asarray(P), e)

    call.__name__ = getattr(fn, "__name__", "model_function")
    return call


# ----------------------------------------------------------------------------------------------
# one stage


def _spring_kernel(x, eta, l0, P, edges, s, phi, phi_h1, phi_h2, track_phi):
    """Thread e: :func:`_spring_update` of spring e."""
    e = cuda.grid(1)
    if e < edges.shape[0]:
        _spring_update(e, x, eta, l0, P, edges, s, phi, phi_h1, phi_h2, track_phi)


def _node_kernel(x, x_new, p, s, inc_ptr, inc_spring, inc_other, masses, inv_mass, anchored,
                 kick1, kick2, drift, with_force, gravity, with_gravity):
    """Thread a: :func:`_node_update` of node a."""
    a = cuda.grid(1)
    if a < x.shape[0]:
        _node_update(a, x, x_new, p, s, inc_ptr, inc_spring, inc_other, masses, inv_mass, anchored,
                     kick1, kick2, drift, with_force, gravity, with_gravity)


def _steps_kernel(x, x_buf, p, eta, l0, P, edges, s, phi, inc_ptr, inc_spring, inc_other, masses, inv_mass,
                  anchored, gravity, with_gravity, kicks, drifts, h, n_steps, track_phi):
    """``n_steps`` whole steps in one cooperative launch: every stage's spring pass and node pass
    over grid-stride loops, separated by grid-wide barriers, in the order and with the
    coefficients of :meth:`~thermonet.cuda.stepper.CudaSplittingStepper.advance`'s two-launch
    path (the same per-spring and per-node updates, so the same numbers). Positions alternate
    between ``x`` and ``x_buf`` stage by stage; the caller counts the stages to know which holds
    the result. kicks: (d+1,), drifts: (d,) coefficients of the splitting.
    """
    grid = cuda.cg.this_grid()
    first = cuda.grid(1)
    stride = cuda.gridsize(1)
    n_drifts = drifts.shape[0]
    pending = 0.0
    parity = 0
    for step in range(n_steps + 1):
        for i in range(n_drifts):
            if step < n_steps:
                k1 = pending if i == 0 else 0.0
                k2 = kicks[i]
                d = drifts[i]
            elif i == 0 and pending != 0.0:  # after the last step: its closing kick
                k1 = 0.0
                k2 = pending
                d = 0.0
            else:
                break
            with_force = k1 != 0.0 or k2 != 0.0
            xs = x if parity == 0 else x_buf
            xn = x_buf if parity == 0 else x
            if with_force:
                for e in range(first, edges.shape[0], stride):
                    _spring_update(e, xs, eta, l0, P, edges, s, phi, k1 * h, k2 * h, track_phi)
                grid.sync()
            for a in range(first, xs.shape[0], stride):
                _node_update(a, xs, xn, p, s, inc_ptr, inc_spring, inc_other, masses, inv_mass, anchored,
                             k1 * h, k2 * h, d * h, with_force, gravity, with_gravity)
            grid.sync()
            parity = 1 - parity
        pending = kicks[n_drifts]


def _spring_length(x, edges, e):
    """|x_b − x_a| of spring e; x: (n, 3), edges: (m, 2) uint32."""
    a = edges[e, 0]
    b = edges[e, 1]
    dx = x[b, 0] - x[a, 0]
    dy = x[b, 1] - x[a, 1]
    dz = x[b, 2] - x[a, 2]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


def _spring_update(e, x, eta, l0, P, edges, s, phi, phi_h1, phi_h2, track_phi):
    """Spring e: s[e] = T/l at x; Φ[e] += phi_h1 θ; Φ[e] += phi_h2 θ.

    x: (n, 3); eta, l0, s, phi: (m,) (eta, phi empty when not THERMAL); P: (k, m) or (k, 1);
    edges: (m, 2) uint32.
    """
    l = _spring_length(x, edges, e)
    c = 0 if UNIFORM else e
    if THERMAL:
        theta = temperature(l, eta[e], l0[e], P, c)
    else:
        theta = P[REFERENCE_TEMPERATURE, c]
    s[e] = tension(l, theta, l0[e], P, c) / l
    if THERMAL and track_phi:
        if phi_h1 != 0.0:
            phi[e] += phi_h1 * theta
        phi[e] += phi_h2 * theta


def _node_update(a, x, x_new, p, s, inc_ptr, inc_spring, inc_other, masses, inv_mass, anchored,
                 kick1, kick2, drift, with_force, gravity, with_gravity):
    """Node a: f = Σ s_e (x_b − x_a) (+ m g); p += kick1 f; p += kick2 f; x_new = x + drift p/m.

    x, x_new, p: (n, 3); inc_ptr: (n+1,) int64; inc_spring, inc_other: (2m,) uint32;
    masses, inv_mass: (n,); anchored: (n,) bool; gravity: (3,).
    """
    xa0 = x[a, 0]
    xa1 = x[a, 1]
    xa2 = x[a, 2]
    if anchored[a]:
        x_new[a, 0] = xa0
        x_new[a, 1] = xa1
        x_new[a, 2] = xa2
        return
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


# ----------------------------------------------------------------------------------------------
# diagnostics


def _spring_sums_kernel(x, eta, l0, P, edges, partial):
    """Per block: Σ U (Σ F(l, θ0) when not THERMAL), Σ η, min θ, max θ into partial[block, :4]."""
    sh = cuda.shared.array((4, REDUCE_THREADS), float64)
    t = cuda.threadIdx.x
    energy = 0.0
    entropy_sum = 0.0
    theta_min = math.inf
    theta_max = -math.inf
    for e in range(cuda.grid(1), edges.shape[0], cuda.gridsize(1)):
        l = _spring_length(x, edges, e)
        c = 0 if UNIFORM else e
        if THERMAL:
            th = temperature(l, eta[e], l0[e], P, c)
            energy += internal_energy(l, eta[e], l0[e], P, c)
            entropy_sum += eta[e]
        else:
            th = P[REFERENCE_TEMPERATURE, c]
            energy += free_energy(l, th, l0[e], P, c)
        theta_min = min(theta_min, th)
        theta_max = max(theta_max, th)
    sh[0, t] = energy
    sh[1, t] = entropy_sum
    sh[2, t] = theta_min
    sh[3, t] = theta_max
    cuda.syncthreads()
    stride = REDUCE_THREADS // 2
    while stride > 0:
        if t < stride:
            sh[0, t] += sh[0, t + stride]
            sh[1, t] += sh[1, t + stride]
            sh[2, t] = min(sh[2, t], sh[2, t + stride])
            sh[3, t] = max(sh[3, t], sh[3, t + stride])
        cuda.syncthreads()
        stride //= 2
    if t == 0:
        for q in range(4):
            partial[cuda.blockIdx.x, q] = sh[q, 0]


def _node_sums_kernel(x, p, masses, anchored, ref, gravity, partial):
    """Per block, over free nodes: K, −Σ m g·x, Σ p, Σ (x − ref) × p into partial[block, :8]."""
    sh = cuda.shared.array((8, REDUCE_THREADS), float64)
    t = cuda.threadIdx.x
    for q in range(8):
        sh[q, t] = 0.0
    for a in range(cuda.grid(1), x.shape[0], cuda.gridsize(1)):
        if not anchored[a]:
            p0 = p[a, 0]
            p1 = p[a, 1]
            p2 = p[a, 2]
            r0 = x[a, 0] - ref[0]
            r1 = x[a, 1] - ref[1]
            r2 = x[a, 2] - ref[2]
            sh[0, t] += 0.5 * (p0 * p0 + p1 * p1 + p2 * p2) / masses[a]
            sh[1, t] -= masses[a] * (gravity[0] * x[a, 0] + gravity[1] * x[a, 1] + gravity[2] * x[a, 2])
            sh[2, t] += p0
            sh[3, t] += p1
            sh[4, t] += p2
            sh[5, t] += r1 * p2 - r2 * p1
            sh[6, t] += r2 * p0 - r0 * p2
            sh[7, t] += r0 * p1 - r1 * p0
    cuda.syncthreads()
    stride = REDUCE_THREADS // 2
    while stride > 0:
        if t < stride:
            for q in range(8):
                sh[q, t] += sh[q, t + stride]
        cuda.syncthreads()
        stride //= 2
    if t == 0:
        for q in range(8):
            partial[cuda.blockIdx.x, q] = sh[q, 0]


def _finish_kernel(partial, ops, out):
    """One block: out[q] = the reduction ops[q] (0 sum, 1 min, 2 max) of partial[:, q].

    partial: (blocks, Q); ops: (Q,) int32, Q ≤ 8; out: (Q,).
    """
    sh = cuda.shared.array((8, REDUCE_THREADS), float64)
    t = cuda.threadIdx.x
    n_q = ops.shape[0]
    for q in range(n_q):
        op = ops[q]
        v = 0.0 if op == 0 else (math.inf if op == 1 else -math.inf)
        for i in range(t, partial.shape[0], REDUCE_THREADS):
            v = _combine(op, v, partial[i, q])
        sh[q, t] = v
    cuda.syncthreads()
    stride = REDUCE_THREADS // 2
    while stride > 0:
        if t < stride:
            for q in range(n_q):
                sh[q, t] = _combine(ops[q], sh[q, t], sh[q, t + stride])
        cuda.syncthreads()
        stride //= 2
    if t == 0:
        for q in range(n_q):
            out[q] = sh[q, 0]


@njit(inline="always")
def _combine(op, a, b):
    """a and b reduced by op: 0 sum, 1 min, 2 max."""
    if op == 0:
        return a + b
    return min(a, b) if op == 1 else max(a, b)


#: device functions the kernels share, bound per model before the kernels (callers after callees)
_SHARED = (("_spring_length", _spring_length), ("_spring_update", _spring_update), ("_node_update", _node_update))


def compile_ptx(model, thermal: bool = True, uniform: bool = False, cc=(9, 0)) -> dict[str, str]:
    """PTX of every kernel for ``model`` and compute capability ``cc``, compiled as for a GPU (not
    the simulator). Needs numba-cuda's NVVM (the CUDA toolkit) but no GPU, so it checks that a
    model compiles for the device on any machine with the toolkit. Returns name -> PTX text.
    Not the fused ``_steps_kernel``: numba-cuda types its grid-wide barrier only with a driver
    present (the ``gpu`` tests compile and run it); it runs the same inlined updates."""
    from numba import boolean, int32, int64, uint32

    ns = model_namespace(model)
    ns.update(THERMAL=bool(thermal), UNIFORM=bool(uniform), REDUCE_THREADS=REDUCE_THREADS,
              REFERENCE_TEMPERATURE=model.parameter_index(model.reference_temperature))
    for name, template in _SHARED:
        ns[name] = njit(inline="always")(rebind(template, f"{model.name}_ptx", ns))
    v, m2, u = float64[::1], float64[:, ::1], uint32[::1]
    signatures = {
        "spring": (_spring_kernel, (m2, v, v, m2, uint32[:, ::1], v, v, float64, float64, boolean)),
        "node": (_node_kernel, (m2, m2, m2, v, int64[::1], u, u, v, v, boolean[::1], float64, float64, float64,
                                boolean, v, boolean)),
        "spring_sums": (_spring_sums_kernel, (m2, v, v, m2, uint32[:, ::1], m2)),
        "node_sums": (_node_sums_kernel, (m2, m2, v, boolean[::1], v, v, m2)),
        "finish": (_finish_kernel, (m2, int32[::1], v)),
    }
    out = {}
    for name, (template, sig) in signatures.items():
        ptx, _ = cuda.compile_ptx(rebind(template, f"{model.name}_ptx", ns), sig, cc=cc)
        out[name] = ptx
    return out
