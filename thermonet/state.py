"""The evolving state of a run: positions, momenta, thermal displacements, entropies, time, step.

In the engine's internal numbering inside a :class:`~thermonet.simulation.Simulation`
(``Simulation.internal_state``), in the user's numbering where a Simulation hands it out
(``Simulation.state``) or takes it in (``Simulation.load_state``, checkpoints).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(eq=False)
class State:
    """The integrator state after ``step`` steps, at time ``time``.

    positions, momenta: (n, 3) float64. thermal_displacement Φ, entropy η: (m,) float64
    (η is constant in time for every integrator here, but it is state, not a parameter);
    both None in a purely mechanical run (thermal coupling off).
    """

    positions: np.ndarray
    momenta: np.ndarray
    thermal_displacement: np.ndarray | None
    entropy: np.ndarray | None
    time: float = 0.0
    step: int = 0
    extra: dict = field(default_factory=dict)

    def __repr__(self) -> str:
        springs = "" if self.entropy is None else f", {len(self.entropy)} springs (η, Φ)"
        return f"<State step {self.step}, t = {self.time:.6g}: {len(self.positions)} nodes (x, p){springs}>"

    def copy(self) -> "State":
        return State(
            self.positions.copy(),
            self.momenta.copy(),
            None if self.thermal_displacement is None else self.thermal_displacement.copy(),
            None if self.entropy is None else self.entropy.copy(),
            self.time,
            self.step,
            {k: _copied(v) for k, v in self.extra.items()},
        )


def _copied(value):
    """A copy of an ``extra`` entry: arrays and dicts of arrays (the heat-flow logs) copied."""
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, dict):
        return {k: _copied(v) for k, v in value.items()}
    return value


def copy_extra(source: dict, target: dict) -> None:
    """Copy the arrays of a state's ``extra`` (the heat-flow logs, the loads' work) into another's,
    in place where it has them (a stepper may hold those arrays)."""
    for k, v in source.items():
        if isinstance(v, dict):
            copy_extra(v, target.setdefault(k, {}))
        elif isinstance(v, np.ndarray):
            t = target.get(k)
            if isinstance(t, np.ndarray) and t.shape == v.shape:
                np.copyto(t, v)
            else:
                target[k] = v.copy()
