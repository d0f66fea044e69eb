"""CUDA kernels of the explicit step's sub-flows and of the diagnostics sums, compiled per model.

A stage of the schedule (:mod:`thermonet.explicit.schedule`) is two launches, each running
the sub-flows of :mod:`thermonet.kernels.subflows` (the CPU kernel's own):

1. :func:`_spring_kernel`, one thread per spring e: ``s[e] = T/l`` at x and ``Φ[e] += k h θ``
   (the two kicks that meet at a step boundary as two separate additions, as on the CPU), and
   the admissibility test: a spring outside the admissible states sets ``flag`` with where it
   happened, and every later launch of the call returns at once (the CPU kernel's stop);
2. :func:`_node_kernel`, one thread per node a: gathers ``f_a = Σ s_e (x_b − x_a)`` over its
   CSR incidence list in the CPU's order, kicks ``p`` and drifts into a second position buffer
   (other threads still read the old one).

An extra sub-flow row is one launch of its slot's :func:`_flow_kernel`. :func:`_steps_kernel`
runs whole chunks of steps in one cooperative launch, the same rows over grid-stride loops.

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

from ...heat import exchange as heat_exchange
from ...heat.passes import _gather_two_forces
from ...heat.rows import CONDUCTION_FORWARD, CONDUCTION_REVERSE, THERMAL_WAVES
from ...kernels import subflows
from ...kernels.specialize import MODEL_FUNCTIONS, function_fingerprint, kernel_namespace, model_fingerprint, rebind
from ...kernels.subflows import bind_subflows
from ..schedule import FIRST_FLOW_SLOT, MAX_FLOWS
from . import FLAG_ROW, FLAG_SET, FLAG_STAGES, FLAG_STEP, simulator_enabled

# Bound per model by cuda_kernels(); see thermonet.explicit.cpu for their meaning.
temperature = tension = internal_energy = free_energy = None
spring_force = spring_energy = spring_temperature = outside_admissible = advance_thermal_displacement = None
squared_length = None
gather_force = kick_momentum = drift_position = load_row = store_row = update = gather_two_forces = None
flow_update_0 = flow_update_1 = flow_update_2 = flow_update_3 = None
# --- heat flow (thermonet.heat.cuda): compiled in only with CONDUCTION / WAVES ---
sweep_phase = temperature_update = phase_count = conduction_due = keep_temperature = sweep_follows = first_phase = None
finish_before_kick = finish_deferred = phase_elements = deferred_closing = None
joined_boundary = conduction_plan = phase_mode = kept_length = None
CONDUCTION = False
WAVES = False
# --- end heat flow ---
node_load = evaluate_load = load_power = add_work = drive_member = None  # loads: with LOADS
LOADS = False
THERMAL = True
REFERENCE_TEMPERATURE = 0
UNIFORM = False
#: threads per block of the stage kernels. The simulator runs each block as Python threads, and
#: its cost grows with blocks and with barriers: few blocks there, tiny reduction trees.
THREADS = 256
SIMULATOR_THREADS = 32
#: launch bounds of the fused kernel (threads per block, blocks per multiprocessor): registers
#: capped at 64 a thread, so that four blocks fit on a multiprocessor. Unbounded it takes 96 on
#: an H100 (two blocks each); bounded, the fused launch went from 12.0 to 14.0 G spring-steps/s
#: at 1e6 springs and from 14.0 to 17.8 at 3e6 (small nets use fewer blocks anyway:
#: thermonet.explicit.cuda.stepper.fused_grid). None: unbounded.
FUSED_LAUNCH_BOUNDS = (THREADS, 4)
#: launch bounds of the fused kernel on small nets, which run at most two blocks a multiprocessor
#: (thermonet.explicit.cuda.stepper.CudaSplittingStepper.SMALL_NET_BLOCKS_PER_SM): up to 128
#: registers a thread, so the per-step work is not spilled to local memory where latency, not
#: bandwidth, bounds a step
SMALL_NET_LAUNCH_BOUNDS = (THREADS, 2)
#: threads per block of the diagnostics sums, a compile-time constant of their shared-memory trees
#: (a power of two), and their (grid-stride) blocks
REDUCE_THREADS = 256
REDUCE_BLOCKS = 256
SIMULATOR_REDUCE_THREADS = 4
SIMULATOR_REDUCE_BLOCKS = 2

#: the reductions of the sums' columns, by name (compile-time constants of the finishing kernel)
SUM, MIN, MAX = 0, 1, 2
#: columns of the spring sums and the reduction of each
SPRING_SUMS = ("internal", "entropy", "theta_min", "theta_max")
SPRING_OPS = (SUM, SUM, MIN, MAX)
NODE_SUMS = ("kinetic", "potential", "px", "py", "pz", "Lx", "Ly", "Lz")
NODE_OPS = (SUM,) * 8


_CACHE: dict = {}


class CudaKernels:
    """The compiled kernels of one model variant and their launch geometry."""

    def __init__(self, spring, node, flows, steps, spring_sums, node_sums, finish, threads, reduce_threads,
                 reduce_blocks):
        self.spring, self.node, self.flows, self.steps = spring, node, flows, steps
        self.steps_small = steps  # the fused kernel for small nets: see SMALL_NET_LAUNCH_BOUNDS
        self.sweep = self.temperature = None  # heat flow: see cuda_kernels(conduction=, waves=)
        self.load_start = self.load_stage = None  # loads: see cuda_kernels(loads=True)
        self.spring_sums, self.node_sums, self.finish = spring_sums, node_sums, finish
        self.threads, self.reduce_threads, self.reduce_blocks = threads, reduce_threads, reduce_blocks

    def blocks(self, n: int) -> int:
        """Blocks of one-thread-per-item launches over n items."""
        return (n + self.threads - 1) // self.threads


def cuda_kernels(model, thermal: bool = True, uniform: bool = False, flows=(), conduction: bool = False,
                 waves: bool = False, loads: bool = False) -> CudaKernels:
    """The CUDA kernels for ``model`` (purely mechanical when not ``thermal``; parameters shared
    by all springs, a ``(k, 1)`` array, when ``uniform``: see
    :func:`thermonet.kernels.specialize.kernel_parameters`), with the extra sub-flows ``flows``
    (:class:`~thermonet.explicit.schedule.SubFlow` s, slot order) and the heat-flow rows it
    may meet compiled in (``conduction``, ``waves``: :mod:`thermonet.heat.cuda`); with ``loads``
    the node kernel adds the loads' forces and ``load_start`` / ``load_stage`` run the loads' own
    passes (two launches per stage only: the fused ``steps`` kernel is not compiled with them)."""
    sim = simulator_enabled()
    key = (model_fingerprint(model), bool(thermal), bool(uniform), sim, tuple(id(f) for f in flows),
           bool(conduction), bool(waves), bool(loads), FUSED_LAUNCH_BOUNDS, SMALL_NET_LAUNCH_BOUNDS)
    if key not in _CACHE:
        ns = kernel_namespace(model, thermal, uniform)
        if sim:
            ns.update({name: _simulator_adapter(ns[name]) for name in MODEL_FUNCTIONS})
        reduce_threads = SIMULATOR_REDUCE_THREADS if sim else REDUCE_THREADS
        ns["REDUCE_THREADS"] = reduce_threads
        flows_tag = f"_f{function_fingerprint(*(f.update for f in flows))}" if flows else ""
        tag = (f"{model.name}_{key[0]}_{'thermal' if thermal else 'mech'}{'_uniform' if uniform else ''}"
               f"_r{reduce_threads}_s{subflows.source_digest()}{flows_tag}")
        jit = cuda.jit if sim else cuda.jit(cache=True)
        inline = (lambda fn: fn) if sim else njit(inline="always")
        bind_subflows(ns, tag, inline)
        # --- heat flow ---
        ns["CONDUCTION"], ns["WAVES"] = bool(conduction), bool(waves)
        if conduction or waves:
            from ...heat import cuda as heat

            tag += f"_{'k' * conduction}{'w' * waves}{heat_exchange.source_digest()}{heat.source_digest()}"
            heat.bind_device_heat(ns, tag, inline)
        else:
            _bind_no_heat(ns, inline)
        # --- end heat flow ---
        ns["LOADS"] = bool(loads)
        if loads:
            from ...loads.cuda import bind_device_loads

            tag += bind_device_loads(ns, tag, inline, sim)
        for slot in range(MAX_FLOWS):
            update = _device_update(flows[slot].update, sim) if slot < len(flows) else inline(_no_update)
            ns[f"flow_update_{slot}"] = update  # (a device function even when empty: the fused kernel calls it)
        bind_shared(ns, tag, inline)  # shared by the two-launch and the fused path

        def compile_(template, namespace=ns, suffix="", compiler=jit):
            return compiler(rebind(template, tag + suffix, namespace))

        fused_jit = jit if sim or FUSED_LAUNCH_BOUNDS is None else \
            cuda.jit(cache=True, launch_bounds=FUSED_LAUNCH_BOUNDS)
        small_jit = jit if sim or SMALL_NET_LAUNCH_BOUNDS is None else \
            cuda.jit(cache=True, launch_bounds=SMALL_NET_LAUNCH_BOUNDS)

        flow_kernels = tuple(compile_(_flow_kernel, dict(ns, update=ns[f"flow_update_{slot}"]), f"_{slot}")
                             for slot in range(len(flows)))
        kernels = CudaKernels(
            compile_(_spring_kernel), compile_(_node_kernel), flow_kernels,
            compile_(_steps_kernel, compiler=fused_jit),
            compile_(_spring_sums_kernel), compile_(_node_sums_kernel), compile_(_finish_kernel),
            SIMULATOR_THREADS if sim else THREADS, reduce_threads, SIMULATOR_REDUCE_BLOCKS if sim else REDUCE_BLOCKS)
        # (a dispatcher compiles at its first launch: a run compiles only the variant it uses)
        kernels.steps_small = kernels.steps if sim else compile_(_steps_kernel, suffix="_small", compiler=small_jit)
        if conduction or waves:  # heat flow
            kernels.sweep, kernels.temperature = heat.heat_kernels(compile_)  # (thermonet.heat.cuda)
        if loads:  # loads
            from ...loads.cuda import load_stage_kernel, load_start_kernel

            kernels.load_start, kernels.load_stage = compile_(load_start_kernel), compile_(load_stage_kernel)
        _CACHE[key] = kernels
    return _CACHE[key]


def _simulator_adapter(fn):
    """``fn`` callable from simulated kernel code: its array argument P as the NumPy array."""
    def call(l, s, l0, P, e):
        return fn(l, s, l0, np.asarray(P), e)

    call.__name__ = getattr(fn, "__name__", "model_function")
    return call


def _device_update(update, sim: bool):
    """A sub-flow's ``update`` as the kernels call it: the Python function under the simulator
    (its arrays are simulator arrays), else an inlined device function."""
    py = getattr(update, "py_func", update)
    return py if sim else njit(inline="always")(py)


def _no_update(i, data, tau, t, x, p, phi, eta):
    """An empty flow slot."""
    return None


def _bind_no_heat(ns: dict, inline) -> None:
    """The heat-flow functions the kernels call, as empty ones: no heat flow compiled in."""
    ns["sweep_phase"], ns["temperature_update"] = inline(_no_sweep), inline(_no_temperature)
    ns["phase_count"], ns["conduction_due"] = inline(_no_phases), inline(_no_due)
    ns["keep_temperature"], ns["sweep_follows"] = inline(_no_keep), inline(_no_follows)
    ns["first_phase"] = inline(_no_first_phase)
    ns["finish_before_kick"], ns["finish_deferred"] = inline(_no_finish), inline(_no_deferred)
    ns["phase_elements"] = inline(_no_elements)
    ns["deferred_closing"] = inline(_no_closing)
    ns["joined_boundary"], ns["conduction_plan"] = inline(_no_joined), inline(_no_plan)
    ns["phase_mode"] = inline(_no_mode)
    ns["kept_length"] = inline(_no_length)


def _no_sweep(code, phase, heat, tau, t, phi, eta, first, stride, mode):
    """No heat flow compiled in."""
    return None


def _no_temperature(e, x, eta, edges, springs, heat):
    """No heat flow compiled in."""
    return None


def _no_phases(code, colour_ptr, star_colour_ptr, sweeps):
    """No heat flow compiled in."""
    return 0


def _no_due(code, every, step_in_cycle):
    """No heat flow compiled in."""
    return False


def _no_keep(e, l, theta, kept):
    """No heat flow compiled in."""
    return None


def _no_follows(table, r, every, step_in_cycle):
    """No heat flow compiled in."""
    return False


def _no_first_phase(code, start_kept):
    """No heat flow compiled in."""
    return 0


def _no_finish(e, eta, kept):
    """No heat flow compiled in."""
    return None


def _no_deferred(table, r):
    """No heat flow compiled in."""
    return False


def _no_joined(table):
    """No heat flow compiled in."""
    return False


def _no_plan(code, count, n_colours, sweeps, n_bound, start_kept, finish_pending, joined, follows, resume):
    """No heat flow compiled in."""
    return 0, 0, -1, -1, 0, 0


def _no_mode(phase, count, together, start_mode, finish_mode):
    """No heat flow compiled in."""
    return 0


def _no_length(e, kept):
    """No heat flow compiled in."""
    return 0.0


def _no_closing(table):
    """No heat flow compiled in: no closing kick is deferred."""
    return -1


def _no_elements(code, phase, heat):
    """No heat flow compiled in."""
    return 0


# ----------------------------------------------------------------------------------------------
# one stage


def _spring_kernel(x, eta, phi, springs, edges, s, steps, run, flag, where, kept, keep, finish):
    """Thread e: :func:`_spring_update` of spring e, unless the call already stopped (``flag``).
    steps: (kick1 h, kick2 h) of Φ's update; where: (step, row, stages) written into ``flag``
    if spring e is outside the admissible states; kept, keep, finish: see :func:`_spring_update`."""
    e = cuda.grid(1)
    if e < edges.shape[0] and flag[FLAG_SET] == 0:
        if _spring_update(e, x, eta, phi, springs, edges, s, steps, run, kept, keep, finish):
            _raise_flag(flag, where)


def _node_kernel(x, x_new, p, s, topology, nodes, steps, flag, loads, s_first):
    """Thread a: :func:`_node_update` of node a, unless the call already stopped (``flag``);
    steps: (kick1 h, kick2 h, drift h, with_force, split); loads: a LoadArrays record with LOADS."""
    a = cuda.grid(1)
    if a < x.shape[0] and flag[FLAG_SET] == 0:
        _node_update(a, x, x_new, p, s, topology, nodes, steps, loads, s_first)


def _flow_kernel(data, tau, t, x, p, phi, eta, flag):
    """Thread i: the slot's sub-flow ``update`` of element i over tau at time t, unless the call
    already stopped (``flag``)."""
    i = cuda.grid(1)
    if i < data[0].shape[0] and flag[FLAG_SET] == 0:
        update(i, data, tau, t, x, p, phi, eta)


def _steps_kernel(state, x_buf, s, topology, springs, nodes, table, flows, run, flag):
    """``run.n_steps`` whole steps in one cooperative launch: every row of the schedule ``table``
    over grid-stride loops, separated by grid-wide barriers, in the order and with the
    coefficients of :meth:`~thermonet.explicit.cuda.stepper.CudaSplittingStepper.advance`'s two-launch
    path (the same per-spring and per-node updates, so the same numbers), and the call's closing
    kick. Positions alternate between ``state.x`` and ``x_buf`` node pass by node pass; the caller
    counts them to know which holds the result (:meth:`~thermonet.explicit.cuda.stepper.CudaSplittingStepper.node_passes`). A spring outside the admissible states stops the
    launch after its spring pass, with ``flag`` saying where. flows: (the extra sub-flows' data,
    the :class:`~thermonet.kernels.records.Heat` record); heat rows run their phases
    (:mod:`thermonet.heat.cuda`) between barriers.
    """
    grid = cuda.cg.this_grid()
    first = cuda.grid(1)
    stride = cuda.gridsize(1)
    x = state.x
    p = state.p
    phi = state.phi
    eta = state.eta
    effects = flows[0]
    heat = flows[1]
    theta_valid = CONDUCTION and heat.theta_ok[0] >= 1.0  # the previous call's sweeps continue
    start_kept = False  # heat.theta_start = heat.theta (see thermonet.heat.cuda.first_phase)
    finish_pending = False  # the forward sweep's finish, left to the next spring pass
    kept = (heat.theta, heat.length, heat.theta_start, heat.capacity, heat.produced)  # (DeviceHeat.kept)
    h = run.h
    n_rows = table.code.shape[0]
    edges = topology.edges
    pending = 0.0
    parity = 0
    # the closing kick deferred past the step boundary (thermonet.heat.cuda.deferred_closing): its
    # coefficient, and whether its forces were computed before a sweep (into heat.s_before)
    closing = deferred_closing(table) if CONDUCTION else -1
    deferred = 0.0
    split = False
    # a cycle boundary's two rows as one exchange (thermonet.heat.cuda.joined_boundary): joined,
    # the reverse row left its update to the forward row; saved, the call ended with it pending;
    # resume, the last call did and this one continues it
    joined_layout = CONDUCTION and joined_boundary(table)
    joined = saved = False
    resume = joined_layout and heat.theta_ok[0] == 2.0
    for step in range(run.n_steps + 1):
        for r in range(n_rows):
            xs = x if parity == 0 else x_buf
            xn = x_buf if parity == 0 else x
            row = r  # where a bad spring is reported (0: at the previous step's end positions)
            s_first = s
            split_kick = False
            kick_first = 0.0
            if step < run.n_steps:
                code = table.code[r]
                if code >= FIRST_FLOW_SLOT:
                    tau = table.kick[r] * h
                    t = run.t0 + (step + table.drift[r]) * h
                    _flow_grid(code, effects, tau, t, xs, p, phi, eta, first, stride)
                    grid.sync()
                    theta_valid = start_kept = False
                    continue
                if code <= CONDUCTION_FORWARD:  # --- heat flow (as the CPU's _advance) ---
                    if WAVES and code == THERMAL_WAVES:
                        theta_valid = False
                    elif CONDUCTION and code >= CONDUCTION_REVERSE:
                        if not conduction_due(code, run.conduction_every,
                                              (run.cycle_step + step) % run.conduction_every):
                            continue
                        if not theta_valid:
                            for e in range(first, edges.shape[0], stride):
                                temperature_update(e, xs, eta, edges, springs, heat)
                            grid.sync()
                            start_kept = True
                        theta_valid = True
                    else:
                        continue
                    t = run.t0 + (step + table.drift[r]) * h
                    tau = table.kick[r] * h * (run.conduction_every if code != THERMAL_WAVES else 1)
                    finish_pending = CONDUCTION and finish_deferred(table, r)
                    count = phase_count(code, heat.colour_ptr, heat.star_colour_ptr, heat.sweeps[0])
                    lo, hi, skip, together, start_mode, finish_mode = 0, count, -1, -1, 0, 0
                    if CONDUCTION and code != THERMAL_WAVES:
                        follows = joined_layout and step + 1 < run.n_steps
                        lo, hi, skip, together, start_mode, finish_mode = conduction_plan(
                            code, count, heat.star_colour_ptr.shape[0] - 1, heat.sweeps[0], heat.bound_spring.shape[0],
                            start_kept, finish_pending, joined, follows, resume and step == 0)
                        joined = joined_layout and code == CONDUCTION_REVERSE and follows
                        saved = joined_layout and code == CONDUCTION_REVERSE and not follows
                        resume = False
                    for phase in range(lo, hi):
                        if phase != skip and phase_elements(code, phase, heat) > 0:
                            sweep_phase(code, phase, heat, tau, t, phi, eta, first, stride,
                                        phase_mode(phase, count, together, start_mode, finish_mode))
                            grid.sync()
                    start_kept = code == CONDUCTION_REVERSE  # its finish kept θ as the start (or, joined, its start)
                    continue
                k1 = pending if r == 0 else 0.0
                k2 = table.kick[r]
                d = table.drift[r]
                if r == closing:  # deferred: a spring pass now if a sweep follows, the rest later
                    deferred = k2
                    split = sweep_follows(table, r, run.conduction_every,
                                          (run.cycle_step + step) % run.conduction_every)
                    if split:
                        for e in range(first, edges.shape[0], stride):
                            if _spring_update(e, xs, eta, phi, springs, edges, heat.s_before, (0.0, k2 * h), run, kept,
                                              True, False):
                                _raise_flag(flag, (step, r, parity))
                        grid.sync()
                        if flag[FLAG_SET] != 0:
                            return
                        theta_valid = start_kept = True
                    continue
                if deferred != 0.0:  # the first stage after a deferred closing kick
                    if split:  # the node pass kicks with heat.s_before's forces first
                        s_first = heat.s_before
                        split_kick = True
                        kick_first = deferred
                    else:
                        k1 = deferred
                        row = 0
                    deferred = 0.0
            elif r == 0 and pending != 0.0:  # after the last step: its closing kick
                k1 = 0.0
                k2 = pending
                d = 0.0
            elif r == 0 and deferred != 0.0:  # after the last step: its deferred closing kick
                k1 = 0.0
                k2 = deferred
                d = 0.0
                row = n_rows
                if split:  # its forces are in heat.s_before: only the node pass is left
                    for a in range(first, xs.shape[0], stride):
                        _node_update(a, xs, xn, p, heat.s_before, topology, nodes, (0.0, k2 * h, 0.0, True, False),
                                     nodes, s)
                    grid.sync()
                    parity = 1 - parity
                    break
            else:
                break
            with_force = k1 != 0.0 or k2 != 0.0
            # heat flow: a stage without drift before a due sweep keeps θ(l, η) and l for it
            keep = CONDUCTION and with_force and d == 0.0 and step < run.n_steps and sweep_follows(
                table, r, run.conduction_every, (run.cycle_step + step) % run.conduction_every)
            if with_force or d != 0.0:
                theta_valid = start_kept = keep
            finish = finish_pending
            finish_pending = False
            if with_force:
                for e in range(first, edges.shape[0], stride):
                    if _spring_update(e, xs, eta, phi, springs, edges, s, (k1 * h, k2 * h), run, kept, keep, finish):
                        _raise_flag(flag, (step, row if step < run.n_steps else n_rows, parity))
                grid.sync()
                if flag[FLAG_SET] != 0:
                    return
            for a in range(first, xs.shape[0], stride):
                _node_update(a, xs, xn, p, s, topology, nodes,
                             ((kick_first if split_kick else k1) * h, k2 * h, d * h, with_force, split_kick), nodes,
                             s_first)
            grid.sync()
            parity = 1 - parity
        pending = table.carry
    if CONDUCTION and first == 0:
        heat.theta_ok[0] = (2.0 if saved else 1.0) if theta_valid else 0.0


def _flow_grid(slot, effects, tau, t, x, p, phi, eta, first, stride):
    """The sub-flow in ``slot`` over its elements in a grid-stride loop (the fused launch)."""
    if slot == 0:
        for i in range(first, effects[0][0].shape[0], stride):
            flow_update_0(i, effects[0], tau, t, x, p, phi, eta)
    elif slot == 1:
        for i in range(first, effects[1][0].shape[0], stride):
            flow_update_1(i, effects[1], tau, t, x, p, phi, eta)
    elif slot == 2:
        for i in range(first, effects[2][0].shape[0], stride):
            flow_update_2(i, effects[2], tau, t, x, p, phi, eta)
    else:
        for i in range(first, effects[3][0].shape[0], stride):
            flow_update_3(i, effects[3], tau, t, x, p, phi, eta)


def _raise_flag(flag, where):
    """Record where a spring left the admissible states (every thread that finds one writes
    the same values)."""
    flag[FLAG_STEP] = where[0]
    flag[FLAG_ROW] = where[1]
    flag[FLAG_STAGES] = where[2]
    flag[FLAG_SET] = 1


def _spring_length(x, edges, e):
    """|x_b − x_a| of spring e; x: (n, 3), edges: (m, 2) uint32."""
    return math.sqrt(squared_length(x, edges, e))


def _spring_update(e, x, eta, phi, springs, edges, s, steps, run, kept, keep, finish):
    """Spring e: s[e] = T/l at x; Φ[e] += steps[0] θ; Φ[e] += steps[1] θ. Returns whether the
    spring is outside the admissible states. Heat flow (``kept``: the heat record's arrays,
    :attr:`thermonet.heat.cuda.DeviceHeat.kept`): with ``finish``, first the entropy update that
    ends the forward sweep before this stage; with ``keep`` (a stage without drift right before
    a conduction sweep), θ and l kept for the sweep, in place of a temperature pass. A sweep
    keeps l with θ (the same function of the same x), so with ``finish`` l is read from there.

    x: (n, 3); eta, phi, s: (m,) (eta, phi empty when not THERMAL); edges: (m, 2) uint32.
    """
    if CONDUCTION and finish:  # at the sweep's positions, whose lengths it kept: x is not read
        finish_before_kick(e, eta, kept)
        l = kept_length(e, kept)
    else:
        l = _spring_length(x, edges, e)
    c = 0 if UNIFORM else e
    rest = springs.rest[e]
    theta, force = spring_force(l, eta[e] if THERMAL else 0.0, rest, springs.P, c)
    s[e] = force
    if CONDUCTION and keep:
        keep_temperature(e, l, theta, kept)
    if THERMAL and run.track_phi:
        advance_thermal_displacement(phi, e, theta, steps[0], steps[1])
    return outside_admissible(l, rest, force, theta, run.stretch_min, run.stretch_max)


def _node_update(a, x, x_new, p, s, topology, nodes, steps, loads, s_first):
    """Node a: f = Σ s_e (x_b − x_a) (+ m g) (+ its load, with LOADS); p += kick1 f; p += kick2 f;
    x_new = x + drift p/m, steps = (kick1, kick2, drift, with_force, split); with ``split`` (heat
    flow, never with LOADS) kick1's force is the one of T/l ``s_first`` (:func:`_kick_split`).
    x, x_new, p: (n, 3); s, s_first: (m,). The fused kernel, never compiled with LOADS, passes a
    placeholder for ``loads``."""
    xa0, xa1, xa2 = load_row(x, a)
    if nodes.anchored[a]:
        store_row(x_new, a, xa0, xa1, xa2)
        return
    p0, p1, p2 = load_row(p, a)
    if CONDUCTION and steps[4]:
        p0, p1, p2 = _kick_split(a, x, xa0, xa1, xa2, p0, p1, p2, s_first, s, topology, nodes, steps[0], steps[1])
        store_row(p, a, p0, p1, p2)
    elif steps[3]:
        f0, f1, f2 = gather_force(a, x, s, topology.inc_ptr, topology.inc_spring, topology.inc_other, nodes.masses,
                                  nodes.gravity, nodes.with_gravity)
        if LOADS:
            f0, f1, f2 = node_load(a, f0, f1, f2, loads.node_force, loads.node_weight, loads.node_drive, loads.value,
                                   loads.free)
        p0, p1, p2 = kick_momentum(p0, p1, p2, f0, f1, f2, steps[0], steps[1])
        store_row(p, a, p0, p1, p2)
    drift_position(x_new, a, xa0, xa1, xa2, p0, p1, p2, steps[2] * nodes.inv_mass[a])


def _kick_split(a, x, xa0, xa1, xa2, p0, p1, p2, s_first, s, topology, nodes, kick1, kick2):
    """Node a's momentum after two kicks at the same positions x with different forces: kick1
    with T/l ``s_first`` (a closing kick's, computed before the conduction sweep between them:
    :func:`thermonet.heat.cuda.deferred_closing`), then kick2 with ``s``: the operations of two
    :func:`_node_update` s on the same operands, both forces gathered in one pass over the
    incidences (the CPU's ``gather_two_forces``, :mod:`thermonet.heat.passes`). Returns (p0, p1, p2)."""
    g0, g1, g2, f0, f1, f2 = gather_two_forces(a, x, s_first, s, topology.inc_ptr, topology.inc_spring,
                                               topology.inc_other, nodes.masses, nodes.gravity, nodes.with_gravity)
    p0 = p0 + kick1 * g0
    p1 = p1 + kick1 * g1
    p2 = p2 + kick1 * g2
    return p0 + kick2 * f0, p1 + kick2 * f1, p2 + kick2 * f2


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
        eta_e = eta[e] if THERMAL else 0.0
        th = spring_temperature(l, eta_e, l0[e], P, c)
        energy += spring_energy(l, eta_e, th, l0[e], P, c)
        entropy_sum += eta_e
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
    """One block: out[q] = the reduction ops[q] (SUM, MIN or MAX) of partial[:, q].

    partial: (blocks, Q); ops: (Q,) int32, Q ≤ 8; out: (Q,).
    """
    sh = cuda.shared.array((8, REDUCE_THREADS), float64)
    t = cuda.threadIdx.x
    n_q = ops.shape[0]
    for q in range(n_q):
        op = ops[q]
        v = 0.0 if op == SUM else (math.inf if op == MIN else -math.inf)
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
    """a and b reduced by op: SUM, MIN or MAX."""
    if op == SUM:
        return a + b
    return min(a, b) if op == MIN else max(a, b)


#: device functions the kernels share, bound per model before the kernels (callers after callees)
_SHARED = (("_spring_length", _spring_length), ("_spring_update", _spring_update), ("_kick_split", _kick_split),
           ("_node_update", _node_update),
           ("_raise_flag", _raise_flag), ("_flow_grid", _flow_grid))


def bind_shared(ns: dict, tag: str, inline) -> None:
    """Bind the device functions the kernels share (:data:`_SHARED`, and the CPU's
    ``gather_two_forces`` that :func:`_kick_split` calls) into ``ns``, each compiled by ``inline``."""
    ns["gather_two_forces"] = inline(rebind(_gather_two_forces, tag, ns))
    for name, template in _SHARED:  # in order: later ones call earlier ones
        ns[name] = inline(rebind(template, tag, ns))


def compile_ptx(model, thermal: bool = True, uniform: bool = False, cc=(9, 0)) -> dict[str, str]:
    """PTX of every kernel for ``model`` and compute capability ``cc``, compiled as for a GPU (not
    the simulator). Needs numba-cuda's NVVM (the CUDA toolkit) but no GPU, so it checks that a
    model compiles for the device on any machine with the toolkit. Returns name -> PTX text.
    Not the fused ``_steps_kernel``: numba-cuda types its grid-wide barrier only with a driver
    present (the ``gpu`` tests compile and run it); it runs the same inlined updates."""
    from numba import typeof

    from ...kernels import records

    ns = kernel_namespace(model, thermal, uniform)
    ns["REDUCE_THREADS"] = REDUCE_THREADS
    tag = f"{model.name}_ptx"
    bind_subflows(ns, tag, njit(inline="always"))
    _bind_no_heat(ns, njit(inline="always"))
    bind_shared(ns, tag, njit(inline="always"))
    v, x, u = np.empty(1), np.empty((1, 3)), np.empty(1, np.uint32)
    springs = records.Springs(v, np.empty((len(model.parameters), 1)))
    topology = records.Topology(np.empty((1, 2), np.uint32), np.empty(2, np.int64), u, u)
    nodes = records.Nodes(v, v, np.empty(1, np.bool_), np.empty(3), True, np.empty(3))
    run = records.Run(1.0, 0.0, 1, True, 0.1, 10.0, False, False)
    flag = np.zeros(4, np.int64)
    samples = {
        "spring": (_spring_kernel, (x, v, v, springs, topology.edges, v, (1.0, 1.0), run, flag, (0, 0, 0),
                                    (v, v, v, v, v), False, False)),
        "node": (_node_kernel, (x, x, x, v, topology, nodes, (1.0, 1.0, 1.0, True, False), flag, nodes, v)),
        "spring_sums": (_spring_sums_kernel, (x, v, v, springs.P, topology.edges, x)),
        "node_sums": (_node_sums_kernel, (x, x, v, nodes.anchored, v, v, x)),
        "finish": (_finish_kernel, (x, np.empty(1, np.int32), v)),
    }
    out = {}
    for name, (template, args) in samples.items():
        ptx, _ = cuda.compile_ptx(rebind(template, tag, ns), tuple(typeof(a) for a in args), cc=cc)
        out[name] = ptx
    return out
