"""The notebook-facing API: a net, a model, an initial state and an integrator, run in time.

    >>> import thermonet as tn
    >>> sim = tn.Simulation(tn.chain(), model="hencky", parameters=dict(c=100, beta=0.2, C0=5, theta0=300),
    ...                     temperatures=[800, 1200, 400], momenta=[[0, 0, 0], [20, 10, 10], [10, 20, 10], [0, 10, 0]],
    ...                     integrator="co2", h=0.01)
    >>> diag = sim.run(t_end=1.0)
    >>> sim.state.positions, sim.temperatures(), diag.energy

Everything a user passes in or reads back is in the net's own numbering; the engine's internal
numbering (chosen for memory locality) never shows.
"""

from __future__ import annotations

import math
import time as _time
from typing import Callable, Iterable, Mapping

import numpy as np

from .diagnostics import Diagnostics, diagnostics_row, measure, spring_fields
from .blowup import STRETCH_BOUNDS
from .compile_watch import CompileWatch
from .run_guards import DEFAULT_ENERGY_TOLERANCE, GUARD_MODES, StabilityGuard, energy_departure
from .errors import InputError, SimulationError
from .integrators import get_integrator
from .integrators.base import StepFailure
from .layout import build_layout
from .models import get_model
from .net import Net
from .system import State, System

#: nets with at least this many springs use the multi-threaded kernels
PARALLEL_MIN_SPRINGS = 16384


class Simulation:
    """A run of a thermo-elastic spring net.

    Parameters
    ----------
    net: the :class:`~thermonet.net.Net`.
    model: a model name ("hencky", "quadratic") or a :class:`~thermonet.models.Model`.
    parameters: model parameters, name -> scalar or (m,) array (user spring numbering);
        missing ones take the model's defaults.
    temperatures: initial temperature per spring θ(0), scalar or (m,); default: each spring's
        reference temperature. Entropies are η = Γ(l(0), θ(0)), Γ = −∂F/∂θ (Mata & Lew 2011,
        (11)).
    momenta / velocities: initial (n, 3) momenta or velocities (give at most one; default rest).
    integrator: a name (see ``thermonet.available_integrators()``) or an Integrator.
    h: time step.
    gravity: optional (3,) uniform acceleration (an external potential; energy includes it).
    thermal: thermal coupling on (default). Off: a purely mechanical run, every spring held at
        its reference temperature; no temperatures, entropies or Φ are allocated or computed.
    threads: number of threads for the parallel kernels (default: Numba's default, all cores).
    parallel: force the multi-threaded (True) or serial (False) kernels; default by net size.
    renumber: reorder nodes/springs internally for locality (results are reported in user order).
    integrator_options: passed to the integrator factory / stepper (e.g. ``alpha`` for GTR-α).
    stretch_bounds: (lo, hi), default (1e-4, 1e4): admissible stretches l/l0. The explicit kernel
        stops a run at the first step in which a spring leaves them, or whose tension is not
        finite, or (thermal) whose θ is not > 0; the state is rewound to the last good step and
        a :class:`StepFailure` (a SimulationError) names step, time, spring, nodes and quantity.
    energy_tolerance: relative bound on |H − H(0)|/|H(0)|, checked at the diagnostics cadence
        (default ``DEFAULT_ENERGY_TOLERANCE`` = 0.1; None: no energy guard); a run beyond it
        stops with a SimulationError, the state rewound to the previous stop.
    stability_guard: "stop" (default; True), "warn" or "off" (False): the explicit integrators'
        stable step re-estimated at the diagnostics cadence from the current stiffnesses
        (:class:`thermonet.run_guards.StabilityGuard`): a StepWarning above 0.9 h_max, and above
        1.5 h_max a stop (StabilityLimitExceeded, a SimulationError; "warn": warned only), the
        state rewound to the previous stop.
    backend: "cpu" (default) or "cuda": the explicit integrators on an NVIDIA GPU through
        numba-cuda, the state resident on the device (see :mod:`thermonet.cuda`).
    """

    def __init__(
        self,
        net: Net,
        model="hencky",
        parameters: Mapping | None = None,
        temperatures=None,
        momenta=None,
        velocities=None,
        integrator="co2",
        h: float = 1e-3,
        gravity=None,
        thermal: bool = True,
        threads: int | None = None,
        parallel: bool | None = None,
        renumber: bool = True,
        integrator_options: Mapping | None = None,
        backend: str = "cpu",
        stretch_bounds=STRETCH_BOUNDS,
        energy_tolerance: float | None = DEFAULT_ENERGY_TOLERANCE,
        stability_guard="stop",
    ):
        if not isinstance(net, Net):
            raise InputError(f"net must be a thermonet.Net, got {type(net).__name__}")
        self.net = net
        self.model = get_model(model)
        self.h = _check_step(h)
        integrator_options = dict(integrator_options or {})
        stepper_keys = {"tolerance", "max_iterations", "retry", "linear_solver", "rtol", "atol"}
        stepper_options = {k: integrator_options.pop(k) for k in list(integrator_options) if k in stepper_keys}
        self.integrator = get_integrator(integrator, **integrator_options)
        self.backend = _check_backend(backend, self.integrator)
        if self.backend != "cpu":
            stepper_options["backend"] = self.backend
        self.threads = threads
        m = net.n_springs
        layout = build_layout(net, renumber=renumber)
        self.layout = layout

        P_user = self.model.parameter_array(parameters or {}, m)
        gravity_vec = None
        if gravity is not None:
            gravity_vec = np.asarray(gravity, dtype=np.float64).reshape(-1)
            if gravity_vec.shape != (3,) or not np.isfinite(gravity_vec).all():
                raise InputError(f"gravity must be a finite 3-vector, got {gravity!r}")
        ref = net.anchor_point()
        self.angular_momentum_about = "anchor point" if (ref is not None and net.anchored.any()) else (
            "origin" if ref is not None else "origin (anchors do not coincide: angular momentum is not conserved)")
        masses = layout.nodes_to_internal(net.masses)
        anchored = layout.nodes_to_internal(net.anchored)
        self.system = System(
            model=self.model,
            layout=layout,
            rest_lengths=np.ascontiguousarray(layout.springs_to_internal(net.rest_lengths)),
            parameters=np.ascontiguousarray(P_user[:, layout.spring_order]),
            masses=np.ascontiguousarray(masses),
            inv_mass=np.where(anchored, 0.0, 1.0 / masses),
            anchored=np.ascontiguousarray(anchored),
            reference_point=np.zeros(3) if ref is None else ref,
            gravity=gravity_vec,
            thermal=bool(thermal),
            stretch_bounds=_check_stretch_bounds(stretch_bounds),
        )
        if energy_tolerance is not None and not (float(energy_tolerance) > 0):
            raise InputError(f"energy_tolerance must be > 0 (relative), got {energy_tolerance}")
        self.energy_tolerance = None if energy_tolerance is None else float(energy_tolerance)
        self.stability_guard = StabilityGuard(self, _guard_mode(stability_guard))

        x0 = layout.nodes_to_internal(net.positions).copy()
        p0 = self._initial_momenta(momenta, velocities)
        phi, eta = None, None
        if thermal:
            eta = np.ascontiguousarray(layout.springs_to_internal(self._initial_entropies(temperatures, P_user)))
            phi = np.zeros(m)
        elif temperatures is not None:
            raise InputError("initial temperatures given but thermal coupling is off (thermal=False)")
        self._state = State(
            positions=np.ascontiguousarray(x0),
            momenta=np.ascontiguousarray(layout.nodes_to_internal(p0)),
            thermal_displacement=phi,
            entropy=eta,
        )
        if parallel is None:
            parallel = threads != 1 and m >= PARALLEL_MIN_SPRINGS
        self.parallel = bool(parallel)
        self.stepper = self.integrator.make_stepper(self.system, parallel=self.parallel, **stepper_options)
        self.diagnostics = Diagnostics()
        #: seconds spent stepping (Numba compilation excluded) and steps run, over all runs
        self.wall_time = 0.0
        self.steps_run = 0
        #: seconds ``run`` spent compiling kernels (first runs of a model and integrator)
        self.compile_time = 0.0

    # ------------------------------------------------------------------------------------------
    # initial data

    def _initial_momenta(self, momenta, velocities) -> np.ndarray:
        net = self.net
        n = net.n_nodes
        if momenta is not None and velocities is not None:
            raise InputError("give either momenta or velocities, not both")
        if momenta is None and velocities is None:
            return np.zeros((n, 3))
        given = momenta if momenta is not None else velocities
        what = "momenta" if momenta is not None else "velocities"
        arr = np.asarray(given, dtype=np.float64)
        if arr.shape == (3,):
            arr = np.broadcast_to(arr, (n, 3)).copy()
            arr[net.anchored] = 0.0
        if arr.shape == (n, 2):
            arr = np.column_stack([arr, np.zeros(n)])
        if arr.shape != (n, 3):
            raise InputError(f"initial {what} must have shape ({n}, 3), got {arr.shape}")
        bad = ~np.isfinite(arr).all(axis=1)
        if bad.any():
            a = int(np.flatnonzero(bad)[0])
            raise InputError(f"node {a}: initial {what[:-1] if what == 'momenta' else 'velocity'} is not finite: {arr[a].tolist()}")
        moving = net.anchored & (np.abs(arr).sum(axis=1) > 0)
        if moving.any():
            a = int(np.flatnonzero(moving)[0])
            raise InputError(f"node {a} is anchored but has initial {what} {arr[a].tolist()}")
        if velocities is not None:
            arr = arr * net.masses[:, None]
        return arr

    def _initial_entropies(self, temperatures, P_user) -> np.ndarray:
        """η = Γ(l(0), θ(0)) per spring (user numbering)."""
        from .kernels.springs import map_springs

        theta0 = self._initial_temperatures(temperatures, P_user)
        lengths = self.net.lengths()
        eta = np.empty(self.net.n_springs)
        map_springs(self.model, "entropy")(lengths, theta0, self.net.rest_lengths, P_user, eta)
        bad = ~np.isfinite(eta)
        if bad.any():
            e = int(np.flatnonzero(bad)[0])
            raise InputError(f"spring {e}: initial entropy is not finite (θ = {theta0[e]}, l = {lengths[e]})")
        return eta

    def _initial_temperatures(self, temperatures, P_user) -> np.ndarray:
        m = self.net.n_springs
        if temperatures is None:
            return P_user[self.model.parameter_index(self.model.reference_temperature)].copy()
        theta = np.asarray(temperatures, dtype=np.float64)
        if theta.ndim == 0:
            theta = np.full(m, float(theta))
        if theta.shape != (m,):
            raise InputError(f"initial temperatures must be a scalar or one per spring ({m}), got shape {theta.shape}")
        bad = ~(np.isfinite(theta) & (theta > 0))
        if bad.any():
            e = int(np.flatnonzero(bad)[0])
            raise InputError(f"spring {e}: initial temperature must be finite and > 0, got {theta[e]}")
        return theta

    # ------------------------------------------------------------------------------------------
    # running

    @property
    def time(self) -> float:
        return self._state.time

    @property
    def step(self) -> int:
        return self._state.step

    def steps_until(self, t_end: float) -> int:
        """Steps from the current time to ``t_end``, which must be a whole number of steps
        (:func:`thermonet.step_policy.whole_steps`; an InputError otherwise)."""
        from .step_policy import whole_steps

        return whole_steps(t_end, self.h, self._state.time)

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
            default: about 1000 rows over the run.
        observers: (k, callback) pairs; ``callback(sim)`` is called every k steps (at multiples of
            k in the global step count) and at the end of the run. Where a callback is a bound
            method of an object with a ``flush()`` method (``RunOutput``: frames written on a
            thread), that is called before ``run`` returns or raises.
        progress: called as ``progress(done, total, elapsed_seconds)`` at each stop, elapsed
            without the time Numba spent compiling kernels; where it has a ``compiling()``
            method, that is called when the run starts compiling a kernel (first runs only).
        Returns the diagnostics series (``sim.diagnostics``, accumulated over runs).
        """
        if (t_end is None) == (steps is None):
            raise InputError("run: give exactly one of t_end or steps")
        if steps is None:
            if not math.isfinite(t_end):
                raise InputError(f"run: t_end must be finite, got {t_end}")
            steps = self.steps_until(t_end)
        steps = int(steps)
        if steps < 0:
            raise InputError(f"run: steps must be >= 0, got {steps}")
        if diagnostics_every is None:
            diagnostics_every = max(1, steps // 1000)
        if diagnostics_every < 1:
            raise InputError(f"run: diagnostics_every must be >= 1, got {diagnostics_every}")
        cadences = [(int(diagnostics_every), self._diagnostics_stop)] + [(int(k), cb) for k, cb in observers]
        for k, _ in cadences:
            if k < 1:
                raise InputError(f"run: observer cadence must be >= 1, got {k}")
        if not self.diagnostics.rows or self.diagnostics.rows[-1]["step"] != self._state.step:
            self._record(self)
        for k, cb in cadences[1:]:
            if self._state.step % k == 0:
                cb(self)
        if self.threads:
            import numba

            numba.set_num_threads(int(self.threads))
        start = self._state.step
        end = start + steps
        flushes = _flushes(cadences[1:])  # (observers may have been a generator: read once above)
        watch = CompileWatch(getattr(progress, "compiling", None))  # compile time kept out of rates
        t0 = _time.perf_counter()
        watch.__enter__()
        try:
            while self._state.step < end:
                cur = self._state.step
                stop = min([end] + [(cur // k + 1) * k for k, _ in cadences])
                self._advance(stop - cur, measure=stop % cadences[0][0] == 0 or stop == end)
                done = self._state.step
                for k, cb in cadences:
                    if done % k == 0 or done == end:
                        if cb == self._diagnostics_stop and self.diagnostics.rows and self.diagnostics.rows[-1]["step"] == done:
                            continue
                        cb(self)
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
            self.compile_time += watch.seconds
        for flush in flushes:
            flush()
        self.wall_time += _time.perf_counter() - t0 - watch.seconds
        self.steps_run += steps
        return self.diagnostics

    @property
    def h(self) -> float:
        """The time step. Setting it starts a new time origin at the current step."""
        return self._h

    @h.setter
    def h(self, value) -> None:
        self._h = _check_step(value)
        state = getattr(self, "_state", None)
        self._time_origin = (0, 0.0) if state is None else (state.step, state.time)

    def _set_step(self, step: int) -> None:
        """Move the step counter; time is origin + (steps since origin)·h, so it does not depend
        on how the run was cut into chunks."""
        state = self._state
        origin_step, origin_time = self._time_origin
        state.step = step
        state.time = origin_time + (step - origin_step) * self._h

    #: steps a backup of the state may lag behind a chunk's start (explicit CPU runs): copying
    #: the state at every observer stop costs a noticeable share of a short chunk, and a rewind
    #: replays at most this many steps more
    BACKUP_SPAN = 256

    def _advance(self, n: int, measure: bool = False) -> None:
        """n steps; with ``measure``, a stepper that can reduces the diagnostics sums of the end
        state on the way (see ``SplittingStepper.advance``)."""
        step0 = self._state.step
        backup = self._keep_backup()
        try:
            if measure and self.stepper.measures:
                stats = self.stepper.advance(self._state, n, self._h, measure=True)
            else:
                stats = self.stepper.advance(self._state, n, self._h)
        except StepFailure as exc:
            if exc.details.get("rewind") and backup is not None:
                self._rewind(backup, step0 + exc.steps_done - backup.step)
            self._set_step(step0 + exc.steps_done)
            self._record(self)
            if exc.details.get("rewind"):
                raise StepFailure(self._blowup_message(exc, step0), exc.steps_done, exc.details) from None
            raise
        self._set_step(step0 + n)
        self._last_stats = stats or {}

    def _keep_backup(self) -> State | None:
        """A copy of the state at this or an earlier chunk start, at most :data:`BACKUP_SPAN`
        steps back, of this run's history and step size (explicit CPU runs only: their kernel
        stops mid-step and the last good step is then replayed from the copy, bit for bit;
        implicit steppers keep their state intact themselves). A copy costs about a fifth of one
        step."""
        if self.backend != "cpu" or not self.integrator.explicit:
            return None
        s = self._state
        b = getattr(self, "_backup", None)
        if self._backup_usable() and s.step - b.step < self.BACKUP_SPAN:
            return b
        if b is None:
            b = self._backup = s.copy()
        else:
            np.copyto(b.positions, s.positions)
            np.copyto(b.momenta, s.momenta)
            if s.thermal_displacement is not None:
                np.copyto(b.thermal_displacement, s.thermal_displacement)
        b.step, b.time = s.step, s.time
        self._backup_of = (s, self._h)  # a loaded state or a new h makes the copy useless for replays
        return b

    def _backup_usable(self) -> bool:
        """Whether the backup is an earlier state of the current history, at the current h."""
        b = getattr(self, "_backup", None)
        if b is None:
            return False
        state, h = getattr(self, "_backup_of", (None, None))
        return state is self._state and h == self._h and b.step <= self._state.step

    def _rewind(self, backup: State, steps: int) -> None:
        """Restore ``backup`` (a chunk start) and replay ``steps`` steps: the run's last good
        state, bit for bit (runs do not depend on how they are chunked)."""
        s = self._state
        np.copyto(s.positions, backup.positions)
        np.copyto(s.momenta, backup.momenta)
        if s.thermal_displacement is not None:
            np.copyto(s.thermal_displacement, backup.thermal_displacement)
        self._set_step(backup.step)
        if steps > 0:
            self.stepper.advance(s, steps, self._h)
            self._set_step(backup.step + steps)

    def _blowup_message(self, exc: StepFailure, step0: int) -> str:
        bad_step = step0 + exc.steps_done + 1
        good_time = self._state.time
        return (f"the run left the admissible states in step {bad_step} (t = {good_time + self._h:.6g}): {exc}. "
                f"Stopped; the state is the last good one (step {bad_step - 1}, t = {good_time:.6g}). "
                f"Try a smaller h than {self._h:g} (`thermonet info` estimates the stable step) or an implicit "
                f"integrator (ho4, gtr-1/2).")

    def record_diagnostics(self) -> None:
        """Record a diagnostics row for the current state unless the last row is of this step
        (checkpoints call it so that a resumed run's rows equal an uninterrupted run's)."""
        if not self.diagnostics.rows or self.diagnostics.rows[-1]["step"] != self._state.step:
            self._record(self)

    def _diagnostics_stop(self, _sim=None) -> None:
        """The run loop's diagnostics observer: a row, then the run-time guards
        (:mod:`thermonet.run_guards`): the energy departure, then the stable step."""
        self._record(self)
        rows = self.diagnostics.rows
        departure = energy_departure(rows, self.energy_tolerance)
        if departure is not None:
            bad_step, bad_time = self._state.step, self._state.time
            e0 = rows[0]["energy"]
            where = self._rewind_to_previous_stop()
            raise SimulationError(
                f"the energy departed from its initial value {e0:.10g} by {departure:.3g} "
                f"(relative; tolerance {self.energy_tolerance:g}) at step {bad_step} (t = {bad_time:.6g}); "
                f"{where}. Try a smaller h than {self._h:g} or an implicit integrator (ho4, gtr-1/2); "
                f"energy_tolerance (scene: integrator.energy_tolerance) sets the guard")
        try:
            self.stability_guard.check(self)
        except SimulationError as exc:
            where = self._rewind_to_previous_stop()
            raise type(exc)(f"{exc}; {where}. Use a smaller h or an implicit integrator (ho4, gtr-1/2), or pass "
                            f"--allow-unstable-step (scene: integrator.check_step = false; API: "
                            f"stability_guard='warn') to only warn") from None

    def _rewind_to_previous_stop(self) -> str:
        """Drop the last diagnostics row and rewind the state to the row before (where the
        backup allows); returns where the state now is, in words."""
        rows = self.diagnostics.rows
        backup = getattr(self, "_backup", None)
        dropped = rows.pop()
        last = rows[-1]["step"] if rows else -1
        if rows and self._backup_usable() and backup.step <= last:
            self._rewind(backup, last - backup.step)
            return (f"the state was rewound to step {last} (t = {self._state.time:.6g}), "
                    "the last diagnostics stop before")
        rows.append(dropped)  # no earlier state to go back to: the row stays
        return f"the state is that of step {self._state.step}"

    def _record(self, _sim=None) -> None:
        row = self.stepper.diagnostics_row(self.system, self._state)  # a device-resident state
        if row is None:
            sums = self.stepper.closing_sums(self._state)  # reduced by the last advance
            if sums is not None:
                s = self._state
                entropy = float(np.sum(s.entropy)) if self.system.thermal else None
                row = diagnostics_row(self.system, s, entropy=entropy, **sums)
            else:
                row = measure(self.system, self._state, self.parallel)
        row.update(getattr(self, "_last_stats", {}) or {})
        self.diagnostics.append(row)
        self._check_physical(row)

    def _check_physical(self, row: dict) -> None:
        """Stop with a :class:`SimulationError` naming the node or spring once the state is no
        longer physical: a non-finite value (typically h above the stability limit) or a
        temperature θ ≤ 0 (possible in models such as "quadratic"). Checked at the diagnostics
        cadence and at the end of every run, so a run never silently returns such a state."""
        if math.isfinite(row["energy"]) and row.get("theta_min", 1.0) > 0:
            return
        s, lay = self.internal_state(), self.layout
        where = f"at step {s.step} (t = {s.time:.6g})"
        unstable = f"; h = {self.h} may be above the stability limit"
        bad = ~(np.isfinite(s.positions).all(axis=1) & np.isfinite(s.momenta).all(axis=1))
        if bad.any():
            a = int(lay.node_order[np.flatnonzero(bad)[0]])
            raise SimulationError(f"node {a} has a non-finite position or momentum {where}{unstable}")
        if self.system.thermal:
            theta = self.temperatures()
            bad = ~(np.isfinite(theta) & (theta > 0))
            if bad.any():
                e = int(np.flatnonzero(bad)[0])
                raise SimulationError(
                    f"spring {e} has temperature {theta[e]:.6g} {where}: the state left the range of model "
                    f"{self.model.name!r}, where θ must stay > 0, or h = {self.h} is too large"
                )
        raise SimulationError(f"the energy is not finite {where}{unstable}")

    # ------------------------------------------------------------------------------------------
    # reading back (user numbering)

    @property
    def state(self) -> State:
        """A copy of the current state in the user's numbering."""
        s, lay = self.internal_state(), self.layout
        return State(
            positions=lay.nodes_to_user(s.positions),
            momenta=lay.nodes_to_user(s.momenta),
            thermal_displacement=None if s.thermal_displacement is None else lay.springs_to_user(s.thermal_displacement),
            entropy=None if s.entropy is None else lay.springs_to_user(s.entropy),
            time=s.time,
            step=s.step,
        )

    def load_state(self, state: State) -> None:
        """Replace the current state by ``state`` (user numbering), e.g. from a checkpoint."""
        lay = self.layout

        def nodes(a):
            return np.ascontiguousarray(lay.nodes_to_internal(np.asarray(a, dtype=np.float64)))

        def springs(a):
            if not self.system.thermal:
                return None
            return np.ascontiguousarray(lay.springs_to_internal(np.asarray(a, dtype=np.float64)))

        self._state = State(
            positions=nodes(state.positions),
            momenta=nodes(state.momenta),
            thermal_displacement=springs(state.thermal_displacement),
            entropy=springs(state.entropy),
            time=float(state.time),
            step=int(state.step),
        )
        step, time = self._state.step, self._state.time
        # a state of a run that started at t = 0 with this h keeps time = step·h exactly (resume is
        # then bit-identical); any other state starts a new time origin
        on_grid = abs(time - step * self._h) <= 1e-12 * max(1.0, abs(time))
        self._time_origin = (0, 0.0) if on_grid else (step, time)

    def internal_state(self) -> State:
        """The current state itself, in the engine's internal numbering (``self.layout`` maps it
        to the user's), with its arrays up to date on the host: a device-resident stepper
        (backend "cuda") copies its state back first. Not a copy: read it, do not keep or
        modify it. For output writers; users want :attr:`state`."""
        self.stepper.sync(self._state)
        return self._state

    def internal_spring_fields(self):
        """Length, temperature, tension and internal energy of every spring now, each (m,), in
        the internal numbering (one threaded pass; for output writers)."""
        s = self.internal_state()
        return spring_fields(self.system, s.positions, s.entropy, self.parallel)

    def spring_fields(self):
        """Length, temperature, tension and internal energy of every spring now, each (m,),
        user numbering (one pass over the springs)."""
        f, lay = self.internal_spring_fields(), self.layout
        return type(f)(*(lay.springs_to_user(a) for a in (f.length, f.temperature, f.tension, f.internal_energy)))

    def temperatures(self) -> np.ndarray:
        """(m,) spring temperatures θ(l, η) now (Mata & Lew 2011, (12) and (18b))."""
        return self.layout.springs_to_user(self.internal_spring_fields().temperature)

    def lengths(self) -> np.ndarray:
        return self.layout.springs_to_user(self.internal_spring_fields().length)

    def strains(self) -> np.ndarray:
        """(m,) logarithmic strains ln(l / l0) (the log of output frames: equal to theirs bit for
        bit, within about an ulp of NumPy's)."""
        from .kernels.springs import log_strain

        return log_strain(self.lengths(), self.net.rest_lengths)

    def tensions(self) -> np.ndarray:
        return self.layout.springs_to_user(self.internal_spring_fields().tension)

    def velocities(self) -> np.ndarray:
        return self.state.momenta / self.net.masses[:, None]

    def to_meshio(self):
        """The current state as a ``meshio.Mesh`` in the user's numbering: springs as "line"
        cells at the current positions, node displacement, velocity, momentum, spring strain,
        tension (and temperature, entropy with thermal coupling); see :mod:`thermonet.io.convert`."""
        from .io.convert import simulation_mesh

        return simulation_mesh(self)

    def to_pyvista(self):
        """The current state as a ``pyvista.UnstructuredGrid`` (the fields of :meth:`to_meshio`;
        needs PyVista)."""
        from .io.convert import simulation_mesh, to_pyvista

        return to_pyvista(simulation_mesh(self))

    def conservation_summary(self) -> dict:
        """Initial value and maximal deviation of each conserved quantity, plus speed."""
        out = self.diagnostics.summary()
        out["_run"] = {
            "steps": self.steps_run,
            "wall_time_s": self.wall_time,
            "steps_per_s": self.steps_run / self.wall_time if self.wall_time > 0 else float("nan"),
            "spring_steps_per_s": self.steps_run * self.net.n_springs / self.wall_time if self.wall_time > 0 else float("nan"),
            "compile_s": self.compile_time,
        }
        solver_summary = self.stepper.summary()  # implicit integrators: Newton totals
        if solver_summary is not None:
            out["_run"]["newton"] = solver_summary
        return out

    def __repr__(self) -> str:
        return (f"<Simulation {self.net.n_nodes} nodes, {self.net.n_springs} springs, model {self.model.name}, "
                f"{self.integrator.name} h={self.h}, t={self.time:.6g}, step {self.step}>")


def _check_backend(backend, integrator) -> str:
    name = str(backend).lower()
    if name not in ("cpu", "cuda"):
        raise InputError(f"unknown backend {backend!r}; known: cpu, cuda")
    if name == "cuda":
        if not integrator.explicit:
            raise InputError(f"integrator {integrator.name!r} is implicit; backend 'cuda' runs only the explicit "
                             "integrators (gtr-0, gtr-1, co2, f10, nm2, co4, co6)")
        from .cuda import require_cuda

        require_cuda()
    return name


def _guard_mode(mode) -> str:
    if mode is True:
        return "stop"
    if mode is False or mode is None:
        return "off"
    if str(mode).lower() not in GUARD_MODES:
        raise InputError(f"stability_guard must be one of {', '.join(GUARD_MODES)} (or True/False), got {mode!r}")
    return str(mode).lower()


def _check_stretch_bounds(bounds) -> tuple[float, float]:
    try:
        lo, hi = (float(b) for b in bounds)
    except (TypeError, ValueError):
        raise InputError(f"stretch_bounds must be two numbers (lo, hi), got {bounds!r}") from None
    if not (0 <= lo < 1 < hi):
        raise InputError(f"stretch_bounds must satisfy 0 <= lo < 1 < hi, got ({lo}, {hi})")
    return lo, hi


def _check_step(h) -> float:
    try:
        h = float(h)
    except (TypeError, ValueError):
        raise InputError(f"time step h must be a number, got {h!r}") from None
    if not (math.isfinite(h) and h > 0):
        raise InputError(f"time step h must be finite and > 0, got {h}")
    return h


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


__all__ = ["Simulation", "SimulationError"]

