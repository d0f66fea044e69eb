"""Heat flow around any adiabatic integrator.

Explicit splittings run conduction and thermal waves in their own kernels
(:meth:`~thermonet.explicit.splitting.Splitting.with_heat`, compiled into the fused kernel).
Every other stepper (the implicit ones) is wrapped by :class:`ConductionAround`:
``K_f(kh/2) ∘ A(h)^k ∘ K_r(kh/2)`` per conduction cycle of k steps (k = 1: every step), the
sweeps compiled (:func:`thermonet.heat.passes.heat_kernels`), the steps A the stepper's own.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..integrators.base import StepFailure, Stepper
from ..kernels import records


def integrator_with_heat(integrator, heat, backend: str):
    """The integrator a run with heat flow uses: an explicit splitting with the heat rows in its
    schedule; an implicit integrator as it is (its stepper is wrapped), which supports
    conduction but not thermal waves."""
    if backend != "cpu" and not getattr(integrator, "explicit", False):
        raise InputError(f"heat flow (conduction, baths, sources, thermal waves) on backend {backend!r} runs with "
                         f"the explicit integrators; {integrator.name} is implicit")
    if getattr(integrator, "explicit", False):
        return integrator.with_heat(heat.conduction, heat.waves)
    if heat.waves:
        raise InputError(f"thermal waves (g_star) run with the explicit splittings (co2, co4, co6); "
                         f"{integrator.name} is implicit")
    return integrator


class ConductionAround(Stepper):
    """``K_f(h/2) ∘ inner(h) ∘ K_r(h/2)`` per step, for a stepper without heat rows of its own."""

    def __init__(self, inner: Stepper, system, parallel: bool = False):
        from .passes import heat_kernels

        self.inner = inner
        self.system = system
        self.heat = system.heat
        P, uniform = system.kernel_parameters
        self._temperature_pass, self._sweep = heat_kernels(system.model, parallel, uniform)
        self._topology = records.topology(system.layout)
        self._springs = records.Springs(system.rest_lengths, P)
        self._theta = np.empty(system.n_springs)
        self._theta_start = np.empty(system.n_springs)
        self._length = np.empty(system.n_springs)

    def _conduct(self, state, tau: float, t: float, directions: int, sweeps: int) -> None:
        from .logs import heat_logs

        record = self.heat.record(tau, heat_logs(state, self.heat), sweeps=sweeps)
        self._temperature_pass(state.positions, state.entropy, self._topology, self._springs, self._theta,
                               self._length)
        self._sweep(record, self._theta, self._theta_start, state.entropy, tau, t, directions)

    def advance(self, state, n_steps: int, h: float, measure: bool = False):
        """``n_steps`` steps; on a failed step the state is restored to the step's start (η and
        the logs included) and the StepFailure says how many steps were done. The forward half
        sweep runs before the first step of each conduction cycle, the reverse one after its
        last (:func:`~thermonet.heat.logs.cycle_of`)."""
        from .logs import cycle_of, heat_logs
        from .passes import FORWARD, REVERSE

        stats = None
        step0, t0 = state.step, state.time
        every, at, sweeps = cycle_of(state, self.heat)
        tau = 0.5 * every * h / sweeps
        for i in range(int(n_steps)):
            t = t0 + i * h
            eta = state.entropy.copy()
            opens = (at + i) % every == 0
            # (only a forward half sweep before the inner step changes the logs that a failed
            # step must give back: copying them at every step cost 0.65 ms a step on 1e5 springs)
            logs = {k: v.copy() for k, v in heat_logs(state, self.heat).items()} if opens else {}
            state.step, state.time = step0 + i, t
            if opens:
                self._conduct(state, tau, t, FORWARD, sweeps)
            try:
                stats = self.inner.advance(state, 1, h)
            except StepFailure as exc:
                np.copyto(state.entropy, eta)
                for k, v in logs.items():
                    np.copyto(state.extra["heat"][k], v)
                state.step, state.time = step0, t0
                raise StepFailure(str(exc), steps_done=i, details=exc.details) from None
            if (at + i + 1) % every == 0:
                self._conduct(state, tau, t0 + (i + 1) * h, REVERSE, sweeps)
        state.step, state.time = step0, t0
        return stats

    def diagnostics_row(self, system, state):
        return self.inner.diagnostics_row(system, state)

    def sync(self, state) -> None:
        self.inner.sync(state)

    def summary(self):
        return self.inner.summary()

    def __getattr__(self, name):
        return getattr(self.inner, name)
