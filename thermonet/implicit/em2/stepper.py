"""EM2, the energy–momentum (discrete-gradient midpoint) integrator (docs/theory.md §3; Gonzalez 1996,
Simo & Tarnow 1992): implicit in x¹ only, second order, symmetric.

    x¹ = x⁰ + h M⁻¹ (p⁰ + p¹)/2,   p¹ = p⁰ + h m g − h Σ_e ∇̄U_e,   η¹ = η,   Φ¹ = Φ⁰ + h θ(l̄, η)

with the discrete gradient ∇̄U_e = ∓s_e d̄_e, s_e = [U(l¹, η) − U(l⁰, η)] / [(l¹ − l⁰) l̄]
(kernels in :mod:`thermonet.implicit.em2.kernels`). Total energy is conserved exactly (to the Newton
tolerance) at any step, so EM2 has no stability limit: far above the explicit limit the fast
modes lose accuracy (their phase), not stability. Linear and angular momentum and every spring's
entropy are kept exactly. Φ is a diagnostic here (θ at the mean length).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .kernels import LENGTH_LIMIT, LINE_SEARCH_ABOVE, LINE_SEARCH_HALVINGS, EM2Work  # noqa: F401
from ..core.records import plain
from ...integrators.base import Integrator, register_integrator
from ..core.stepper import ImplicitStepper, newton_options


class EM2(Integrator):
    """The energy–momentum integrator: unconditionally stable (no h_max)."""

    name = "em2"
    order = 2
    explicit = False
    #: no stability limit: the step policy and the run-time guard never refuse its step
    stability_interval = math.inf
    unconditionally_stable = True
    description = "energy–momentum (discrete-gradient midpoint) step at fixed entropy, implicit in x¹, order 2"

    def make_stepper(self, system, parallel: bool = False, **options) -> "EM2Stepper":
        options.setdefault("max_iterations", MAX_ITERATIONS)
        options.setdefault("retry", RETRY)
        stepper = EM2Stepper(self, system, newton_options(options), parallel)
        stepper.rounding_atol = "atol" not in options
        return stepper


#: EM2's default Newton iterations per step (other schemes: 12): far above the explicit limit
#: the corrections are shortened (LENGTH_LIMIT) and take a few more iterations
MAX_ITERATIONS = 30
#: EM2's default retry levels (other schemes: 0): a step whose Newton solve fails is redone as
#: 2, 4, …, 2**RETRY substeps (warned, and in the diagnostics), each keeping the energy exactly.
#: Far above the explicit limit (hω ≳ 10 on nets whose springs turn or stretch a lot per step)
#: a whole step's Newton solve does not always converge from the predictor: measured on the
#: heated plate (scenes/lattice2d.toml) at 7.6× CO2's limit, 8 of 20 steps needed 2–4 substeps
RETRY = 4
#: with kept factorizations (far above the explicit limit) the last step's displacement is the
#: guess, without weighing the own one, where its scaled residual max |R| / max Rabs is at most
#: this: on the steel part it is 5e-3–3e-2 at 100× CO2's stable step and 2e-2–1e-1 at 1e4× (10th to
#: 90th percentile), the own guess's 0.9–1.0, which won no step after the first, so weighing it
#: cost a residual a step; where neither guess is that close (a hot lattice ringing at 5×: both
#: 0.25–0.8) the two are still weighed, and such runs take the iterations they took before
PREVIOUS_TAKEN = 0.1
#: without a given ``atol``, Newton's absolute increment tolerance is this many ulps of the
#: largest coordinate: a correction below the positions' own rounding is noise (near rest, the
#: forces' rounding, c ε per spring from ln(l/l0), can hold the scaled residual above 1e-12
#: while the displacements are tiny; measured on a chain's slow mode at 1e-4 amplitude)
ATOL_ULPS = 8


class LengthLimited:
    """The stepper's linear solver, its corrections made safe far from the solution (a damped
    Newton step): each correction is first shortened so that no spring's vector changes by more
    than LENGTH_LIMIT times its length, and then, while the scaled residual is above
    LINE_SEARCH_ABOVE, halved until the residual's 2-norm falls (Armijo; the Newton direction
    descends on it). Far above the explicit limit a full Newton correction would stretch a stiff
    spring by thousands of lengths, or through zero; near the solution the correction is taken
    whole and Newton converges quadratically. Everything else is the wrapped solver's."""

    def __init__(self, solver, stepper):
        object.__setattr__(self, "inner", solver)
        object.__setattr__(self, "stepper", stepper)

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def __setattr__(self, name, value):  # statistics (iterations, ...) live in the wrapped solver
        setattr(self.inner, name, value)

    def solve(self, rhs, target: float = 0.0, settled: float = 0.0):
        du = self.inner.solve(rhs, target, settled)
        st = self.stepper
        rmax, smax = st.norms
        # the compiled path's damping kernel (implicit/em2/kernels.py), so both paths damp alike
        st.kernels.damp(st._step_start, st._topology, st._springs, st._nodes, st._work, st._residuals,
                        (rmax, smax), (st.u, du, st.trial))
        return du


class EM2Stepper(ImplicitStepper):
    """EM2 bound to a system: 3 unknowns (the displacement) per free node."""

    block = 3
    scheme = "em2"
    #: Newton's atol follows the positions' rounding (ATOL_ULPS; set by EM2.make_stepper)
    rounding_atol = False
    #: a max |R| at or below this that Newton no longer reduces is converged (set by predict)
    residual_floor = 0.0
    #: (unknowns, status, spring) where predict left the residual evaluated (take_evaluated)
    _evaluated = None

    #: "auto" follows h·ω_max (implicit/core/compiled_path.choose_by_step)
    chooses_by_step = True
    #: a failed step's equations are solved by continuation in h before substeps (retry)
    continuation = True

    def __init__(self, integrator, system, options, parallel: bool = False):
        super().__init__(integrator, system, options, parallel)
        #: (h, u, x¹) of the last step finished, the predictor's other guess (predict)
        self._previous = None
        self._previous_saved = None
        self.solver = self.wrap_solver(self.solver)

    def wrap_solver(self, solver):
        return LengthLimited(solver, self)

    def make_work(self, start) -> EM2Work:
        # the start kernel writes the acceleration at x⁰ here; predict() makes the guess from it
        self.accel = self.prediction = np.zeros(self.pattern.size)
        self.trial = np.zeros(self.pattern.size)  # the damped step's trial points
        return EM2Work.allocate(start)

    def atol_rounding(self) -> float:
        return ATOL_ULPS * np.finfo(np.float64).eps if self.rounding_atol else 0.0

    def begin(self, x, p, eta, h: float) -> None:
        super().begin(x, p, eta, h)
        if getattr(self.solver, "reuses_factorization", False):
            self.solver.new_step()  # a kept factorization is now an earlier step's (modified Newton)
        if self.rounding_atol:
            floor = self.atol_rounding() * float(np.abs(x).max(initial=0.0))
            if not 0.5 * self.options.atol <= floor <= 2.0 * self.options.atol:
                self.options = dataclasses.replace(self.options, atol=floor)

    # -- kept factorizations across steps, and across a checkpoint ---------------------------
    #: the key in ``state.extra`` of the point where the kept factorization was made (solvers.
    #: direct.ReusedLU): (h, x⁰, p⁰, η, u) flattened; absent where none is kept
    FACTORIZATION_KEY = "factorization_point"
    #: the key of the number of solves it had made and what it is worth in solves ((2,) float:
    #: which solver solves the next, and when it is refactorized; a (3,) key of an older run holds
    #: the worth last)
    SOLVES_KEY = "factorization_solves"
    #: the key of how stale it had grown ((4,) float: solvers.direct.ReusedLU.staleness)
    STALENESS_KEY = "factorization_staleness"
    #: the key of the solver's count toward its first copy onto the elimination tree and whether
    #: it made one ((2,) float: ReusedLU.superlu_solves, laid_out), kept with or without a kept
    #: factorization
    TREE_KEY = "factorization_tree"

    def jacobian_point(self) -> np.ndarray:
        """Where the Jacobian is being made: the step (h, x⁰, p⁰, η) and the unknowns u of the
        last residual, one flat copy."""
        x0, p0, eta, h = self._step_start
        return np.concatenate(([h], x0.ravel(), p0.ravel(), eta, self.u))

    def refactorize_at(self, point: np.ndarray) -> None:
        """The kept factorization rebuilt at a saved ``point`` (jacobian_point): the same
        Jacobian values, so the same factorization, as where it was first made."""
        n, m = self.system.n_nodes, self.system.n_springs
        h = float(point[0])
        x0, p0 = point[1:1 + 3 * n].reshape(n, 3), point[1 + 3 * n:1 + 6 * n].reshape(n, 3)
        eta = point[1 + 6 * n:1 + 6 * n + m]
        options, saved_u = self.options, self.u.copy()
        try:
            self.begin(x0, p0, eta, h)
            self.predict(self.trial)  # (the start values the residual reads)
            self.u[:] = point[1 + 6 * n + m:]
            status, _ = self.residual(self.u)
            if status != 0:
                self.solver.stale = True
                return
            if self.data.size != self.pattern.nnz:
                self.data = np.zeros(self.pattern.nnz)
            self.jacobian(self.data)
            self.solver.factorize(self.data, h)
        finally:
            self.options = options  # (begin may move atol: the run's own steps decide it)
            self.u[:] = saved_u

    #: the key in ``state.extra`` of the last step's (h, u, x¹), the predictor's other guess
    PREVIOUS_KEY = "em2_previous_step"

    def _history_from(self, state) -> None:
        super()._history_from(state)
        saved = state.extra.get(self.PREVIOUS_KEY)
        if isinstance(saved, np.ndarray) and saved.size == 1 + self.u.size + 3 * self.system.n_nodes:
            if self._previous is None or saved is not self._previous_saved:
                size = self.u.size
                self._previous = (float(saved[0]), saved[1:1 + size].copy(), saved[1 + size:].reshape(-1, 3).copy())
        else:
            self._previous = None
        solver = self.solver
        if not getattr(solver, "reuses_factorization", False):
            return
        count = state.extra.get(self.TREE_KEY)
        if isinstance(count, np.ndarray) and count.size == 2:
            solver.restore_tree_count(count)
        saved = state.extra.get(self.FACTORIZATION_KEY)  # (only of one carried from step to step)
        if not isinstance(saved, np.ndarray) or saved.size < 2:
            solver.stale = True  # none kept with this state: the next step factorizes
        elif saved is not solver.point and not (
                not solver.stale and solver.point is not None and np.array_equal(saved, solver.point)):
            self.refactorize_at(saved)  # resumed, or rewound: the factorization this state was left with
            if solver.stale:  # (its residual there was not admissible: the next step factorizes)
                return
            solves = state.extra.get(self.SOLVES_KEY)
            if isinstance(solves, np.ndarray) and 1 <= solves.size <= 3:
                solver.restore_solves(int(solves[0]), float(solves[-1]) if solves.size > 1 else None)
            staleness = state.extra.get(self.STALENESS_KEY)
            if isinstance(staleness, np.ndarray) and staleness.size == solver.staleness.size:
                solver.restore_staleness(staleness)

    def _history_to(self, state) -> None:
        super()._history_to(state)
        if self._previous is not None:
            h, u, x1 = self._previous
            self._previous_saved = state.extra[self.PREVIOUS_KEY] = np.concatenate(([h], u, x1.ravel()))
        else:
            state.extra.pop(self.PREVIOUS_KEY, None)
        solver = self.solver
        if getattr(solver, "reuses_factorization", False):
            state.extra[self.TREE_KEY] = np.array([float(solver.superlu_solves), float(solver.laid_out)])
        if getattr(solver, "carries_factorization", False) and not solver.stale and solver.point is not None:
            state.extra[self.FACTORIZATION_KEY] = solver.point
            state.extra[self.SOLVES_KEY] = np.array([float(solver.solves), float(solver.worth)])
            state.extra[self.STALENESS_KEY] = solver.staleness.copy()
        else:
            for key in (self.FACTORIZATION_KEY, self.SOLVES_KEY, self.STALENESS_KEY):
                state.extra.pop(key, None)

    def predictor_coefficients(self, h: float) -> np.ndarray:
        """The start kernel's output is the acceleration a (the predictor is EM2's own)."""
        return np.array([[0.0, 1.0, 0.0, 0.0]])

    def predict(self, u: np.ndarray) -> None:
        """The midpoint step of each node on its own springs' stiffness (implicit.em2.kernels), or, with
        kept factorizations and where the step before ended at this step's start with the same
        h, that step's displacement again (constant velocity: a slowly moving part's) where its
        scaled residual is at most PREVIOUS_TAKEN, else the one of the two whose max |R| is
        the smaller; and the residual's rounding floor (``residual_floor``,
        read by the Newton iteration): ATOL_ULPS ulps of the largest spring force that one ulp of length would make,
        (h/2) κ_e l⁰_e with κ_e the predictor's spring stiffness. A max |R| below it that a
        Newton correction no longer reduces (less than 2×) is the rounding of the force terms: a
        net at rest in exact equilibrium has a max |R| of a few 1e-16 over a max Rabs of the
        same size, a scaled residual of order 1 that no Newton correction can reduce."""
        self._evaluated = None
        self.kernels.predict(self._step_start, self._topology, self._springs, self._nodes, self._work,
                             self.accel, u)
        start = self.work.start  # (guess: the predictor's per-spring stiffness κ_e, until the finish)
        self.residual_floor = (ATOL_ULPS * np.finfo(np.float64).eps * 0.5 * self.h
                               * float(np.max(start.guess * start.len0, initial=0.0)))
        before = self._previous  # (with kept factorizations, the path far above the limit)
        if (before is None or before[0] != self.h or not getattr(self.solver, "reuses_factorization", False)
                or not np.array_equal(before[2], self._step_start[0])):
            return
        status, spring = self.residual(before[1])
        previous = self.norms[0] if status == 0 else math.inf
        if status == 0 and self.norms[0] <= PREVIOUS_TAKEN * self.norms[1]:
            u[:] = before[1]
            # the residual's buffers now hold its value at u: Newton's first evaluation would
            # repeat it bit for bit (take_evaluated)
            self._evaluated = (before[1], status, spring)
            return
        status, spring = self.residual(u)
        if status == 0 and self.norms[0] <= previous:
            self._evaluated = (u.copy(), status, spring)
        elif previous < math.inf:
            u[:] = before[1]  # (Newton evaluates it again: the buffers hold the own guess's)

    def take_evaluated(self, u: np.ndarray):
        """(status, spring) of the last residual where predict left it evaluated at exactly u
        (the guess it chose, after weighing it), once; else None."""
        done, self._evaluated = self._evaluated, None
        if done is None or not np.array_equal(done[0], u):
            return None
        return done[1], done[2]

    def finish(self, phi0, new):
        status, spring = self.kernels.finish(self._step_start, self._topology, self._springs, self._nodes,
                                             self._work, self.u, phi0, plain(new))
        if status == 0:  # (the next step's other predictor)
            self._previous = (self.h, self.u.copy(), new.x.copy())
        return status, spring

    def residual(self, u: np.ndarray):
        self._evaluated = None  # (the buffers move to u)
        status, spring, rmax, smax = self.kernels.residual(self._step_start, self._topology, self._springs,
                                                           self._nodes, self._work, u, self._residuals)
        self.norms = (rmax, smax)
        return status, spring

    def linearize(self) -> None:
        self.kernels.linearize(self._springs, self._work, self.h)

    def apply_inverse_inertia(self, v):
        """(h/m) v per free node."""
        return (np.asarray(v).reshape(-1, 3) * (self.h / self.block_mass)[:, None]).ravel()

    def jacobian(self, data: np.ndarray) -> None:
        self.kernels.jacobian(self._topology, self._springs, self._nodes, self._work, self._places, self.h, data)


EM2_INTEGRATOR = register_integrator(EM2())
