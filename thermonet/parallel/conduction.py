"""Heat conduction in the explicit step over processes, bit for bit that of one process.

A call runs the CPU kernel's conducting ``advance`` (:func:`thermonet.explicit.cpu._advance`)
step by step, in the same order and with the same compiled passes, on the process's share
(:mod:`thermonet.parallel.heat_stages`): the kick deferred past a sweep, the refresh of the
forces from the swept temperatures, the closing kick, the sweeps' continuation across calls.

The conduction sweeps are divided among the processes (:mod:`thermonet.parallel.sweep`): each
sweeps its blocks of junctions colour by colour and sends the temperatures it changed to the
processes holding them between the colours. The share's heat logs, with the temperatures and
lengths the next call continues from, stay in the process from call to call (as its positions);
they are put together on rank 0 when the whole state is read (:meth:`DistributedConduction.to_root`).
"""

from __future__ import annotations

import numpy as np

from ..heat.logs import cycle_of, heat_logs
from ..heat.passes import CONTINUE, FORWARD, REVERSE, SAVE
from ..kernels import records
from ..loads.elements import NO_LOADS
from .sweep import DistributedSweep


class DistributedConduction:
    """The conducting calls of a :class:`~thermonet.parallel.stepper.DistributedStepper`.

    stepper: the stepper (its share, halo, records and buffers); functions: the compiled stage
    functions of :func:`~thermonet.parallel.heat_stages.heat_stage_functions`; temperature_pass:
    the conducting CPU kernel variant's; phases: the sweep's, of
    :func:`~thermonet.parallel.heat_stages.sweep_phase_functions`.
    """

    def __init__(self, stepper, functions, temperature_pass, phases):
        self.stepper = stepper
        self.heat = stepper.system.heat
        self._forces, self._before_sweep, self._kick_drift, self._deferred_alone, self._closing = functions
        self._temperature = temperature_pass
        sh = stepper.share
        ml = len(sh.springs)
        self._length = np.empty(ml)  # the share's spring lengths kept with θ (the whole net's heat.length)
        self._strain = np.empty(ml)  # their strains (Model.strain), valid where a spring pass kept them
        self._s_before = np.empty(ml)  # the forces of a kick deferred past a sweep
        self._theta_log = np.empty(ml)  # the share's part of the whole heat log "theta"
        self._sweep = DistributedSweep(self.heat, stepper.decomposition, sh, stepper.comm, phases, stepper.rank)

    def take(self, state) -> None:
        """This process's part of ``state``'s heat logs (a state it has not stepped yet): the
        lengths and temperatures the next call continues from, the sweep's logs."""
        sh = self.stepper.share
        logs = heat_logs(state, self.heat)
        np.take(logs["length"], sh.springs, out=self._length)
        np.take(logs["theta"], sh.springs, out=self._theta_log)
        self._sweep.take(logs)
        self.continue_from_logs(state)

    def continue_from_logs(self, state) -> None:
        """The next call continues from the share's logs (taken, or put back from a backup): the
        kept temperatures, where the logs say they are valid."""
        if heat_logs(state, self.heat)["theta_ok"][0] >= 1.0:
            self.stepper._scratch.theta_keep[:] = self._theta_log

    def share_logs(self) -> dict:
        """The per-spring and per-entry heat logs this process keeps for its share (arrays it
        steps in place), keyed as the whole ones."""
        return {"length": self._length, "theta": self._theta_log, **self._sweep.share_logs()}

    @property
    def entries(self) -> np.ndarray:
        """(E_r,) int64 the bath and source entries whose logs this process keeps (whole-net
        entry numbers: the same in every numbering)."""
        return self._sweep.part.entries

    def to_root(self, state) -> None:
        """The shares' heat logs into ``state``'s whole ones on rank 0 (every process must call it)."""
        self._sweep.to_root(state.extra["heat"], [(self._length, state.extra["heat"]["length"]),
                                                  (self._theta_log, state.extra["heat"]["theta"])])

    def heat_sums(self) -> np.ndarray:
        """This process's exact accumulators of a row's heat-flow sums (:meth:`DistributedSweep.heat_sums`)."""
        return self._sweep.heat_sums(self.stepper._counted)

    def advance(self, state, n_steps: int, h: float) -> None:
        """``n_steps`` steps of the share (taken from ``state`` by the stepper), as the CPU
        kernel's ``advance`` with conduction: the share's x, p, Φ, η and heat logs stay in the
        shares (the stepper puts them together when read); the logs' cycle and theta_ok, the same
        on every process, are updated in the whole logs of every process."""
        st = self.stepper
        logs = heat_logs(state, self.heat)
        every, cycle_step, sweeps = cycle_of(state, self.heat)
        lo, hi = st.system.stretch_bounds
        run = records.Run(float(h), float(state.time), int(n_steps), bool(st.integrator.track_phi), float(lo),
                          float(hi), False, False, int(every), int(cycle_step))
        arrays = records.StateArrays(st._x, st._p, st._phi, st._eta)
        scratch = st._scratch
        before = scratch._replace(s=self._s_before)
        topology, springs, nodes = st._topology, st._springs, st._nodes
        length, strain, s_before = self._length, self._strain, self._s_before
        cur, nxt = st._x, scratch.x_buf
        kicks, drifts, carry = st._kicks, st._drifts, st._carry
        pending = deferred = 0.0
        theta_valid = ended_cycle = resume_sweep = False
        strain_ok = False  # as the kernel's: the strains are those of the lengths
        if logs["theta_ok"][0] >= 1.0:  # continue the previous call's sweeps (theta_keep holds them)
            theta_valid = True
            resume_sweep = logs["theta_ok"][0] == 2.0

        def boundary(directions: int, step: int) -> bool:
            """The sweeps at the start of step ``step``; False when the pending kick's spring pass
            found an inadmissible spring (on any process)."""
            nonlocal strain_ok
            if pending == 0.0 and not theta_valid:
                self._temperature(cur, arrays.eta, topology, springs, scratch.theta_keep, length)
                strain_ok = False
            if pending != 0.0:
                if st._any(self._before_sweep(cur, arrays, topology, springs, before, (length, strain), pending, run)):
                    return False
                strain_ok = True
            self._sweep.sweep(logs["theta_ok"], scratch.theta_keep, arrays.eta,
                              0.5 * run.conduction_every * run.h / sweeps, run.t0 + step * run.h, directions, sweeps)
            return True

        for step in range(n_steps):
            if (cycle_step + step) % every == 0:
                directions = FORWARD | REVERSE if step > 0 else (FORWARD | CONTINUE if resume_sweep else FORWARD)
                if not boundary(directions, step):
                    return self._failed(state, logs, cur, step - 1)
                if pending != 0.0:
                    deferred, pending = pending, 0.0
                theta_valid = True
            for r, (k2, drift) in enumerate(zip(kicks, drifts)):
                k1 = pending if r == 0 else 0.0
                with_force = k1 != 0.0 or k2 != 0.0
                steps = records.KickDrift(k1 * h, k2 * h, drift * h, with_force)
                if with_force:
                    # after a sweep (θ valid): the forces from the swept θ, no θ(l, η); the kernel's
                    # deferred entropy update (finish_refresh_pass) the sweep here made already
                    bad = self._forces(cur, arrays, topology, springs, scratch, (length, strain, strain_ok),
                                       (k1 * h, k2 * h), run, drift == 0.0, theta_valid)
                    strain_ok = strain_ok or not theta_valid  # (a spring pass keeps them with l)
                    if st._any(bad):  # row 0's positions end the previous step: that one was bad
                        return self._failed(state, logs, cur, step - 1 if r == 0 and step > 0 else step)
                    theta_valid = True
                if drift != 0.0:
                    theta_valid = False
                self._kick_drift(cur, nxt, arrays, topology, nodes, scratch, steps, s_before, NO_LOADS, deferred, k2,
                                 drift, h)
                deferred = 0.0
                cur, nxt = nxt, cur
                if drift != 0.0:
                    st.halo.exchange(cur)
            pending = carry
        if (cycle_step + n_steps) % every == 0:  # the call ends a cycle: its reverse half sweep
            if not boundary(REVERSE | SAVE, n_steps):
                return self._failed(state, logs, cur, n_steps - 1)
            if pending != 0.0:
                deferred, pending = pending, 0.0
            theta_valid = True
            ended_cycle = True
        if deferred != 0.0:  # drift 0: the positions stay in cur
            self._deferred_alone(cur, nxt, arrays, topology, nodes, scratch, s_before, NO_LOADS, deferred * h)
        if pending != 0.0:
            if st._any(self._closing(cur, nxt, arrays, topology, springs, nodes, scratch, (length, strain), s_before,
                                     NO_LOADS, pending, run)):
                return self._failed(state, logs, cur, n_steps - 1)
            theta_valid = True
        if theta_valid:
            self._theta_log[:] = scratch.theta_keep
        logs["theta_ok"][0] = (2.0 if ended_cycle else 1.0) if theta_valid else 0.0
        st._ended(cur)
        return None

    def _failed(self, state, logs, cur, steps_done: int):
        """A spring left the admissible states: the state as far as it got, the sweeps' kept
        temperatures no longer valid (as the kernel's), then the stepper's stop."""
        logs["theta_ok"][0] = 0.0
        return self.stepper._stopped(state, cur, steps_done)
