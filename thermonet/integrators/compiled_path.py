"""The compiled Newton path of an implicit stepper: whole steps, many per call, in one compiled
driver (:mod:`thermonet.kernels.newton_compiled`), with a dense LU; and the choice between it and
the sparse path (:func:`thermonet.solvers.newton.newton` with SuperLU or matrix-free sweeps).

``newton_path`` (a stepper option): "compiled", "sparse", or "auto" (default): compiled up to
COMPILED_MAX_UNKNOWNS unknowns where the scheme offers it, sparse above (measured crossover:
benchmarks/README.md, "Implicit integrators").
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..kernels.implicit_common import implicit_kernels
from ..kernels.implicit_records import NextState, plain
from ..kernels.newton_compiled import CONVERGED, NO_CONVERGENCE, REASONS, newton_steps_kernel
from ..solvers import NewtonResult
#: "auto" takes the compiled path up to this many unknowns (B per free node): where its dense
#: LU (size³/3) starts to cost more than the sparse path's Python and SuperLU overhead
COMPILED_MAX_UNKNOWNS = 120


def offers_compiled(kernels) -> bool:
    """Whether a scheme's kernels include the compiled path's (compiled_residual, …)."""
    return all(hasattr(kernels, k) for k in ("compiled_residual", "compiled_jacobian", "compiled_finish"))


def use_compiled(path: str, size: int, kernels, name: str) -> bool:
    """The choice of ``newton_path`` for a net of ``size`` unknowns."""
    if path == "sparse":
        return False
    if path == "compiled":
        if not offers_compiled(kernels):
            raise InputError(f"{name}: newton_path='compiled' is not available for this scheme")
        return True
    return offers_compiled(kernels) and size <= COMPILED_MAX_UNKNOWNS


class CompiledNewton:
    """The compiled driver bound to one stepper (its records, pattern and options) and the
    driver's buffers: the CSR values, the dense matrix and its pivots, the correction, the next
    state, the per-step iteration counts and final residuals, the failure's history and info."""

    def __init__(self, stepper):
        system = stepper.system
        _, uniform = system.kernel_parameters
        kernels = implicit_kernels(system.model, stepper.scheme, False, uniform, stepper.rate)
        self.driver = newton_steps_kernel(system.model, stepper.scheme, kernels, uniform, stepper.rate)
        pattern = stepper.pattern
        size = pattern.size
        n, m = system.n_nodes, system.n_springs
        self.stepper = stepper
        self._new = NextState(np.empty((n, 3)), np.empty((n, 3)), np.empty(m), np.empty(m))
        self._linear = None
        self._buffers = (pattern.indptr, pattern.indices, np.zeros(pattern.nnz), np.zeros((size, size)),
                         np.zeros(size, dtype=np.int64), np.zeros(size))
        opts = stepper.options
        self._control = (float(opts.tolerance), float(opts.rtol), float(opts.atol), int(opts.max_iterations))
        self._history = np.zeros(int(opts.max_iterations) + 2)
        self._info = np.zeros(5, dtype=np.int64)
        self._out = None
        self._coef = (None, None)

    def run(self, x, p, phi, eta, h: float, n_steps: int):
        """Up to n_steps steps from (x, p, Φ, η), committed in place step by step. Returns (steps
        done, iterations (done,), final scaled residuals (done,), the failure or None): a
        failure is (NewtonResult, reason, status, spring) of step ``done``."""
        s = self.stepper
        if self._coef[0] != h:
            self._coef = (h, s.predictor_coefficients(h))
        if self._out is None or self._out[0].shape[0] < n_steps:
            self._out = (np.zeros(n_steps, dtype=np.int64), np.zeros(n_steps), self._history, self._info)
        if self._linear is None:
            self._linear = self._buffers + (s.u, plain(s.residuals), tuple(self._new))
        records = (s._topology, s._springs, s._nodes, s._work, s._places)
        done = self.driver((x, p, phi, eta, float(h), self._coef[1]), records, s.compiled_extra(), self._linear,
                           self._control + (int(n_steps),), self._out)
        iterations, finals = self._out[0][:done], self._out[1][:done]
        s.warm = False
        if done == n_steps:
            return done, iterations, finals, None
        _, reason, status, spring, nh = (int(v) for v in self._info)
        its = int(self._out[0][done]) if reason != CONVERGED and nh else 0
        history = [float(r) for r in self._history[:nh]]
        if reason == NO_CONVERGENCE:
            text = f"no convergence in {s.options.max_iterations} iterations"
        else:
            text = REASONS[reason]
        result = NewtonResult(False, its, history, status, spring, text) if nh else None
        return done, iterations, finals, (result, text, status, spring)

    def attempt(self, x, p, phi, eta, h: float):
        """One step from copies of (x, p, Φ, η): (the new state's buffers, the NewtonResult), or
        the failure tuple of :meth:`run` as (None, failure)."""
        xs, ps, phis, etas = x.copy(), p.copy(), phi.copy(), eta.copy()
        done, iterations, finals, failure = self.run(xs, ps, phis, etas, h, 1)
        if failure is not None:
            return None, failure
        history = [float(finals[0])]
        return (NextState(xs, ps, phis, etas), NewtonResult(True, int(iterations[0]), history)), None
