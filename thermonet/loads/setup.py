"""A Simulation's loads: checked against the integrator and backend, the initial state's driven
axes held (the stepper is wrapped for them in :func:`thermonet.assemble.assemble`), and measured
at every diagnostics row (each load's displacement, reaction or applied force and
work; the total work and the balance H − H(0) − W)."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .arrays import LoadSet, resolve  # noqa: F401  (resolve: the Simulation's entry point)
from .stepping import WORK, work_of


def check_load_support(load_set: LoadSet | None, integrator, backend: str) -> None:
    """An InputError where the integrator or backend cannot run loads."""
    if load_set is None:
        return
    if not integrator.explicit:
        for i, load in enumerate(load_set.loads):
            if load.kind == "drive" and load_set.free[i].any():
                raise InputError(f"loads.{load_set.names[i]}.free: integrator {integrator.name!r} is implicit and "
                                 f"drives whole nodes; a drive free in some axes needs an explicit integrator")


class SimulationLoads:
    """The loads of a running Simulation, for its diagnostics rows (see the module docstring)."""

    def __init__(self, layout, load_set: LoadSet):
        self.set = load_set
        lay = layout
        self._internal = [lay.node_rank[idx] for idx in load_set.nodes]
        # a force's potential −f·Σ w x is outside the reported H: its work adds f·Σ w x − f(0)·Σ w x(0)
        self._weights = []
        for load, idx in zip(load_set.loads, load_set.nodes):
            m = load_set.masses[idx]
            total = load.kind == "force" and load.total
            self._weights.append(m / m.sum() if total else np.ones(len(idx)))
        self._start = [load_set.positions[idx].mean(axis=0) for idx in load_set.nodes]
        self._force_moment0 = [self._force_moment(i, load_set.positions[idx], 0.0)
                               for i, idx in enumerate(load_set.nodes)]

    def _force_moment(self, i: int, x_group: np.ndarray, t: float) -> float:
        if self.set.loads[i].kind != "force":
            return 0.0
        return float(self.set.value(i, t) @ (self._weights[i] @ x_group))

    def columns(self, sim, row: dict) -> dict:
        """The load columns of a diagnostics row of the current state."""
        state = sim.internal_state()
        work = work_of(state, len(self.set))
        out: dict = {}
        reactions = self._reactions(sim, state)
        total = 0.0
        for i, name in enumerate(self.set.names):
            x_group = state.positions[self._internal[i]]
            u = x_group.mean(axis=0) - self._start[i]
            w = float(work[i])
            if self.set.loads[i].kind == "force":
                w += self._force_moment(i, x_group, state.time) - self._force_moment0[i]
                f = self.set.value(i, state.time) * self._weights[i].sum()
                out.update({f"{name}_ux": u[0], f"{name}_uy": u[1], f"{name}_uz": u[2],
                            f"{name}_Fx": f[0], f"{name}_Fy": f[1], f"{name}_Fz": f[2]})
            else:
                r = reactions[i]
                out.update({f"{name}_ux": u[0], f"{name}_uy": u[1], f"{name}_uz": u[2],
                            f"{name}_Rx": r[0], f"{name}_Ry": r[1], f"{name}_Rz": r[2]})
            out[f"{name}_work"] = w
            total += w
        energy0 = sim.diagnostics.rows[0]["energy"] if sim.diagnostics.rows else row["energy"]
        out["work"] = total
        # H − H(0) − W, less the heat that came in when heat flows (its balance is in the row)
        out["energy_balance"] = row.get("energy_balance", row["energy"] - energy0) - total
        return {k: float(v) for k, v in out.items()}

    def _reactions(self, sim, state) -> list:
        """(3,) per drive: Σ over its nodes of the spring forces on them, at the state."""
        drives = self.set.drives
        out = [None] * len(self.set)
        if not drives:
            return out
        fields = sim.internal_spring_fields()
        s = fields.tension / fields.length
        x = state.positions
        for i in drives:
            nodes, springs, others = self._incidence(sim.layout, i)
            out[i] = (s[springs, None] * (x[others] - x[nodes])).sum(axis=0)
        return out

    def _incidence(self, lay, i: int) -> tuple:
        """(node, spring, other end) per incidence of drive i's nodes, each (k,): made once."""
        cache = self.__dict__.setdefault("_incidences", {})
        if i not in cache:
            nodes = self._internal[i]
            counts = lay.inc_ptr[nodes + 1] - lay.inc_ptr[nodes]
            at = np.concatenate([np.arange(lay.inc_ptr[a], lay.inc_ptr[a + 1]) for a in nodes])
            cache[i] = (np.repeat(nodes, counts), lay.inc_spring[at], lay.inc_other[at])
        return cache[i]

    def reset_work(self, state) -> None:
        state.extra[WORK] = np.zeros(len(self.set))


def hold_driven_axes(state, layout, load_set: LoadSet | None) -> None:
    """Put the momenta of the driven axes of ``state`` (internal numbering) at 0 and give it the
    loads' work counters (nothing without loads)."""
    if load_set is None:
        return
    for i, load in enumerate(load_set.loads):
        if load.kind == "drive":
            rows = layout.node_rank[load_set.nodes[i]]
            held = load_set.free[i] == 0.0
            state.momenta[np.ix_(rows, np.flatnonzero(held))] = 0.0
    work_of(state, len(load_set))
