"""The runner of a :class:`~thermonet.simulation.Simulation`: steps between observer stops
(diagnostics rows, frames, checkpoints, progress at their cadences), the backup and replay of
the last good state after a blow-up, and the energy policy checked at the diagnostics cadence.

A Simulation holds one :class:`Runner` (``sim.runner``) and calls it from ``run``. The runner
keeps what only running needs (the backup of the state, the last stepper statistics) and works
on the Simulation's state, stepper, system and diagnostics through the Simulation it was made for.
"""

from __future__ import annotations

import math
import time as _time
from typing import Callable, Iterable

import numpy as np

from .blowup import remedy
from .compile_watch import CompileWatch
from .diagnostics import Diagnostics, diagnostics_row, measure
from .errors import InputError, SimulationError
from .heat.logs import balances, cycle_of, heat_columns, heat_logs, wave_energy
from .heat.multirate import ConductionCycle, choose_cycle
from .integrators.base import StepFailure
from .run_guards import energy_departure
from .state import State
from .step_policy import whole_steps


class Runner:
    """Running one Simulation in time (see the module docstring)."""

    #: steps a backup of the state may lag behind a chunk's start (explicit CPU runs): copying
    #: the state at every observer stop costs a noticeable share of a short chunk, and a rewind
    #: replays at most this many steps more
    BACKUP_SPAN = 256

    def __init__(self, sim):
        self.sim = sim
        #: (start, compile watch) of the run in progress (None between runs)
        self._running = None
        #: a copy of an earlier state of this run (explicit CPU runs; :meth:`_keep_backup`), and
        #: (state, h) it was taken of: a loaded state or a new h makes it useless for replays
        self.backup: State | None = None
        self.backup_of: tuple = (None, None)
        #: the statistics of the stepper's last ``advance`` (implicit steppers' Newton counts)
        self.last_stats: dict = {}

    def steps_until(self, t_end: float) -> int:
        """Steps from the current time to ``t_end``, which must be a whole number of steps
        (:func:`thermonet.step_policy.whole_steps`; an InputError otherwise)."""
        sim = self.sim
        return whole_steps(t_end, sim.h, sim._state.time)

    def run(
        self,
        t_end: float | None = None,
        steps: int | None = None,
        diagnostics_every: int | None = None,
        observers: Iterable[tuple[int, Callable]] = (),
        progress: Callable[[int, int, float], None] | None = None,
    ) -> Diagnostics:
        """Advance by ``steps`` steps, or to ``t_end``.

        diagnostics_every: a diagnostics row every k steps (and at the start and end);
            default: about 1000 rows over the run (a multiple of the conduction cycle).
        observers: (k, callback) pairs (then the Simulation's probes, if any); ``callback(sim)`` is called every k steps (at multiples of
            k in the global step count) and at the end of the run. Where a callback is a bound
            method of an object with a ``flush()`` method (``RunOutput``: frames written on a
            thread), that is called before ``run`` returns or raises.
        progress: called as ``progress(done, total, elapsed_seconds)`` at each stop, elapsed
            without the time Numba spent compiling kernels; where it has a ``compiling()``
            method, that is called when the run starts compiling a kernel (first runs only).
        Returns the diagnostics series (``sim.diagnostics``, accumulated over runs).
        """
        sim = self.sim
        if (t_end is None) == (steps is None):
            raise InputError("run: give exactly one of t_end or steps")
        if steps is None:
            if not math.isfinite(t_end):
                raise InputError(f"run: t_end must be finite, got {t_end}")
            steps = self.steps_until(t_end)
        steps = int(steps)
        if steps < 0:
            raise InputError(f"run: steps must be >= 0, got {steps}")
        if diagnostics_every is None:  # about 1000 rows, on conduction cycles' boundaries
            k = self._conduction_cycle_wanted()
            diagnostics_every = max(k, max(1, steps // 1000) // k * k)
        if diagnostics_every < 1:
            raise InputError(f"run: diagnostics_every must be >= 1, got {diagnostics_every}")
        cadences = [(int(diagnostics_every), self._diagnostics_stop)] + [(int(k), cb) for k, cb in observers]
        if sim.probes is not None:  # (after the observers: they only read the state)
            cadences += [(int(k), cb) for k, cb in sim.probes.observers(int(diagnostics_every))]
        for k, _ in cadences:
            if k < 1:
                raise InputError(f"run: observer cadence must be >= 1, got {k}")
        self._choose_conduction_cycle(steps, [k for k, _ in cadences])
        if not sim.diagnostics.rows or sim.diagnostics.rows[-1]["step"] != sim._state.step:
            self._record()
        for k, cb in cadences[1:]:
            if sim._state.step % k == 0:
                cb(sim)
        threads_before = None
        if sim.threads:
            import numba

            # for this run only: a later simulation without ``threads`` gets Numba's setting back
            threads_before = numba.get_num_threads()
            numba.set_num_threads(int(sim.threads))
        start = sim._state.step
        end = start + steps
        flushes = _flushes(cadences[1:])  # (observers may have been a generator: read once above)
        watch = CompileWatch(getattr(progress, "compiling", None))  # compile time kept out of rates
        t0 = _time.perf_counter()
        self._running = (t0, watch)
        watch.__enter__()
        try:
            while sim._state.step < end:
                cur = sim._state.step
                stop = min([end] + [(cur // k + 1) * k for k, _ in cadences])
                self.advance(stop - cur, measure=stop % int(diagnostics_every) == 0 or stop == end)
                done = sim._state.step
                for k, cb in cadences:
                    if done % k == 0 or done == end:
                        if cb == self._diagnostics_stop and sim.diagnostics.rows and sim.diagnostics.rows[-1]["step"] == done:
                            continue
                        cb(sim)
                if progress is not None:
                    progress(done - start, steps, _time.perf_counter() - t0 - watch.seconds)
        except BaseException:
            for flush in flushes:  # keep what was written; the first error is the one to report
                try:
                    flush()
                except Exception:
                    pass
            raise
        finally:
            watch.__exit__()
            self._running = None
            sim.compile_time += watch.seconds
            if threads_before is not None:
                numba.set_num_threads(threads_before)
        for flush in flushes:
            flush()
        sim.wall_time += _time.perf_counter() - t0 - watch.seconds
        sim.steps_run += steps
        return sim.diagnostics

    def seconds_running(self) -> float:
        """Seconds the simulation has spent in ``run`` (compilation excluded), over all runs and
        the current one so far: what the stable-step guard's time budget is a fraction of."""
        sim = self.sim
        running = self._running
        if running is None:
            return sim.wall_time
        t0, watch = running
        return sim.wall_time + _time.perf_counter() - t0 - watch.seconds

    def _conduction_cycle_wanted(self) -> int:
        """The conduction cycle this run would take with no output cadence to follow (1 without
        conduction)."""
        sim = self.sim
        heat = sim.system.heat
        if heat is None or not heat.conduction:
            return 1
        if sim.conduction_every != "auto":
            return int(sim.conduction_every)
        return choose_cycle("auto", heat.fastest_rate(), sim._h, [])[0]

    def _choose_conduction_cycle(self, steps: int, cadences) -> None:
        """The conduction cycle of this run (:mod:`thermonet.heat.multirate`), chosen at a cycle
        boundary so that every output cadence and the run's end fall on one; a run that starts
        inside a cycle (a state left there by ``advance``) finishes it first with the same k."""
        sim = self.sim
        heat = sim.system.heat
        if heat is None or not heat.conduction or steps <= 0:
            return
        every, at, current = cycle_of(sim._state, heat)
        if at != 0:
            sim.conduction_cycle = ConductionCycle(every, f"continuing a cycle of {every} steps begun at step "
                                                          f"{sim._state.step - at}", current)
            return
        step = sim._state.step
        k, sweeps, why = choose_cycle(sim.conduction_every, heat.fastest_rate(), sim._h,
                                      list(cadences) + [steps, step], sweeps=sim.conduction_sweeps)
        if (k, sweeps) != (every, current):
            heat_logs(sim._state, heat)["cycle"][:] = (k, step, sweeps)
        sim.conduction_cycle = ConductionCycle(k, why, sweeps)

    def _set_step(self, step: int) -> None:
        """Move the step counter; time is origin + (steps since origin)·h, so it does not depend
        on how the run was cut into chunks."""
        sim = self.sim
        state = sim._state
        origin_step, origin_time = sim._time_origin
        state.step = step
        state.time = origin_time + (step - origin_step) * sim._h

    def advance(self, n: int, measure: bool = False) -> None:
        """n steps; with ``measure``, a stepper that can reduces the diagnostics sums of the end
        state on the way (see ``SplittingStepper.advance``)."""
        sim = self.sim
        step0 = sim._state.step
        backup = self._keep_backup()
        try:
            if measure and sim.stepper.measures:
                stats = sim.stepper.advance(sim._state, n, sim._h, measure=True)
            else:
                stats = sim.stepper.advance(sim._state, n, sim._h)
        except StepFailure as exc:
            if exc.details.get("rewind") and backup is not None:
                self._rewind(backup, step0 + exc.steps_done - backup.step)
            self._set_step(step0 + exc.steps_done)
            self._record()
            if exc.details.get("rewind"):
                raise StepFailure(self._blowup_message(exc, step0), exc.steps_done, exc.details) from None
            raise
        self._set_step(step0 + n)
        self.last_stats = stats or {}

    def _keep_backup(self) -> State | None:
        """A copy of the state at this or an earlier chunk start, at most :data:`BACKUP_SPAN`
        steps back, of this run's history and step size (explicit CPU runs only: their kernel
        stops mid-step and the last good step is then replayed from the copy, bit for bit;
        implicit steppers keep their state intact themselves). A copy costs about a fifth of one
        step."""
        sim = self.sim
        if sim.backend != "cpu" or not sim.integrator.explicit:
            return None
        s = sim._state
        b = self.backup
        if self._backup_usable() and s.step - b.step < self.BACKUP_SPAN:
            return b
        # (heat flow changes η; without it η stays as it was)
        b = self.backup = sim.stepper.backup_state(s, b, entropy=sim.system.heat is not None)
        b.step, b.time = s.step, s.time
        self.backup_of = (s, sim._h)  # a loaded state or a new h makes the copy useless for replays
        return b

    def _backup_usable(self) -> bool:
        """Whether the backup is an earlier state of the current history, at the current h."""
        sim = self.sim
        b = self.backup
        if b is None:
            return False
        state, h = self.backup_of
        return state is sim._state and h == sim._h and b.step <= sim._state.step

    def _rewind(self, backup: State, steps: int) -> None:
        """Restore ``backup`` (a chunk start) and replay ``steps`` steps: the run's last good
        state, bit for bit (runs do not depend on how they are chunked)."""
        sim = self.sim
        s = sim._state
        sim.stepper.restore_state(backup, s, entropy=sim.system.heat is not None)
        self._set_step(backup.step)
        if steps > 0:
            sim.stepper.advance(s, steps, sim._h)
            self._set_step(backup.step + steps)

    def _blowup_message(self, exc: StepFailure, step0: int) -> str:
        sim = self.sim
        bad_step = step0 + exc.steps_done + 1
        good_time = sim._state.time
        return (f"the run left the admissible states in step {bad_step} (t = {good_time + sim._h:.6g}): {exc}. "
                f"Stopped; the state is the last good one (step {bad_step - 1}, t = {good_time:.6g}). "
                f"{remedy(sim.integrator, sim._h)}.")

    def record_diagnostics(self) -> None:
        """Record a diagnostics row for the current state unless the last row is of this step
        (checkpoints call it so that a resumed run's rows equal an uninterrupted run's)."""
        sim = self.sim
        if not sim.diagnostics.rows or sim.diagnostics.rows[-1]["step"] != sim._state.step:
            self._record()

    def _diagnostics_stop(self, _sim=None) -> None:
        """The run loop's diagnostics observer: a row, then the run-time guards
        (:mod:`thermonet.run_guards`): the energy departure, then the stable step."""
        sim = self.sim
        self._record()
        rows = sim.diagnostics.rows
        departure = energy_departure(rows, sim.energy_tolerance)
        if departure is not None:
            bad_step, bad_time = sim._state.step, sim._state.time
            e0 = rows[0]["energy"]
            where = self._rewind_to_previous_stop()
            raise SimulationError(
                f"the energy departed from its initial value {e0:.10g} by {departure:.3g} "
                f"(relative; tolerance {sim.energy_tolerance:g}) at step {bad_step} (t = {bad_time:.6g}); "
                f"{where}. {remedy(sim.integrator, sim._h)}; "
                f"energy_tolerance (scene: integrator.energy_tolerance) sets the guard")
        try:
            sim.stability_guard.check(sim)
        except SimulationError as exc:
            where = self._rewind_to_previous_stop()
            raise type(exc)(f"{exc}; {where}. {remedy(sim.integrator, sim._h)}; or pass "
                            f"--allow-unstable-step (scene: integrator.check_step = false; API: "
                            f"stability_guard='warn') to only warn") from None

    def _rewind_to_previous_stop(self) -> str:
        """Drop the last diagnostics row and rewind the state to the row before (where the
        backup allows); returns where the state now is, in words."""
        sim = self.sim
        rows = sim.diagnostics.rows
        backup = self.backup
        dropped = rows.pop()
        last = rows[-1]["step"] if rows else -1
        if rows and self._backup_usable() and backup.step <= last:
            self._rewind(backup, last - backup.step)
            return (f"the state was rewound to step {last} (t = {sim._state.time:.6g}), "
                    "the last diagnostics stop before")
        rows.append(dropped)  # no earlier state to go back to: the row stays
        return f"the state is that of step {sim._state.step}"

    def _record(self) -> None:
        sim = self.sim
        if sim.comm is not None and sim.loads is None:
            # over MPI processes: each process reduces its share, the exact sums are added over
            # the processes, and every process makes the same row (no whole state gathered)
            row = self._row(sim.stepper.row_sums(sim._state))
        else:  # (the loads' columns read the loaded nodes: the row is made by rank 0 from the state put together there)
            row = sim.on_root(self._row, whole=False)
        sim.diagnostics.append(row)
        self._check_physical(row)

    def _row(self, sums: dict | None = None) -> dict:
        """The diagnostics row of the current state (with the heat flow's and the loads' columns);
        sums: its sums reduced already (keyed as :func:`diagnostics_row`'s arguments), or None."""
        sim = self.sim
        row = None
        if sums is None:
            row = sim.stepper.diagnostics_row(sim.system, sim._state)  # a device-resident state
            if row is None:
                sums = sim.stepper.closing_sums(sim._state)  # reduced by the last advance
        if row is None:
            row = (diagnostics_row(sim.system, sim._state, **sums) if sums is not None
                   else measure(sim.system, sim._state, sim.parallel))
        heat = sim.system.heat
        if heat is not None:
            if heat.waves:
                row["wave_energy"] = wave_energy(heat, sim._state.thermal_displacement)
                row["energy"] += row["wave_energy"]
            if sim.comm is not None and not sim.stepper.local:  # (each process sums its share's logs)
                row.update(sim.stepper.heat_columns(sim._state))
            else:
                row.update(heat_columns(heat, sim._state))
            row.update(balances(row, sim.diagnostics.rows[0] if sim.diagnostics.rows else row))
        row.update(self.last_stats)
        if sim.loads is not None:  # loads: displacement, reaction, work, balance
            row.update(sim.loads.columns(sim, row))
        return row

    def _check_physical(self, row: dict) -> None:
        """Stop with a :class:`SimulationError` naming the node or spring once the state is no
        longer physical: a non-finite value (typically h above the stability limit) or a
        temperature θ ≤ 0 (possible in models such as "quadratic"). Checked at the diagnostics
        cadence and at the end of every run, so a run never silently returns such a state."""
        if math.isfinite(row["energy"]) and row.get("theta_min", 1.0) > 0:
            return
        raise SimulationError(self.sim.on_root(self._what_is_not_physical))

    def _what_is_not_physical(self) -> str:
        """The message of :meth:`_check_physical`: the first node or spring at fault."""
        sim = self.sim
        s, lay = sim.internal_state(), sim.layout
        where = f"at step {s.step} (t = {s.time:.6g})"
        unstable = f"; h = {sim.h} may be above the stability limit"
        bad = ~(np.isfinite(s.positions).all(axis=1) & np.isfinite(s.momenta).all(axis=1))
        if bad.any():
            a = int(lay.node_order[np.flatnonzero(bad)[0]])
            return f"node {a} has a non-finite position or momentum {where}{unstable}"
        if sim.system.thermal:
            theta = sim.temperatures()
            bad = ~(np.isfinite(theta) & (theta > 0))
            if bad.any():
                e = int(np.flatnonzero(bad)[0])
                return (f"spring {e} has temperature {theta[e]:.6g} {where}: the state left the range of model "
                        f"{sim.model.name!r}, where θ must stay > 0, or h = {sim.h} is too large")
        return f"the energy is not finite {where}{unstable}"


def _flushes(observers) -> list:
    """The ``flush`` methods of the objects whose bound methods are among the observers (each
    object once)."""
    owners = {}
    for _, cb in observers:
        owner = getattr(cb, "__self__", None)
        flush = getattr(owner, "flush", None)
        if callable(flush):
            owners[id(owner)] = flush
    return list(owners.values())
