"""Heat conduction in the explicit step over processes, bit for bit that of one process.

A call runs the CPU kernel's conducting ``advance`` (:func:`thermonet.explicit.cpu._advance`)
step by step, in the same order and with the same compiled passes, on the process's share
(:mod:`thermonet.parallel.heat_stages`): the kick deferred past a sweep, the refresh of the
forces from the swept temperatures, the closing kick, the sweeps' continuation across calls.

The conduction sweeps are divided among the processes (:mod:`thermonet.parallel.sweep`): each
sweeps its blocks of junctions colour by colour and sends the temperatures it changed to the
processes holding them between the colours; a call gathers the share's entropies and heat logs
into the whole state at its end, with the temperatures and lengths the next call continues from.
"""

from __future__ import annotations

import numpy as np

from ..heat.logs import cycle_position, heat_logs
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
        self.heat.without_work_arrays()  # (the whole net's record only lends factors; the share sweeps with its own)
        self._forces, self._before_sweep, self._kick_drift, self._deferred_alone, self._closing = functions
        self._temperature = temperature_pass
        sh = stepper.share
        ml = len(sh.springs)
        self._length = np.empty(ml)  # the share's spring lengths kept with θ (the whole net's heat.length)
        self._strain = np.empty(ml)  # their strains (Model.strain), valid where a spring pass kept them
        self._s_before = np.empty(ml)  # the forces of a kick deferred past a sweep
        self._sweep = DistributedSweep(self.heat, stepper.decomposition, sh, stepper.comm, phases)

    def advance(self, state, n_steps: int, h: float) -> None:
        """``n_steps`` steps of the share (taken from ``state`` by the stepper), as the CPU
        kernel's ``advance`` with conduction; the whole net's η and heat logs updated in place on
        every process; the share's x, p, Φ stay in the shares (the stepper puts them together when read)."""
        st = self.stepper
        sh = st.share
        logs = heat_logs(state, self.heat)
        every, cycle_step = cycle_position(state, self.heat)
        record = self.heat.record(0.5 * every * h, logs)
        lo, hi = st.system.stretch_bounds
        run = records.Run(float(h), float(state.time), int(n_steps), bool(st.integrator.track_phi), float(lo),
                          float(hi), False, False, int(every), int(cycle_step))
        arrays = records.StateArrays(st._x, st._p, st._phi, st._eta)
        scratch = st._scratch
        before = scratch._replace(s=self._s_before)
        topology, springs, nodes = st._topology, st._springs, st._nodes
        length, strain, s_before = self._length, self._strain, self._s_before
        np.take(logs["length"], sh.springs, out=length)
        self._sweep.begin(logs)
        cur, nxt = st._x, scratch.x_buf
        kicks, drifts, carry = st._kicks, st._drifts, st._carry
        pending = deferred = 0.0
        theta_valid = ended_cycle = resume_sweep = False
        strain_ok = False  # as the kernel's: the strains are those of the lengths
        if logs["theta_ok"][0] >= 1.0:  # continue the previous call's sweeps
            np.take(logs["theta"], sh.springs, out=scratch.theta_keep)
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
            self._sweep.sweep(record, scratch.theta_keep, arrays.eta, 0.5 * run.conduction_every * run.h,
                              run.t0 + step * run.h, directions)
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
        more = [(length, logs["length"])] + ([(scratch.theta_keep, logs["theta"])] if theta_valid else [])
        self._sweep.gather(st._eta, state, logs, more)
        logs["theta_ok"][0] = (2.0 if ended_cycle else 1.0) if theta_valid else 0.0
        st._ended(cur)
        return None

    def _failed(self, state, logs, cur, steps_done: int):
        """A spring left the admissible states: the state as far as it got (η and the logs
        gathered), the sweeps' kept temperatures no longer valid (as the kernel's), then the
        stepper's stop."""
        self._sweep.gather(self.stepper._eta, state, logs, [])
        logs["theta_ok"][0] = 0.0
        return self.stepper._stopped(state, cur, steps_done)
