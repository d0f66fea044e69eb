"""Loads around an implicit step (GTR-α, HO4, ...), by Strang splitting, without touching the
implicit kernels: a step of h from t is

    force kick (h/2 at t) ∘ drive to u(t + h/2) ∘ implicit step ∘ drive to u(t + h) ∘ force kick (h/2 at t + h)

Driven nodes are anchors of the implicit step, held at their mid-step position u(t + h/2)
(the midpoint rule for the motion they impose) and moved between steps; each move does the
work ΔU of the springs it strains, exactly. A force's half kicks add f(t) to its free nodes'
momenta and −ḟ·Σ w x to its work counter, as in the explicit kernels. So H − H(0) − W is the
implicit scheme's own energy error; the trajectory is of order 2 in h (the midpoint motion and
the Strang splitting), whatever the scheme's order. Drives must hold the axes they do not set
(``free=False``): a node free in some axes would be an unknown of the implicit step with
constraints it does not take.
"""

from __future__ import annotations

import numpy as np

from ..diagnostics import spring_fields
from ..errors import InputError
from ..integrators.base import StepFailure
from .stepping import work_of


class _Clock:
    time_origin = staticmethod(lambda: (0, 0.0))


class ImplicitLoads:
    """An implicit stepper with the loads of ``load_set`` around each step (see the module
    docstring); everything else is the wrapped stepper's."""

    measures = False

    def __init__(self, inner, system, load_set):
        self.inner, self.system, self.set = inner, system, load_set
        self.loads = _Clock()  # the Simulation points its time_origin at its own clock
        rank = system.layout.node_rank
        self._drives, self._forces = [], []
        for i, (load, idx) in enumerate(zip(load_set.loads, load_set.nodes)):
            rows = rank[idx]
            if load.kind == "drive":
                if load_set.free[i].any():
                    raise InputError(f"loads.{load_set.names[i]}.free: an implicit integrator drives whole nodes; "
                                     f"a drive free in some axes needs an explicit one")
                self._drives.append((i, rows, load_set.positions[idx] - load_set.u0[i]))
            else:
                m = load_set.masses[idx]
                w = m / m.sum() if load.total else np.ones(len(idx))
                self._forces.append((i, rows, w, ~system.anchored[rows]))

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def advance(self, state, n_steps: int, h: float, measure: bool = False):
        step0, t0 = self.loads.time_origin()
        base = state.step - step0
        work = work_of(state, len(self.set))
        stats = None
        first, start = state.step, state.time
        try:
            for i in range(n_steps):
                k = float(base + i)
                keep = (state.positions.copy(), state.momenta.copy(), work.copy())
                self._kick(state, t0 + k * h, 0.5 * h, work)
                self._move(state, t0 + (k + 0.5) * h, work)
                # the inner stepper's step one at a time, each at its own step and time (heat
                # flow's baths and sources and its conduction cycle read them)
                state.step, state.time = first + i, start + i * h
                try:
                    stats = self.inner.advance(state, 1, h)
                except StepFailure as exc:  # the state is this step's start: undo the loads' half
                    np.copyto(state.positions, keep[0])
                    np.copyto(state.momenta, keep[1])
                    np.copyto(work, keep[2])
                    raise StepFailure(str(exc), steps_done=i, details=exc.details) from None
                self._move(state, t0 + (k + 1.0) * h, work)
                self._kick(state, t0 + (k + 1.0) * h, 0.5 * h, work)
        finally:
            state.step, state.time = first, start  # (the driver advances them)
        return stats

    def _kick(self, state, t: float, tau: float, work: np.ndarray) -> None:
        x, p = state.positions, state.momenta
        for i, rows, w, free in self._forces:
            comps = self.set.components[i]
            f = np.array([0.0 if c is None else c(t) for c in comps])
            rate = np.array([0.0 if c is None else c.rate(t) for c in comps])
            p[rows[free]] += tau * w[free, None] * f[None, :]
            work[i] += tau * -(rate @ (w @ x[rows]))

    def _move(self, state, t: float, work: np.ndarray) -> None:
        if not self._drives:
            return
        x = state.positions
        for i, rows, ref in self._drives:
            comps = self.set.components[i]
            u = np.array([0.0 if c is None else c(t) for c in comps])
            before = spring_fields(self.system, x, state.entropy).internal_energy.sum()
            x[rows] = ref + u[None, :]
            work[i] += spring_fields(self.system, x, state.entropy).internal_energy.sum() - before
