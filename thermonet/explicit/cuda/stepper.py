"""The CUDA stepper: a :class:`~thermonet.explicit.splitting.Splitting` run on the GPU with the
state resident in device memory.

The host :class:`~thermonet.system.State` stays the one the :class:`~thermonet.simulation.Simulation`
holds (step and time are kept there), but while the stepper owns it its arrays are stale: the
simulation calls :meth:`CudaSplittingStepper.sync` before it reads them (output frames, the state
property, error reports) and :meth:`CudaSplittingStepper.diagnostics_row` for a diagnostics row,
which is reduced on the device. So a run copies back only frames and diagnostics rows. A state the
simulation replaces (``load_state``) is a new object, and is uploaded at the next ``advance``.
"""

from __future__ import annotations

import numpy as np

from ...blowup import blowup_failure
from ...diagnostics import diagnostics_row
from ...errors import InputError
from ...heat.rows import CONDUCTION_FORWARD, CONDUCTION_REVERSE, THERMAL_WAVES
from ...integrators.base import Stepper
from ...kernels import records
from ...kernels.specialize import kernel_parameters
from ...loads.stepping import StepperLoads, work_of
from ..schedule import FIRST_FLOW_SLOT, flow_data
from . import FLAG_ROW, FLAG_SET, FLAG_STAGES, FLAG_STEP, require_cuda
from .launch import Launcher


class CudaSplittingStepper(Stepper):
    """A :class:`~thermonet.explicit.splitting.Splitting` bound to a system, on the GPU."""

    #: the state lives on the device: the simulation must sync() before reading its arrays
    resident = True
    #: run whole chunks of steps as one cooperative launch (``_steps_kernel``: grid-wide barriers
    #: between the passes) instead of two launches per stage; the same numbers either way (tested
    #: bit for bit on an H100). None: by net size, below :data:`FUSED_MAX_SPRINGS`.
    fused: bool | None = None
    #: Measured on an H100 (CO2, 6-neighbour lattices, G spring-steps/s fused / two launches,
    #: ``benchmarks/gpu_check.py``): 1e5 springs 5.1 / 0.87, 1e6 14.0 / 6.5, 3e6 17.8 / 19.8,
    #: 1e7 19.8 / 22.0. A launch costs tens of µs of host time even through a
    #: :class:`~thermonet.explicit.cuda.launch.Launcher`, which bounds two launches per stage on small nets;
    #: a cooperative launch keeps only the blocks that fit at once, which caps it below the copy
    #: bandwidth on large ones. The two cross between 1e6 and 3e6 springs.
    FUSED_MAX_SPRINGS = 2_000_000
    #: below this many springs a fused launch runs at most SMALL_NET_BLOCKS_PER_SM blocks per
    #: multiprocessor, not all that fit: each grid-wide barrier costs more with more blocks, and on
    #: small nets that outweighs the memory parallelism of a full grid (H100, G spring-steps/s with
    #: 2 blocks per multiprocessor against all that fit: 1e5 springs 6.5–7.3 against 5.1–6.5, 3e5
    #: 11.1–12.1 against 10.4–10.9; at 1e6 the full grid is faster, 14.2–14.6 against 11.4–11.9)
    SMALL_NET_SPRINGS = 500_000
    SMALL_NET_BLOCKS_PER_SM = 2
    #: most steps per fused launch (a launch cannot be interrupted; a few hundred steps keep
    #: Ctrl-C and progress reports responsive and cost one launch each)
    FUSED_MAX_STEPS = 256

    #: steps the device copy of a call's start state may lag behind it: a blow-up restores that
    #: copy and replays the good steps (as the CPU runs do from the Simulation's backup)
    BACKUP_SPAN = 256

    def __init__(self, integrator, system):
        require_cuda()
        from numba import cuda

        from ...heat.cuda import DeviceHeat, deferred_closing
        from .kernels import NODE_OPS, SPRING_OPS, cuda_kernels

        self.integrator = integrator
        self.system = system
        self._cuda = cuda
        P, uniform = kernel_parameters(system.parameters)
        flows = integrator.subflows
        table = integrator.table
        self.loads = StepperLoads.of(system, table)
        if self.loads is not None:  # two launches per stage: the fused kernel does not take loads
            self.fused = False
        n, m = system.n_nodes, system.n_springs
        dev = cuda.to_device
        # --- heat flow: the record and its logs on the device (thermonet.heat.cuda) ---
        conduction, waves = integrator.heat_rows
        if (conduction or waves) and getattr(system, "heat", None) is None:
            raise InputError(f"{integrator.name} has heat-flow rows but the system has no heat flow set up")
        self._heat = DeviceHeat(system.heat if (conduction or waves) else None, integrator, dev)
        self._cycle = (1, 0, 1)  # (k, steps of the cycle made, sub-sweeps j) at the call's start
        self._k = cuda_kernels(system.model, system.thermal, uniform, flows, conduction, waves, self.loads is not None)
        # the closing kick deferred past the step boundary's conduction rows (not with loads, whose
        # work is accounted stage by stage): see thermonet.heat.cuda.deferred_closing
        self._closing = deferred_closing(table) if conduction and self.loads is None else -1
        self._table = records_to_device(table, dev)
        self._rows = [(int(c), float(k), float(d)) for c, k, d in zip(table.code, table.kick, table.drift)]
        self._host_table = table  # (the heat rows' tests, asked on the host: finish_deferred, _sweep_follows)
        self._carry = float(table.carry)
        self._topology = records_to_device(records.topology(system.layout), dev)
        self._springs = records_to_device(records.Springs(system.rest_lengths, P), dev)
        self._nodes = records_to_device(records.nodes(system), dev)
        self._effects = records_to_device(flow_data(flows, system), dev)
        self._loads = records_to_device(self.loads.arrays, dev) if self.loads is not None else self._nodes  # loads
        self._s = cuda.device_array(max(m, 1))
        self._x = cuda.device_array((n, 3))
        self._x_buf = cuda.device_array((n, 3))
        self._p = cuda.device_array((n, 3))
        empty = cuda.device_array(0)
        self._phi = cuda.device_array(m) if system.thermal else empty
        self._eta = cuda.device_array(m) if system.thermal else empty
        self._flag = cuda.to_device(np.zeros(4, np.int64))
        self._backup = None  # (state, step, h, (x, p, phi, eta) device copies) of a recent call's start
        self._fused_blocks = None
        self._spring_ops, self._node_ops = dev(np.array(SPRING_OPS, np.int32)), dev(np.array(NODE_OPS, np.int32))
        blocks = self._k.reduce_blocks
        self._spring_partial = cuda.device_array((blocks, len(SPRING_OPS)))
        self._node_partial = cuda.device_array((blocks, len(NODE_OPS)))
        self._spring_out = cuda.device_array(len(SPRING_OPS))
        self._node_out = cuda.device_array(len(NODE_OPS))
        self._bound = None  # the host State whose arrays the device arrays hold (or are newer than)
        self._device_newer = False
        self._launchers: dict[int, Launcher] = {}

    # ------------------------------------------------------------------------------------------
    # host <-> device

    def _bind(self, state) -> None:
        """Upload ``state`` unless it is the one already on the device."""
        if state is self._bound:
            return
        self._x.copy_to_device(np.ascontiguousarray(state.positions))
        self._p.copy_to_device(np.ascontiguousarray(state.momenta))
        if self.system.thermal:
            self._phi.copy_to_device(np.ascontiguousarray(state.thermal_displacement))
            self._eta.copy_to_device(np.ascontiguousarray(state.entropy))
        self._heat.upload(state)
        if self.loads is not None:  # loads: the work accumulators
            self._loads.work.copy_to_device(work_of(state, len(self.loads.arrays.work)))
        self._bound = state
        self._device_newer = False

    def sync(self, state) -> None:
        """Copy the device state into ``state``'s arrays if the device holds a newer one."""
        if state is not self._bound or not self._device_newer:
            return
        self._x.copy_to_host(state.positions)
        self._p.copy_to_host(state.momenta)
        if self.system.thermal:
            self._phi.copy_to_host(state.thermal_displacement)
            self._eta.copy_to_host(state.entropy)
        self._heat.download(state)
        if self.loads is not None:  # loads: the work accumulators
            self._loads.work.copy_to_host(work_of(state, len(self.loads.arrays.work)))
        self._device_newer = False

    def _state_arrays(self):
        return records.StateArrays(self._x, self._p, self._phi, self._eta)

    def _changing_arrays(self) -> tuple:
        """The device arrays a step changes, which a backup copies: the state's and the heat logs."""
        return tuple(self._state_arrays()) + self._heat.logs

    # ------------------------------------------------------------------------------------------
    # stepping

    def _stage(self, k1: float, k2: float, drift: float, with_force: bool, run, where, keep: bool = False,
               finish: bool = False, kick_first: float | None = None, spring_pass: bool = True) -> None:
        """One stage: the spring pass (with ``finish``, first ending the forward conduction
        sweep before it; with ``keep``, keeping θ and l for the sweep after it), the node pass,
        the loads' pass. ``kick_first``: the node pass first kicks by it with the forces in
        ``heat.s_before`` (a deferred closing kick's); ``spring_pass`` False: only the node pass,
        kicking by k2 with those forces (a call's last deferred closing kick)."""
        k = self._k
        n = self.system.n_nodes
        if with_force and spring_pass:
            self._spring_pass(self._s, (k1, k2), run, where, keep, finish)
        split = kick_first is not None
        s = self._s if spring_pass else self._heat.s_before
        if n > 0:
            self._launch(k.node, k.blocks(n), k.threads, self._x, self._x_buf, self._p, s, self._topology,
                         self._nodes, (kick_first if split else k1, k2, drift, with_force, split), self._flag,
                         self._loads, self._heat.s_before if split else s)
        if self.loads is not None and (with_force or drift != 0.0):  # loads: work, then the drive at t_after
            self._launch(k.load_stage, 1, len(self.loads.arrays.work), self._x, self._x_buf, self._s, self._topology,
                         self._nodes, self._loads, (k1, k2, with_force, drift != 0.0), self._t_after)
        self._x, self._x_buf = self._x_buf, self._x

    def _spring_pass(self, s, steps, run, where, keep: bool, finish: bool) -> None:
        """T/l of every spring into ``s`` (:func:`~thermonet.explicit.cuda.kernels._spring_update`)."""
        m = self.system.n_springs
        if m > 0:
            self._launch(self._k.spring, self._k.blocks(m), self._k.threads, self._x, self._eta, self._phi,
                         self._springs, self._topology.edges, s, steps, run, self._flag, where, self._heat.kept, keep,
                         finish)

    def _flow(self, slot: int, tau: float, t: float) -> None:
        data = self._effects[slot]
        kernel = self._k.flows[slot]
        count = data[0].shape[0]
        if count > 0:
            self._launch(kernel, self._k.blocks(count), self._k.threads, data, tau, t, self._x, self._p, self._phi,
                         self._eta, self._flag)

    def advance(self, state, n_steps: int, h: float, measure: bool = False):
        """As :meth:`thermonet.explicit.stepper.SplittingStepper.advance`: the same rows of the
        same schedule and chunk-boundary handling, so results do not depend on how a run is cut
        into chunks; a spring outside the admissible states stops the call, the device state is
        rewound to the last good step and :class:`~thermonet.integrators.base.StepFailure` names
        the spring, as on the CPU."""
        if n_steps <= 0:
            return None
        self._bind(state)
        self._keep_backup(state, h)
        self._call_step = state.step  # loads: the clock's step
        if self._heat.setup is not None and self._heat.setup.conduction:  # the conduction cycle
            from ...heat.logs import cycle_of

            self._cycle = cycle_of(state, self._heat.setup)
        stop = self._steps(float(state.time), int(n_steps), float(h))
        self._device_newer = True
        if stop is not None:
            self._stopped(state, float(h), *stop)
        return None

    def _steps(self, t0: float, n_steps: int, h: float):
        """n_steps steps from time t0 on the device state; None, or where a launch stopped:
        (flag, steps completed before its launch sequence, positions buffer at that start)."""
        from ...heat.cuda import _conduction_due, _sweep_follows, finish_deferred, joined_boundary  # (the rows' own tests)

        lo, hi = self.system.stretch_bounds
        every, at, sweeps = self._cycle
        run = records.Run(h, t0, n_steps, bool(self.integrator.track_phi), float(lo), float(hi), False, False, every, at)
        fused = self.fused if self.fused is not None else self.system.n_springs < self.FUSED_MAX_SPRINGS
        if fused:
            done = 0
            while done < n_steps:
                chunk = min(n_steps - done, self.FUSED_MAX_STEPS)
                chunk_start = self._x
                self._fused_steps(run._replace(n_steps=chunk, t0=t0 + done * h, cycle_step=(at + done) % every))
                flag = self._flag.copy_to_host()
                if flag[FLAG_SET]:
                    return flag, done, chunk_start
                done += chunk
            return None
        x_start = self._x
        pending = 0.0
        stages = 0  # node passes made (which position buffer holds the current positions)
        heat = self._heat.record(h, every, sweeps) if self._heat.setup is not None else None
        theta_ok = self._heat.theta_ok() if heat is not None else 0.0
        theta_valid = theta_ok >= 1.0
        start_kept = finish = False  # as in _steps_kernel
        joined_layout = self._closing >= 0 and bool(joined_boundary(self._host_table))
        joined = saved = False
        resume = joined_layout and theta_ok == 2.0
        conduction = heat is not None and self._heat.setup.conduction
        clock = self._load_clock(h)  # loads
        deferred, split = 0.0, False  # a deferred closing kick (see _steps_kernel)
        for step in range(n_steps):
            t_step = t0 + step * h
            for r, (code, kick, drift) in enumerate(self._rows):
                if code >= FIRST_FLOW_SLOT:
                    self._flow(code, kick * h, t_step + drift * h)
                    theta_valid = start_kept = False
                    continue
                if code <= CONDUCTION_FORWARD:
                    if code == THERMAL_WAVES:
                        self._heat_row(heat, code, kick * h, t_step + drift * h, theta_valid, False)
                        theta_valid = start_kept = False
                    elif _conduction_due(code, every, (at + step) % every):
                        finish = bool(finish_deferred(self._host_table, r))
                        follows = joined_layout and step + 1 < n_steps
                        self._heat_row(heat, code, kick * every * h, t_step + drift * h, theta_valid, start_kept,
                                       finish, (joined, follows, resume and step == 0))
                        joined = joined_layout and code == CONDUCTION_REVERSE and follows
                        saved = joined_layout and code == CONDUCTION_REVERSE and not follows
                        theta_valid, start_kept, resume = True, code == CONDUCTION_REVERSE, False
                    continue
                if clock is not None:  # loads: the time at the end of this stage's drift
                    self._t_after = clock[0] + ((clock[1] + step) + self._drift_time[r]) * h
                k1 = pending if r == 0 else 0.0
                row, kick_first = r, None
                if r == self._closing:  # deferred: a spring pass now if a sweep follows, the rest later
                    deferred = kick
                    split = bool(_sweep_follows(self._host_table, r, every, (at + step) % every))
                    if split:
                        self._spring_pass(self._heat.s_before, (0.0, kick * h), run, (step, r, stages), True, False)
                        theta_valid = start_kept = True
                    continue
                if deferred != 0.0:  # the first stage after a deferred closing kick
                    if split:
                        kick_first = deferred * h
                    else:
                        k1, row = deferred, 0  # (0: found at the previous step's end positions)
                    deferred = 0.0
                with_force = k1 != 0.0 or kick != 0.0
                keep = conduction and with_force and drift == 0.0 and bool(
                    _sweep_follows(self._host_table, r, every, (at + step) % every))
                self._stage(k1 * h, kick * h, drift * h, with_force, run, (step, row, stages), keep, finish, kick_first)
                finish = False
                if with_force or drift != 0.0:
                    theta_valid = start_kept = keep  # see _steps_kernel
                stages += 1
            pending = self._carry
        if deferred != 0.0 and not split:  # the call's last closing kick, a stage of its own
            self._stage(0.0, deferred * h, 0.0, True, run, (n_steps, len(self._rows), stages))
            theta_valid = False
        elif deferred != 0.0:  # its forces computed before the sweep: only its node pass is left
            self._stage(0.0, deferred * h, 0.0, True, run, (n_steps, len(self._rows), stages), spring_pass=False)
        if heat is not None and self._heat.setup.conduction:
            self._heat.set_theta_ok((2.0 if saved else 1.0) if theta_valid else 0.0)
        if pending != 0.0:
            self._stage(0.0, pending * h, 0.0, True, run, (n_steps, len(self._rows), stages))
        flag = self._flag.copy_to_host()
        return (flag, 0, x_start) if flag[FLAG_SET] else None

    def _heat_row(self, heat, code: int, tau: float, t: float, theta_valid: bool, start_kept: bool,
                  finish_deferred: bool = False, junction=(False, False, False)) -> None:
        """Heat row ``code`` over τ at time t, one launch per phase (:mod:`thermonet.heat.cuda`),
        after a temperature pass when a conduction sweep has no valid θ; the phases
        :func:`~thermonet.heat.cuda.conduction_plan` names, ``junction`` its (joined, follows,
        resume): without the start phase when the pass before kept θ as the start
        (``start_kept``, or after a temperature pass), without the finish phase when the next
        spring pass runs it (``finish_deferred``)."""
        from ...heat.cuda import conduction_plan, phase_mode

        k = self._k
        m = self.system.n_springs
        if code != THERMAL_WAVES and not theta_valid:
            if m > 0:
                self._launch(k.temperature, k.blocks(m), k.threads, self._x, self._eta, self._topology.edges,
                             self._springs, heat, self._flag)
            start_kept = True
        phases = self._heat.phases(code, self._cycle[2])
        lo, hi, skip, together, start_mode, finish_mode = 0, len(phases), -1, -1, 0, 0
        if code != THERMAL_WAVES:
            lo, hi, skip, together, start_mode, finish_mode = conduction_plan(
                code, len(phases), len(self._heat.star_colour_ptr) - 1, self._cycle[2], self._heat.n_bound,
                start_kept, finish_deferred, *junction)
        for phase, count in phases[lo:hi]:
            if count > 0 and phase != skip:
                mode = int(phase_mode(phase, len(phases), together, start_mode, finish_mode))
                self._launch(k.sweep, k.blocks(count), k.threads, code, phase, heat, tau, t, self._phi, self._eta,
                             self._flag, mode)

    def _launch(self, kernel, blocks: int, threads: int, *args) -> None:
        """``kernel[blocks, threads](*args)`` through its :class:`~thermonet.explicit.cuda.launch.Launcher`."""
        launcher = self._launchers.get(id(kernel))
        if launcher is None:
            launcher = self._launchers[id(kernel)] = Launcher(kernel)
        launcher(blocks, threads, *args)

    _t_after = 0.0  # loads: the time at the end of the current stage's drift

    def _load_clock(self, h: float):
        """(origin time, steps from it) of this call, and the loads evaluated at its first kick
        (None without loads); see :meth:`thermonet.loads.stepping.StepperLoads.arrays_for`."""
        if self.loads is None:
            return None
        step0, t0 = self.loads.time_origin()
        clock = (float(t0), float(self._call_step - step0))
        self._drift_time = self.loads.arrays.drift_time
        t = clock[0] + (clock[1] + self.loads.arrays.kick_time[0]) * h
        self._k.load_start[1, len(self.loads.arrays.work)](self._loads, t)
        return clock

    def _fused_steps(self, run) -> None:
        """``run.n_steps`` steps as one cooperative launch; the same rows as :meth:`advance`'s
        two-launch loop (including the closing half kick), so a chunk ends in the same state."""
        k = self._k
        args = (self._state_arrays(), self._x_buf, self._s, self._topology, self._springs, self._nodes, self._table,
                (self._effects, self._heat.record(run.h, run.conduction_every, self._cycle[2])), run, self._flag)
        if self._fused_blocks is None:
            self._fused_blocks = self._cooperative_blocks(args)
        self._fused_kernel()[self._fused_blocks, k.threads](*args)
        if self.node_passes(run.n_steps) % 2:
            self._x, self._x_buf = self._x_buf, self._x

    def node_passes(self, n_steps: int) -> int:
        """Node passes of a call of ``n_steps`` steps (each writes the other position buffer):
        one per stage, the carry's closing kick, and one fewer per step where the closing kick is
        deferred (:func:`thermonet.heat.cuda.deferred_closing`: it joins the next step's first
        stage, the call's last one runs at its end)."""
        stages = sum(1 for c, _, _ in self._rows if c == -1)
        if self._closing >= 0:
            return n_steps * (stages - 1) + 1
        return n_steps * stages + (1 if self._carry != 0.0 else 0)

    def _fused_kernel(self):
        """The fused kernel compiled for this net's size: on nets below :data:`SMALL_NET_SPRINGS`
        the variant with room for more registers (``kernels.SMALL_NET_LAUNCH_BOUNDS``)."""
        return self._k.steps_small if self.system.n_springs < self.SMALL_NET_SPRINGS else self._k.steps

    def _cooperative_blocks(self, args) -> int:
        """Blocks of the fused launch: enough for one thread per spring or node, at most as many
        as can be resident at once (a grid-wide barrier needs every block running), and at most
        :data:`SMALL_NET_BLOCKS_PER_SM` a multiprocessor on small nets; one block under the
        simulator, which supports grid barriers only there."""
        from numba import typeof

        from . import simulator_enabled

        if simulator_enabled():
            return 1
        k = self._k
        kernel = self._fused_kernel().compile(tuple(typeof(a) for a in args))
        return fused_grid(self.system.n_springs, self.system.n_nodes, k.threads,
                          kernel.max_cooperative_grid_blocks(k.threads),
                          self._cuda.get_current_device().MULTIPROCESSOR_COUNT)

    def _keep_backup(self, state, h: float) -> None:
        """A device copy of the state at this call's start, unless one of this history at most
        :data:`BACKUP_SPAN` steps back is kept already."""
        b = self._backup
        if b is not None and b[0] is state and b[2] == h and 0 <= state.step - b[1] < self.BACKUP_SPAN:
            return
        arrays = self._changing_arrays()
        copies = b[4] if b is not None else tuple(self._cuda.device_array_like(a) for a in arrays)
        for source, target in zip(arrays, copies):
            target.copy_to_device(source)
        self._backup = (state, state.step, h, float(state.time), copies)

    def _stopped(self, state, h: float, flag, steps_before: int, x_start) -> None:
        """A launch found a spring outside the admissible states: name it from the positions
        where it was found, restore the backup, replay the good steps and raise."""
        step, row = int(flag[FLAG_STEP]), int(flag[FLAG_ROW])
        found_at = x_start if int(flag[FLAG_STAGES]) % 2 == 0 else (self._x_buf if x_start is self._x else self._x)
        positions = found_at.copy_to_host()
        entropy = self._eta.copy_to_host() if self.system.thermal else None
        # positions at row 0 are the end of the previous step, and a closing kick's (row = the
        # table's length) those of the call's last step: that step was the bad one
        at_step_end = (row == 0 and step > 0) or row == len(self._rows)
        done = steps_before + (step - 1 if at_step_end else step)
        failure = blowup_failure(self.system, positions, entropy, done)
        self._flag.copy_to_device(np.zeros(4, np.int64))
        _, backup_step, _, backup_time, copies = self._backup
        for source, target in zip(copies, self._changing_arrays()):
            target.copy_to_device(source)
        replay = state.step - backup_step + done
        self._call_step = backup_step  # loads (their work accumulators are not rewound: the run stops here)
        if replay > 0 and self._steps(backup_time, replay, h) is not None:
            # the same launches from the same state: only a nondeterministic device could stop again
            raise RuntimeError("the replay of the good steps stopped again")
        raise failure

    # ------------------------------------------------------------------------------------------
    # diagnostics

    def diagnostics_row(self, system, state) -> dict[str, float]:
        """One diagnostics row (the keys of :func:`thermonet.diagnostics.measure`), reduced on the
        device from the device state; only the few sums come back."""
        self._bind(state)
        k = self._k
        blocks, threads = k.reduce_blocks, k.reduce_threads
        k.spring_sums[blocks, threads](self._x, self._eta, self._springs.rest, self._springs.P, self._topology.edges,
                                       self._spring_partial)
        k.finish[1, threads](self._spring_partial, self._spring_ops, self._spring_out)
        k.node_sums[blocks, threads](self._x, self._p, self._nodes.masses, self._nodes.anchored, self._nodes.reference,
                                     self._nodes.gravity,
                                     self._node_partial)
        k.finish[1, threads](self._node_partial, self._node_ops, self._node_out)
        internal, entropy, theta_min, theta_max = (float(v) for v in self._spring_out.copy_to_host())
        if self._heat.setup is not None and self._device_newer:  # the heat columns read the logs (and W(Φ) Φ)
            self._heat.download(state)
            if self._heat.setup.waves:
                self._phi.copy_to_host(state.thermal_displacement)
        kinetic, potential, px, py, pz, Lx, Ly, Lz = (float(v) for v in self._node_out.copy_to_host())
        return diagnostics_row(system, state, kinetic, internal, potential, entropy, (px, py, pz), (Lx, Ly, Lz),
                               theta_min, theta_max)


def fused_grid(springs: int, nodes: int, threads: int, resident: int, multiprocessors: int) -> int:
    """Blocks of a fused launch over a net of ``springs`` and ``nodes``: one thread per spring or
    node if that many blocks of ``threads`` can be resident at once (``resident``, the device's
    answer for the kernel), else all that can; on nets below
    :data:`CudaSplittingStepper.SMALL_NET_SPRINGS` at most
    :data:`~CudaSplittingStepper.SMALL_NET_BLOCKS_PER_SM` per multiprocessor."""
    if springs < CudaSplittingStepper.SMALL_NET_SPRINGS:
        resident = min(resident, CudaSplittingStepper.SMALL_NET_BLOCKS_PER_SM * multiprocessors)
    needed = (max(springs, nodes, 1) + threads - 1) // threads
    return max(1, min(resident, needed))


def records_to_device(record, to_device):
    """``record`` (a possibly nested tuple or named tuple) with every NumPy array copied to the
    device; scalars stay as they are."""
    if isinstance(record, np.ndarray):
        return to_device(record)
    if isinstance(record, tuple):
        items = [records_to_device(item, to_device) for item in record]
        return type(record)(*items) if hasattr(record, "_fields") else tuple(items)
    return record
