"""What every implicit stepper does around its step equations: predictor, Newton solve, update,
checks, loud and safe failure, opt-in retry with substeps, and the statistics it reports.

A subclass (GTR-α, HO4) supplies the scheme: the block size, the name its kernels are
registered under (``implicit.core.schemes.register_scheme``), the predictor, its work record,
and the calls of its kernels. A new implicit scheme is two files, its kernels
(``kernels/<scheme>.py``) and its integrator and stepper (``integrators/<scheme>.py``), each
registered by name. A step is computed from the current state into separate buffers and
copied into the state only once it has converged and passed the checks, so a failed step leaves
the state exactly at the last good step.
"""

from __future__ import annotations

import math
import warnings
from abc import abstractmethod

import numpy as np

from ...errors import InputError
from .schemes import KEEP_ROWS, STATUS_TEXT, implicit_kernels
from ...kernels.records import Springs, StateArrays, nodes as node_record
from .records import BlockPlaces, BlockTopology, Residuals, StartWork, StepStart, plain
from ...solvers import BlockPattern, make_linear_solver
from .newton import NewtonOptions, NewtonResult, NewtonTimers, newton
from ...integrators.base import Stepper, StepFailure
from .compiled_path import CompiledNewton, use_compiled
from .large_steps import choose_path, continued


class _StepError(Exception):
    """A step that did not produce a valid next state (internal; becomes a StepFailure)."""

    def __init__(self, reason: str, result: NewtonResult | None, status: int = 0, spring: int = -1):
        super().__init__(reason)
        self.reason = reason
        self.result = result
        self.status = status
        self.spring = spring


class _KernelRecord:
    """A stepper attribute holding a record of :mod:`thermonet.implicit.core.records`; each
    assignment also keeps, as ``_<name>``, the plain tuple the kernels are called with (made once,
    not at every call: a kernel call then costs what it cost with separate arguments)."""

    def __set_name__(self, owner, name):
        self.record, self.args = f"_{name}_record", f"_{name}"

    def __get__(self, obj, owner=None):
        return self if obj is None else getattr(obj, self.record)

    def __set__(self, obj, value):
        setattr(obj, self.record, value)
        setattr(obj, self.args, None if value is None else plain(value))


class ImplicitStepper(Stepper):
    """Shared driver of an implicit integrator bound to one system (internal numbering).

    What the kernels read, as records (:mod:`thermonet.implicit.core.records`): ``topology``,
    ``springs`` (parameters), ``nodes`` (masses, gravity), ``places`` (the Jacobian's block
    places), ``step_start`` (the step's start state and h, set by :meth:`begin`), ``work`` (the
    scheme's per-spring record, made by :meth:`make_work`; ``work.start`` the start kernel's),
    ``residuals`` (R, Rabs (size,), peak (2, n_free)). Besides: ``u`` (size,) the unknowns,
    ``norms`` (max |R|, max Rabs) of the last residual, ``data`` (nnz,) the Jacobian values,
    ``warm`` whether the per-spring temperatures of the last residual may seed the next one
    (same step), ``pattern``, ``kernels``, ``solver``.
    """

    block: int
    scheme: str
    #: time derivatives of the acceleration the predictor uses (0, 1: ȧ, 2: ȧ and ä)
    rate: int = 0
    #: a local Jacobi step (:meth:`local_jacobi`) updates at most this fraction of the free
    #: nodes; with more, a global one (one sweep, one full residual) costs less
    LOCAL_MAX_FRACTION = 0.05
    #: "auto" (newton_path and linear_solver both) chooses the path by h·ω_max at each new h
    #: (compiled_path.choose_by_step): schemes meant for steps far above the explicit limit
    chooses_by_step = False
    #: a step whose Newton solve fails from the predictor is solved by continuation in the step
    #: (:meth:`continued`) before the retry policy splits it into substeps
    continuation = False
    #: the continuation's smallest stage (a fraction of h) and most stages per step
    CONTINUATION_MIN_FRACTION = 1.0 / 64.0
    CONTINUATION_MAX_SOLVES = 24
    #: a step that continuation found hard sends the next one of the same h straight to it
    CONTINUATION_REMEMBERS = True
    #: the intermediate stages' scaled-residual tolerance (only their extrapolation is used)
    CONTINUATION_TOLERANCE = 1e-8
    topology = _KernelRecord()
    springs = _KernelRecord()
    nodes = _KernelRecord()
    places = _KernelRecord()
    work = _KernelRecord()
    residuals = _KernelRecord()
    step_start = _KernelRecord()

    def __init__(self, integrator, system, options: NewtonOptions, parallel: bool = False):
        if not system.thermal:
            raise InputError(f"integrator {integrator.name} needs thermal coupling (thermal=True)")
        self.integrator = integrator
        self.system = system
        self.options = options
        # the parameters as the kernels read them: (k, m), or one (k, 1) column shared by all
        P, uniform = system.kernel_parameters
        self.kernels = implicit_kernels(system.model, self.scheme, parallel, uniform, self.rate)
        self.kernels_parallel = bool(parallel)
        self.pattern = pattern = BlockPattern.build(system.edges, system.anchored, self.block)
        self.free_index = free_index = pattern.free_index
        # the kernels read the int32 index arrays as unsigned (no negative-index wrap-around),
        # and the incidence with each spring's sign at that node (+1 at its first end; int8: the
        # node passes are memory-bound, and ±1 times a float is exact in any type)
        lay = system.layout
        first_end = system.edges[lay.inc_spring, 0] == np.repeat(np.arange(system.n_nodes), np.diff(lay.inc_ptr))
        self.topology = BlockTopology(edges=system.edges.view(np.uint32), free_index=free_index,
                                      ends=np.ascontiguousarray(free_index[system.edges], dtype=np.int32),
                                      inc_ptr=lay.inc_ptr, inc_spring=lay.inc_spring.view(np.uint32),
                                      inc_sign=np.where(first_end, 1, -1).astype(np.int8))
        self.springs = Springs(system.rest_lengths, P)
        self.nodes = node_record(system)
        self.places = BlockPlaces(pattern.node_base, pattern.node_stride, pattern.spring_base, pattern.spring_stride,
                                  np.zeros((6, 6)))
        self.solver = make_linear_solver(options.linear_solver, pattern, self)
        n, m, size = system.n_nodes, system.n_springs, pattern.size
        free = np.flatnonzero(free_index >= 0)
        self.node_of_block = np.empty(pattern.n_free, dtype=np.int64)
        self.node_of_block[free_index[free]] = free
        self.block_mass = system.masses[self.node_of_block]  # (n_free,)
        local = hasattr(self.kernels, "local_jacobi")
        self.residuals = Residuals(np.zeros(size), np.zeros(size), np.zeros((2, pattern.n_free if local else 0)))
        self.norms = (math.inf, math.inf)
        self.u = np.zeros(size)
        #: the start kernel writes the explicit predictor straight into the unknowns (no copy)
        self.prediction = self.u
        self.data = np.zeros(pattern.nnz if self.solver.assembled else 0)
        self.work = self.make_work(StartWork.allocate(n, m, self.block, KEEP_ROWS, self.kernels.keep_start, self.rate))
        self.warm = False
        self.step_start = None
        self._new = StateArrays(np.empty((n, 3)), np.empty((n, 3)), np.empty(m), np.empty(m))
        self._no_index = np.empty(0, dtype=np.int64)
        self._local = None  # index scratch of local_jacobi, made at its first use
        self.timers = NewtonTimers()
        #: the compiled path (implicit/core/compiled_path.py), or None: the sparse one
        self.compiled = CompiledNewton(self) if use_compiled(options, size, self.kernels, integrator.name) else None
        #: (h, the first solved stage's τ/h) of the last step that continuation found hard, or None
        self._hard = None
        #: the choice "auto" made by the step (chooses_by_step), or None (not chosen by the step)
        self.path_choice = None
        self._by_step = self.chooses_by_step and options.newton_path == "auto" and options.linear_solver == "auto"
        self._paths = {}  # the (compiled, solver) pairs of the paths chosen so far, by linear solver
        self.totals = dict(steps=0, iterations=0, iterations_max=0, residual_max=0.0, retried_steps=0,
                           substeps_max=1, continued_steps=0)

    @property
    def R(self) -> np.ndarray:
        """(size,) the last residual."""
        return self.residuals.R

    @property
    def Rabs(self) -> np.ndarray:
        """(size,) the sum of the magnitudes of the terms of each row of the last residual."""
        return self.residuals.Rabs

    @property
    def h(self) -> float:
        """The step of the current step (set by :meth:`begin`)."""
        return self._step_start[3]

    def wrap_solver(self, solver):
        """The linear solver as the Newton iteration uses it (a scheme may wrap it: EM2 damps)."""
        return solver

    def choose_path(self, state, h: float) -> None:
        """"auto" by the step: at a new h, the path :func:`.large_steps.choose_path` names."""
        choose_path(self, state, h)

    # -- scheme hooks ---------------------------------------------------------------------------
    @abstractmethod
    def make_work(self, start: StartWork):
        """The scheme's work record (per-spring unknowns and scratch) around ``start``."""

    def compiled_extra(self) -> tuple:
        """The ``extra`` tuple the scheme's compiled_* kernels take (implicit/core/compiled_newton.py)."""
        return ()

    def atol_rounding(self) -> float:
        """c > 0 where Newton's atol follows the positions' round-off, c max |x| at each step's
        start (the compiled driver applies it as :meth:`begin` does); 0: atol as given."""
        return 0.0

    @abstractmethod
    def predictor_coefficients(self, h: float) -> np.ndarray:
        """(B/3, 4): sub-block j of a free node's predicted unknowns is c[j, 0] v + c[j, 1] a
        + c[j, 2] ȧ + c[j, 3] ä (velocity, acceleration and its first two time derivatives at
        the step's start; the derivatives beyond ``rate`` are zero); (B/3, 6) for a scheme whose
        predictor extrapolates (columns 4, 5: implicit/core/start.py)."""

    def predict(self, u: np.ndarray) -> None:
        """Fill the unknowns u with the explicit guess the start kernel computed (begin), which
        it wrote into ``self.u`` (= ``self.prediction``)."""
        if u is not self.prediction:
            u[:] = self.prediction

    @abstractmethod
    def residual(self, u: np.ndarray) -> tuple[int, int]:
        """Fill R, Rabs (and scratch) at u; (status, spring)."""

    @abstractmethod
    def jacobian(self, data: np.ndarray) -> None:
        """Fill the Jacobian values at the last residual's point."""

    @abstractmethod
    def linearize(self) -> None:
        """Fill ``work.jc``, the matrix-free Jacobian's coefficients at the last residual's point."""

    def sweep(self, du: np.ndarray, rhs: np.ndarray, r: np.ndarray, update: bool, first: bool = False) -> float:
        """r = rhs − J du, then (update) du += D⁻¹ r, r written out only without ``update``;
        returns max |r| (matrix-free J, the scheme's ``sweep`` kernel). ``first``: du is zero."""
        return self.kernels.sweep(self._topology, self._nodes, self._work, self.h, du, rhs, r, update,
                                  first)

    @abstractmethod
    def apply_inverse_inertia(self, v: np.ndarray) -> np.ndarray:
        """D⁻¹ v for the nodal inertia blocks D (a new array)."""

    @abstractmethod
    def finish(self, phi0: np.ndarray, new: StateArrays) -> tuple[int, int]:
        """The next state into ``new`` from the converged unknowns and Φ⁰ ``phi0`` (m,);
        (status, spring)."""

    def local_scratch(self) -> tuple:
        """The local Jacobi steps' scratch (made at the first use), as
        implicit/core/local_jacobi._local_jacobi takes it: (out (LOCAL_MAX_FRACTION n_free + 1,) int64,
        spring_mark (m,), node_mark (n,) uint8 zeros, springs (m,), nodes (n,) int64,
        node_of_block, block_mass (n_free,))."""
        if self._local is None:
            n, m = self.system.n_nodes, self.system.n_springs
            self._local = (np.empty(int(self.LOCAL_MAX_FRACTION * self.pattern.n_free) + 1, dtype=np.int64),
                           np.zeros(m, dtype=np.uint8), np.zeros(n, dtype=np.uint8),
                           np.empty(m, dtype=np.int64), np.empty(n, dtype=np.int64),
                           self.node_of_block, self.block_mass)
        return self._local

    def local_jacobi(self, u: np.ndarray, fraction: float):
        """One Jacobi step u −= D⁻¹ R restricted to the free nodes with a residual row above
        ``fraction`` × max Rabs, the residual then recomputed only where the step changes it
        (the springs at those nodes, the rows of the nodes at those springs' ends) with the
        kernel's own arithmetic: the residual a full evaluation at the new u gives, bit for bit
        for models whose thermal solve is closed-form (else within that solve's tolerance, from
        the last seeds). The scheme's ``local_jacobi`` kernel (implicit/core/local_jacobi._local_jacobi,
        the compiled Newton path's too); its residuals also write ``residuals.peak`` (2, n_free),
        each free node's largest |R| and Rabs, which the node selection reads. None where the
        scheme has no such kernel or more than LOCAL_MAX_FRACTION of the free nodes are above the
        threshold (a global step is then cheaper); else (status, spring, max |change of u|), with
        ``norms`` of the new residual."""
        kernel = getattr(self.kernels, "local_jacobi", None)
        if kernel is None:
            return None
        done, status, spring, rmax, smax, increment = kernel(
            self._step_start, self._topology, self._springs, self._nodes, self._work, u, self._residuals,
            self.warm, fraction * self.norms[1], self.local_scratch())
        if not done:
            return None
        self.warm = status == 0
        self.norms = (rmax, smax)
        return status, spring, increment

    # -- one step ---------------------------------------------------------------------------------
    def begin(self, x, p, eta, h: float) -> None:
        """Start a step at (x, p, η) with step h: geometry and explicit forces at x."""
        self.step_start = StepStart(x, p, eta, float(h))
        self.warm = False
        status, spring = self.kernels.start(self._step_start, self._topology, self._springs,
                                            self._nodes, self._work[0],
                                            self.predictor_coefficients(self.h), self.prediction)
        if status != 0:
            raise _StepError("invalid state at the start of the step", None, status, spring)

    def attempt(self, x, p, phi, eta, h: float):
        """One step from (x, p, Φ, η); returns the new (x, p, Φ, η) buffers and the Newton
        record, or raises _StepError. Never modifies its inputs. On the compiled path, a step
        whose matrix-free sweeps stall is made by the sparse path (its GMRES fallback), and so is
        any failed step of a scheme with ``continuation``."""
        if self.compiled is not None:
            done, failure = self.compiled.attempt(x, p, phi, eta, h)
            if failure is None:
                return done
            if not failure[-1] and not self.continuation:
                raise _StepError(*failure[:4])
        if self.continuation and self._hard is not None and self._hard[0] == h:
            # the last step of this h needed several stages: no first try at h from the predictor
            result = self.continued(x, p, eta, h, NewtonResult(False, 0, [], reason="continued at once"))
        else:
            self.begin(x, p, eta, h)
            self.predict(self.u)
            result = newton(self, self.u, self.options, self.solver, self.timers, stall=self.continuation)
            if not result.converged and self.continuation:
                result = self.continued(x, p, eta, h, result)
            elif result.converged:
                self._hard = None
        if not result.converged:
            raise _StepError(result.reason, result, result.status, result.spring)
        status, spring = self.finish(phi, self._new)
        if status != 0:
            raise _StepError("non-physical state after the step", result, status, spring)
        return self._new, result

    def continued(self, x, p, eta, h: float, failed: NewtonResult) -> NewtonResult:
        """The step's own equations solved by continuation in the step
        (:func:`.large_steps.continued`); ``failed``: the Newton solve from the predictor."""
        return continued(self, x, p, eta, h, failed)

    # -- the Stepper interface --------------------------------------------------------------------
    #: the key in ``state.extra`` of the predictor's history (rate 2, HO4): the unknowns of the
    #: step that produced the state and its h (0: none), (size + 1,) in the internal numbering;
    #: it travels with the state (checkpoints, load_state), so a resumed run predicts as the
    #: uninterrupted one and continues bit for bit
    HISTORY_KEY = "predictor_history"

    #: the key in ``state.extra`` of the continuation's memory (``_hard``: h and the first solved
    #: stage's τ/h, or none): it travels with the state, so a resumed run continues bit for bit
    CONTINUATION_KEY = "continuation_memory"

    #: the key in ``state.extra`` of the precision of the factors a solver with kept factorizations
    #: makes ((1,) float: 32 or 64; it goes from single to double where single factors fail their
    #: check, :class:`thermonet.solvers.direct.ReusedLU`): a resumed run factorizes as the run did
    PRECISION_KEY = "factorization_precision"

    def _history_from(self, state) -> None:
        """The predictor's history, the continuation's memory and the kept factors' precision,
        from the state they belong to (none there: none)."""
        bits = state.extra.get(self.PRECISION_KEY)
        if isinstance(bits, np.ndarray) and bits.size == 1 and hasattr(self.solver, "restore_precision"):
            self.solver.restore_precision(float(bits[0]))
        if self.continuation:
            saved = state.extra.get(self.CONTINUATION_KEY)
            ok = isinstance(saved, np.ndarray) and saved.shape == (2,) and saved[0] > 0
            self._hard = (float(saved[0]), float(saved[1])) if ok else None
        marker = self.work.start.history
        if not marker.size:
            return
        saved = state.extra.get(self.HISTORY_KEY)
        if isinstance(saved, np.ndarray) and saved.shape == (self.u.size + 1,):
            self.u[:] = saved[:-1]
            marker[0] = saved[-1]
        else:
            marker[0] = 0.0

    def _history_to(self, state) -> None:
        if getattr(self.solver, "reuses_factorization", False):
            state.extra[self.PRECISION_KEY] = np.array([self.solver.bits])
        if self.continuation:
            state.extra[self.CONTINUATION_KEY] = np.array(self._hard if self._hard is not None else (0.0, 0.0))
        marker = self.work.start.history
        if not marker.size:
            return
        saved = state.extra.get(self.HISTORY_KEY)
        if not (isinstance(saved, np.ndarray) and saved.shape == (self.u.size + 1,)):
            saved = state.extra[self.HISTORY_KEY] = np.empty(self.u.size + 1)
        saved[:-1] = self.u
        saved[-1] = marker[0]

    def advance(self, state, n_steps: int, h: float, measure: bool = False):
        if n_steps <= 0:
            return None
        if self._by_step:
            self.choose_path(state, h)
        self._history_from(state)
        try:
            iters, finals = [], []
            counts = [0, 1]  # retried steps, most substeps
            i = 0
            while i < n_steps:
                if self.compiled is not None:  # a run of steps in one call, up to a failed step
                    done, its, fin, failure = self.compiled.run(state.positions, state.momenta,
                                                                state.thermal_displacement, state.entropy, h,
                                                                n_steps - i)
                    iters.extend(its.tolist())
                    finals.extend(fin.tolist())
                    i += done
                    if failure is None:
                        break
                    if not (failure[-1] or self.continuation):  # failed: the retry policy, as the sparse path's
                        self._retry_step(state, h, _StepError(*failure[:4]), i, iters, finals, counts)
                        i += 1
                        continue
                self._step(state, h, i, iters, finals, counts)  # sparse (or stalled sweeps)
                i += 1
        finally:  # (after a failed step: its marker was consumed, the saved history says none)
            self._history_to(state)
        return self._record(state, h, n_steps, iters, finals, *counts)

    def _step(self, state, h: float, i: int, iters: list, finals: list, counts: list) -> None:
        """Step i of a chunk on the sparse path, committed to ``state``."""
        x, p, phi, eta = state.positions, state.momenta, state.thermal_displacement, state.entropy
        try:
            compiled, self.compiled = self.compiled, None
            try:
                new, result = self.attempt(x, p, phi, eta, h)
            finally:
                self.compiled = compiled
        except _StepError as err:
            self._retry_step(state, h, err, i, iters, finals, counts)
            return
        # the new state's buffers become the state's; the old ones the next step's outputs
        state.positions, state.momenta, state.thermal_displacement, state.entropy = new
        self._new = StateArrays(x, p, phi, eta)
        history = self.work.start.history
        if history.size:
            history[0] = h  # u: this committed step's solution (the next predictor's)
        iters.append(result.full_iterations)
        finals.append(result.history[-1])

    def _retry_step(self, state, h, err, i, iters, finals, counts) -> None:
        it, final, substeps = self._retry(state, h, err, i)
        counts[0] += 1
        counts[1] = max(counts[1], substeps)
        iters.append(it)
        finals.append(final)

    def _record(self, state, h, n_steps, iters, finals, retried, substeps_max) -> dict:
        """The totals updated with a chunk's steps, and the chunk's statistics."""
        t = self.totals
        t["steps"] += n_steps
        t["iterations"] += int(sum(iters))
        t["iterations_max"] = max(t["iterations_max"], max(iters))
        t["residual_max"] = max(t["residual_max"], max(finals))
        t["retried_steps"] += retried
        t["substeps_max"] = max(t["substeps_max"], substeps_max)
        if retried:
            warnings.warn(f"{self.integrator.name}: {retried} step(s) of h = {h:g} near t = {state.time:.6g} "
                          f"needed up to {substeps_max} substeps (retry policy)", RuntimeWarning, stacklevel=3)
        return {
            "newton_iterations": iters[-1],
            "newton_iterations_max": max(iters),
            "newton_iterations_mean": float(np.mean(iters)),
            "newton_residual": finals[-1],
            "newton_residual_max": max(finals),
            "retried_steps": retried,
            "substeps_max": substeps_max,
        }

    def _retry(self, state, h: float, err: _StepError, i: int):
        """Redo the failed step as 2, 4, … substeps (as many levels as options.retry); commit
        the first level that succeeds. Returns (Newton iterations, final residual, substeps)."""
        x, p, phi, eta = state.positions, state.momenta, state.thermal_displacement, state.entropy
        tried = []
        for level in range(1, self.options.retry + 1):
            substeps = 2 ** level
            xs, ps, phis, etas = x.copy(), p.copy(), phi.copy(), eta.copy()
            its, final = 0, 0.0
            try:
                for _ in range(substeps):
                    new, result = self.attempt(xs, ps, phis, etas, h / substeps)
                    xs[:], ps[:], phis[:], etas[:] = new
                    its = max(its, result.full_iterations)
                    final = max(final, result.history[-1])
            except _StepError as sub:
                tried.append(f"{substeps} substeps: {sub.reason}")
                continue
            x[:], p[:], phi[:], eta[:] = xs, ps, phis, etas
            return its, final, substeps
        raise self._failure(state, h, err, i, tried)

    def _failure(self, state, h: float, err: _StepError, i: int, tried: list) -> StepFailure:
        """The StepFailure for step i of the chunk, naming step, time, residual history and the
        worst node and spring in the user's numbering."""
        lay = self.system.layout
        k = state.step + i
        t = state.time + i * h
        history = err.result.history if err.result is not None else []
        details = dict(step=k, time=t, h=h, reason=err.reason, residual_history=list(history),
                       worst_node=None, worst_spring=None, retries=tried)
        parts = [f"{self.integrator.name}: step {k} -> {k + 1} (t = {t:.10g} -> {t + h:.10g}, h = {h:g}) failed: {err.reason}"]
        if err.status:
            parts.append(STATUS_TEXT.get(err.status, f"status {err.status}"))
        if history:
            parts.append("scaled residual history [" + ", ".join(f"{r:.3e}" for r in history) + "]")
        if err.spring >= 0:
            e = err.spring
            details["worst_spring"] = int(lay.spring_order[e])
            a, b = self.system.edges[e]
            details["worst_node"] = int(lay.node_order[a if self.free_index[a] >= 0 else b])
            parts.append(f"worst spring {details['worst_spring']} (nodes {int(lay.node_order[a])}, {int(lay.node_order[b])})")
        elif history and self.pattern.size:
            per_node = np.abs(self.R).reshape(-1, self.block).max(axis=1)
            kb = int(np.argmax(per_node))
            details["worst_node"] = int(lay.node_order[self.node_of_block[kb]])
            strain = np.abs(self.len_end() / self.work.start.len0 - 1.0)
            strain = np.where(np.isfinite(strain), strain, np.inf)
            e = int(np.argmax(strain))
            details["worst_spring"] = int(lay.spring_order[e])
            parts.append(f"worst node {details['worst_node']} (|R| = {per_node[kb]:.3e}), worst spring "
                         f"{details['worst_spring']} (relative length change {strain[e]:.3g} over the step)")
        if tried:
            parts.append("retries: " + "; ".join(tried))
        parts.append(f"state left at step {k}, t = {t:.10g}")
        return StepFailure("; ".join(parts), steps_done=i, details=details)

    def len_end(self) -> np.ndarray:
        """(m,) spring lengths at the end of the step, at the last iterate."""
        return self.work.len1

    # -- summaries --------------------------------------------------------------------------------
    def summary(self) -> dict:
        """Totals over the stepper's life: steps, Newton iterations (total, mean, max), the
        largest final scaled residual, retried steps, and seconds per phase."""
        t = dict(self.totals)
        t["iterations_mean"] = t["iterations"] / t["steps"] if t["steps"] else math.nan
        t["linear_solver"] = self.solver.name if self.compiled is None else f"compiled, {self.compiled.linear_solver}"
        t["newton_path"] = "sparse" if self.compiled is None else "compiled"
        choice = self.path_choice
        opts = self.options
        t["path_reason"] = (choice.reason if choice is not None else
                            f"newton_path = {opts.newton_path!r}, linear_solver = {opts.linear_solver!r}")
        t["h_omega_max"] = choice.h_omega if choice is not None else None  # (not chosen by the step)
        # steps redone as substeps (the retry policy), as a fraction of the steps
        t["substep_fraction"] = t["retried_steps"] / t["steps"] if t["steps"] else 0.0
        t["factorizations"] = self.timers.factorizations  # (splu-reuse) made, and iterations that kept one
        t["reused_factorizations"] = self.timers.reused_factorizations
        # (splu-reuse) of the factorizations, those made because a carried one had grown stale
        t["stale_refactorizations"] = getattr(self.solver, "stale_refactorizations", 0)
        # (splu-reuse) solves with kept factors copied onto their elimination tree (solvers.tree_solve)
        t["tree_solves"] = getattr(self.solver, "tree_solves", 0)
        # (splu-reuse) the precision of the kept factors, and why double where single was asked for
        t["factor_precision"] = getattr(self.solver, "precision", None)
        t["factor_precision_raised"] = getattr(self.solver, "raised", "")
        t["unknowns"] = self.pattern.size
        t["jacobian_nnz"] = self.pattern.nnz
        t["jacobi_steps"] = self.timers.jacobi_steps  # finishing steps u −= D⁻¹ R, not counted as iterations
        t["local_steps"] = self.timers.local_steps  # of those, the ones on a few nodes only
        t.update({f"time_{k}": v for k, v in self.timers.as_dict().items() if isinstance(v, float)})
        return t


def newton_options(options: dict) -> NewtonOptions:
    """The stepper options accepted by the implicit integrators (see NewtonOptions)."""
    return NewtonOptions.from_options(**options)
