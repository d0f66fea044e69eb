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

from contextlib import nullcontext
from typing import Mapping

import numpy as np

from .assemble import assemble
from .blowup import STRETCH_BOUNDS
from .diagnostics import Diagnostics, spring_fields
from .driver import Runner
from .errors import InputError, SimulationError
from .heat.logs import PER_SPRING_LOGS, heat_logs
from .heat.multirate import check_conduction_every, check_conduction_sweeps
from .heat.parameters import split_parameters
from .heat.setup import build_heat
from .inputs import (angular_momentum_reference, build_system, check_backend, check_energy_tolerance, check_step,
                     guard_mode, initial_state)
from .integrators import get_integrator
from .kernels.springs import log_strain
from .layout import build_layout
from .loads.setup import SimulationLoads, check_load_support, hold_driven_axes, resolve
from .materials.continuum import apply_continuum
from .models import get_model
from .net import Net
from .output_fields import OutputFields
from .probes import Probes
from .run_guards import DEFAULT_ENERGY_TOLERANCE, StabilityGuard
from .state import State

#: nets with at least this many springs use the multi-threaded kernels
PARALLEL_MIN_SPRINGS = 16384


class Simulation:
    """A run of a thermo-elastic spring net: the public façade. Input checking and building live
    in :mod:`thermonet.inputs`, the stepper in :func:`thermonet.assemble.assemble`, running in
    time in the :class:`~thermonet.driver.Runner` the Simulation holds (``self.runner``).

    Parameters
    ----------
    net: the :class:`~thermonet.net.Net`.
    model: a model name ("hencky", "quadratic") or a :class:`~thermonet.models.Model`.
    parameters: model parameters, name -> scalar or (m,) array (user spring numbering);
        missing ones take the model's defaults. Or, for a net read from a mesh, continuum
        properties (``youngs_modulus``, ``density``, ``heat_capacity``, ``thermal_expansion``,
        ``conductivity``, ...; docs/continuum.md) that set every spring's stiffness, beta, C0, g,
        g_star and the node masses (``self.continuum`` records what the rule made).
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
        numba-cuda, the state resident on the device (see :mod:`thermonet.explicit.cuda`).
    conduction: Fourier heat conduction between springs (docs/heat.md) through each spring's
        conductance ``g``, given in ``parameters`` like a model parameter (scalar or (m,), ≥ 0);
        default: on when ``g`` is given. Each conduction cycle of k steps becomes
        ``K(kh/2) ∘ A(h)^k ∘ K(kh/2)``, K a sweep of node-star exchanges (:mod:`thermonet.heat`);
        the diagnostics gain the entropy produced, the heat of each bath and source and the
        energy and entropy balances.
    conduction_every: k, the steps of one conduction cycle: "auto" (default: the largest k of
        1, 2, 5, 10, 20, … with λ k h ≤ 0.3, λ the conduction's fastest rate, that divides the
        output cadences; :mod:`thermonet.heat.multirate`) or a whole number that divides every
        run's output cadences and length. "auto" may also sweep each cycle boundary j > 1 times
        (sub-sweeps: the error of a cycle of k / j steps at the cost of one boundary).
        ``self.conduction_cycle`` says which k and j ran and why.
    conduction_sweeps: j, with an integer ``conduction_every``: each cycle boundary's conduction
        as 2j half sweeps over k h / (2 j) (default 1); "auto" chooses j itself.
    thermal_waves: Green–Naghdi type II thermal waves (docs/heat.md) through ``g_star`` (in
        ``parameters``); explicit splittings only; default: on when ``g_star`` is given.
    baths: name -> :class:`thermonet.heat.Bath` (a node group held at θ_b(t)), needs conduction.
    sources: name -> :class:`thermonet.heat.Source` (a spring group receiving power P(t) per
        spring), needs conduction.
    loads: driven node groups and forces (:class:`thermonet.loads.Drive`, :class:`thermonet.loads.Force`),
        a sequence or a mapping name -> load; diagnostics rows then carry each load's
        displacement, reaction and work and the energy balance H − H(0) − W
        (− ΣQ with heat flow; docs/loads.md).
    anchors: node group names of the net (a mesh's physical groups) or node indices to hold
        fixed, on top of the net's own anchored nodes (``read_mesh(anchors=...)`` does the same
        when reading a mesh).
    comm: an mpi4py communicator to distribute the net over (docs/parallel.md); default: the
        processes of ``mpiexec`` when started by it, else none. Results are those of one process.
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
        conduction: bool | None = None,
        conduction_every="auto",
        conduction_sweeps: int | None = None,
        thermal_waves: bool | None = None,
        baths: Mapping | None = None,
        sources: Mapping | None = None,
        loads=None,
        anchors=None,
        comm=None,
    ):
        from .parallel import world

        mpi = world(comm)
        if mpi is not None and mpi.Get_rank() > 0:  # (its part comes from rank 0: thermonet.parallel.ship)
            from .parallel.ship import receive_simulation

            receive_simulation(self, mpi, model, threads)
            return
        if mpi is None:
            building = nullcontext()
        else:  # (over MPI processes rank 0 builds the whole net: an error here is raised on every process)
            from .parallel.ship import errors_told_to_others

            building = errors_told_to_others(mpi)
        with building:
            if not isinstance(net, Net):
                raise InputError(f"net must be a thermonet.Net, got {type(net).__name__}")
            if anchors is not None:
                net = _with_anchors(net, anchors)
            self.model = get_model(model)
            net, parameters, self.continuum = apply_continuum(net, self.model, parameters)
            model_parameters, transport = split_parameters(parameters)  # the model's, and heat flow's
            self.net = net
            self._state: State | None = None
            self.h = check_step(h)
            integrator_options = dict(integrator_options or {})
            stepper_keys = {"tolerance", "max_iterations", "retry", "linear_solver", "rtol", "atol",
                            "newton_path"}
            stepper_options = {k: integrator_options.pop(k) for k in list(integrator_options) if k in stepper_keys}
            try:
                self.integrator = get_integrator(integrator, **integrator_options)
            except (InputError, TypeError):
                unknown = integrator_option_problem(integrator_options)
                if unknown is None:
                    raise
                raise InputError(f"integrator {integrator!r}: {unknown}") from None
            self.backend = check_backend(backend, self.integrator)
            self.threads = threads
            self.layout = layout = build_layout(net, renumber=renumber)
            P_user = self.model.parameter_array(model_parameters, net.n_springs)
            self.angular_momentum_about = angular_momentum_reference(net)
            heat = build_heat(net, layout, self.model, P_user, transport, thermal=thermal, conduction=conduction,
                              waves=thermal_waves, baths=baths, sources=sources)
            load_set = resolve(loads, net)
            check_load_support(load_set, self.integrator, self.backend)
            self.system = build_system(net, self.model, layout, P_user, gravity, thermal, stretch_bounds, heat,
                                       load_set)
            if parallel is None:
                parallel = threads != 1 and net.n_springs >= PARALLEL_MIN_SPRINGS
            self.parallel = bool(parallel)
            self.integrator, self.stepper = assemble(self.integrator, self.system, parallel=self.parallel,
                                                     backend=self.backend, options=stepper_options,
                                                     time_origin=self.time_origin)
            #: the MPI communicator the net is distributed over (None: one process)
            self.comm = mpi
            if self.comm is not None:
                from .parallel.stepper import distribute

                self.stepper = distribute(self, self.comm)
            self.energy_tolerance = check_energy_tolerance(energy_tolerance)
            self.stability_guard = StabilityGuard(self, guard_mode(stability_guard))  # (the integrator with heat)
            self._state = initial_state(net, self.model, layout, P_user, thermal, temperatures, momenta, velocities)
            if heat is not None:
                heat_logs(self._state, heat)
            self.conduction_every = check_conduction_every(conduction_every)
            self.conduction_sweeps = check_conduction_sweeps(conduction_sweeps, self.conduction_every)
            if heat is not None and heat.conduction and self.conduction_every != "auto":  # cycles counted from step 0
                heat_logs(self._state, heat)["cycle"][:] = (self.conduction_every, 0, self.conduction_sweeps or 1)
            #: the conduction cycle the last run used (None: no conduction, or no run yet): a
            #: :class:`~thermonet.heat.multirate.ConductionCycle` (k, why, sweeps)
            self.conduction_cycle = None
            hold_driven_axes(self._state, layout, load_set)
            #: the loads' columns of the diagnostics rows (None without loads)
            self.loads = None if load_set is None else SimulationLoads(layout, load_set)
            #: per-group series attached by :meth:`add_probes` (None: none)
            self.probes = None
            self.diagnostics = Diagnostics()
            #: seconds spent stepping (Numba compilation excluded) and steps run, over all runs
            self.wall_time = 0.0
            self.steps_run = 0
            #: seconds ``run`` spent compiling kernels (first runs of a model and integrator)
            self.compile_time = 0.0
            self.runner = Runner(self)
        if mpi is not None:  # every other process's part of it sent, rank 0's share kept
            from .parallel.ship import send_parts

            send_parts(self, mpi)

    # ------------------------------------------------------------------------------------------
    # time

    @property
    def time(self) -> float:
        return self._state.time

    @property
    def step(self) -> int:
        return self._state.step

    @property
    def h(self) -> float:
        """The time step. Setting it starts a new time origin at the current step."""
        return self._h

    @h.setter
    def h(self, value) -> None:
        self._h = check_step(value)
        state = self._state
        self._time_origin = (0, 0.0) if state is None else (state.step, state.time)

    def time_origin(self) -> tuple[int, float]:
        """(step, time) where the run's clock starts: time = origin time + (step − origin step)·h,
        so a time does not depend on how runs were cut into chunks."""
        return self._time_origin

    # ------------------------------------------------------------------------------------------
    # running (:class:`~thermonet.driver.Runner`)

    def run(self, t_end: float | None = None, steps: int | None = None, diagnostics_every: int | None = None,
            observers=(), progress=None) -> Diagnostics:
        """Advance by ``steps`` steps, or to ``t_end``; the probes of :meth:`add_probes` record
        at their cadences (default ``diagnostics_every``). See :meth:`Runner.run
        <thermonet.driver.Runner.run>` for the arguments; returns ``self.diagnostics``."""
        return self.runner.run(t_end, steps, diagnostics_every, observers, progress)

    def steps_until(self, t_end: float) -> int:
        """Steps from the current time to ``t_end`` (a whole number of steps; an InputError
        otherwise)."""
        return self.runner.steps_until(t_end)

    def record_diagnostics(self) -> None:
        """Record a diagnostics row for the current state unless the last row is of this step."""
        self.runner.record_diagnostics()

    def add_probes(self, probes: Mapping) -> "Probes":
        """Attach probes: name -> :class:`~thermonet.probes.Probe` (a group's mean, min and max of
        one quantity at a cadence; docs/scenes.md). Every later :meth:`run` records them;
        ``self.probes.series`` holds the rows, ``self.probes.to_csv(folder)`` writes them.
        Returns the :class:`~thermonet.probes.Probes`."""
        self.probes = Probes(self, probes)
        return self.probes

    # ------------------------------------------------------------------------------------------
    # reading back (user numbering)

    @property
    def state(self) -> State:
        """A copy of the current state in the user's numbering (over MPI processes: put together
        by rank 0 and given to every process; read it on every process)."""
        return self.on_root(self._user_state, arrays=True)

    def _user_state(self) -> State:
        s, lay = self.internal_state(), self.layout
        return State(
            positions=lay.nodes_to_user(s.positions),
            momenta=lay.nodes_to_user(s.momenta),
            thermal_displacement=None if s.thermal_displacement is None else lay.springs_to_user(s.thermal_displacement),
            entropy=None if s.entropy is None else lay.springs_to_user(s.entropy),
            time=s.time,
            step=s.step,
            extra={**{k: v.copy() for k, v in s.extra.items() if isinstance(v, np.ndarray)}, **self._heat_logs_to_user(s)},
        )

    def _heat_logs_to_user(self, s: State) -> dict:
        """The heat-flow logs of internal state ``s`` as a State's ``extra`` (per-spring ones in the
        user's numbering; the bath and source entries as they are)."""
        logs = s.extra.get("heat")
        if logs is None:
            return {}
        out = {k: v.copy() for k, v in logs.items()}
        for k in PER_SPRING_LOGS:
            out[k] = self.layout.springs_to_user(logs[k])
        return {"heat": out}

    def load_state(self, state: State) -> None:
        """Replace the current state by ``state`` (user numbering), e.g. from a checkpoint (over
        MPI processes every process loads it: rank 0 puts it into the internal numbering and gives
        it to the others)."""
        self._state = self.on_root(lambda: self._internal_of(state), arrays=True)
        step, time = self._state.step, self._state.time
        # a state of a run that started at t = 0 with this h keeps time = step·h exactly (resume is
        # then bit-identical); any other state starts a new time origin
        on_grid = abs(time - step * self._h) <= 1e-12 * max(1.0, abs(time))
        self._time_origin = (0, 0.0) if on_grid else (step, time)

    def _internal_of(self, state: State) -> State:
        """``state`` (user numbering) as a new State in the internal numbering, with this run's
        heat logs (those ``state`` gives, the others at their defaults)."""
        lay = self.layout

        def nodes(a):
            return np.ascontiguousarray(lay.nodes_to_internal(np.asarray(a, dtype=np.float64)))

        def springs(a):
            if not self.system.thermal:
                return None
            return np.ascontiguousarray(lay.springs_to_internal(np.asarray(a, dtype=np.float64)))

        out = State(
            positions=nodes(state.positions),
            momenta=nodes(state.momenta),
            thermal_displacement=springs(state.thermal_displacement),
            entropy=springs(state.entropy),
            time=float(state.time),
            step=int(state.step),
            extra={k: (np.array(v, dtype=np.float64) if isinstance(v, np.ndarray) else v)
                   for k, v in state.extra.items()},
        )
        heat = self.system.heat
        if heat is not None:
            logs = heat.new_logs()
            given = (state.extra or {}).get("heat")
            if given is not None:
                for k, v in logs.items():
                    if k not in given:  # (a log this version added: its default)
                        continue
                    a = np.asarray(given[k], dtype=np.float64)
                    if k == "cycle" and a.shape == (2,):  # (saved before sub-sweeps: one sweep)
                        a = np.append(a, 1.0)
                    if a.shape != v.shape:
                        raise InputError(f"the state's heat log {k!r} has shape {a.shape}, this run's has {v.shape}")
                    v[:] = springs(a) if k in PER_SPRING_LOGS else a
            out.extra["heat"] = logs
        return out

    def internal_state(self) -> State:
        """The current state itself, in the engine's internal numbering (``self.layout`` maps it
        to the user's), with its arrays up to date on the host: a device-resident stepper
        (backend "cuda") copies its state back first. Not a copy: read it, do not keep or
        modify it. For output writers; users want :attr:`state`."""
        self.stepper.sync(self._state)
        return self._state

    def on_root(self, fn, whole: bool = True, arrays: bool = False):
        """``fn()`` with the whole state at hand: in one process, simply called; over MPI processes
        (a step every process takes), run by rank 0 with the state put together there (x, p, η,
        and Φ where ``whole``), its result or its error given to every process. For what needs
        the whole net (diagnostics rows with loads, frames, guards): the other processes hold
        their shares only (docs/parallel.md). ``arrays``: a result holding large arrays (sent
        as buffers rather than pickled)."""
        if self.comm is None or self.stepper.local:  # (rank 0 already inside one)
            return fn()
        return self.stepper.on_root(self._state, fn, whole, arrays)

    def internal_spring_fields(self):
        """Length, temperature, tension and internal energy of every spring now, each (m,), in
        the internal numbering (one threaded pass; for output writers; over MPI processes
        computed by rank 0 and given to every process)."""
        def fields():
            s = self.internal_state()
            return spring_fields(self.system, s.positions, s.entropy, self.parallel)

        return self.on_root(fields, arrays=True)

    def spring_fields(self):
        """Length, temperature, tension and internal energy of every spring now, each (m,),
        user numbering (one pass over the springs)."""
        def user():
            f, lay = self.internal_spring_fields(), self.layout
            return type(f)(*(lay.springs_to_user(a) for a in (f.length, f.temperature, f.tension, f.internal_energy)))

        return self.on_root(user, arrays=True)  # (over MPI processes rank 0 alone holds the numbering)

    def temperatures(self) -> np.ndarray:
        """(m,) spring temperatures θ(l, η) now (Mata & Lew 2011, (12) and (18b))."""
        return self.on_root(lambda: self.layout.springs_to_user(self.internal_spring_fields().temperature), arrays=True)

    def lengths(self) -> np.ndarray:
        return self.on_root(lambda: self.layout.springs_to_user(self.internal_spring_fields().length), arrays=True)

    def strains(self) -> np.ndarray:
        """(m,) logarithmic strains ln(l / l0) (the log of output frames: equal to theirs bit for
        bit, within about an ulp of NumPy's)."""
        return self.on_root(lambda: log_strain(self.lengths(), self.net.rest_lengths), arrays=True)  # (l0: rank 0's)

    def tensions(self) -> np.ndarray:
        return self.on_root(lambda: self.layout.springs_to_user(self.internal_spring_fields().tension), arrays=True)

    def velocities(self) -> np.ndarray:
        return self.on_root(lambda: self.state.momenta / self.net.masses[:, None], arrays=True)  # (masses: rank 0's)

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

    def output_fields(self, points: np.ndarray, point: dict, cell: dict):
        """An :class:`~thermonet.output_fields.OutputFields` writing this simulation's fields, in
        the user's numbering, into the given arrays at each ``write()`` (output writers' frames):
        points (n, 3) the positions; point: name -> target of ``displacement``, ``velocity``,
        ``momentum`` ((n, 3)) or ``node_temperature`` ((n,)); cell: name -> (m,) target of
        ``temperature``, ``tension``, ``strain``, ``entropy``, ``thermal_displacement``."""
        return OutputFields(self, points, point, cell)

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


__all__ = ["Simulation", "SimulationError"]


def _with_anchors(net: Net, anchors) -> Net:
    """A copy of ``net`` with the nodes of ``anchors`` (node group names of the net, or node
    indices) anchored too (the ``anchors=`` of :class:`Simulation`)."""
    import dataclasses

    if isinstance(anchors, (str, int, np.integer)):
        anchors = [anchors]
    anchored = np.array(net.anchored, dtype=bool)
    for item in anchors:
        if not isinstance(item, (str, int, np.integer)) or isinstance(item, bool):
            raise InputError(f"anchors: node group names or node indices, got {item!r}")
        anchored[net.nodes(item if isinstance(item, str) else [item], "anchors")] = True
    return dataclasses.replace(net, anchored=anchored)


#: options an integrator may take (integrator_options=, scene integrator.options): the implicit
#: steppers' solver settings, and GTR-α's α
INTEGRATOR_OPTION_NAMES = ("tolerance", "max_iterations", "retry", "linear_solver", "rtol", "atol", "newton_path",
                           "alpha")


def integrator_option_problem(options) -> str | None:
    """``unknown option 'tolerence' (did you mean 'tolerance'?); options: ...`` for the first
    option no integrator takes, or None."""
    import difflib

    for key in options:
        if key not in INTEGRATOR_OPTION_NAMES:
            close = difflib.get_close_matches(str(key), INTEGRATOR_OPTION_NAMES, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            return (f"unknown option {key!r}{hint}; options: {', '.join(INTEGRATOR_OPTION_NAMES[:-1])} (implicit "
                    f"integrators), alpha (gtr-alpha)")
    return None
