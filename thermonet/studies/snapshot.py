"""The end state of a run as the studies compare it, and the paper's error measure."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

QUANTITIES = ("position", "momentum", "temperature")


@dataclass(frozen=True)
class Snapshot:
    """positions, momenta: (k, 3) of the k free nodes (user order); temperatures: (m,)."""

    positions: np.ndarray
    momenta: np.ndarray
    temperatures: np.ndarray

    @classmethod
    def of(cls, sim) -> "Snapshot":
        """The current state of a :class:`~thermonet.Simulation`."""
        state = sim.state
        free = ~np.asarray(sim.net.anchored, dtype=bool)
        return cls(state.positions[free], state.momenta[free], sim.temperatures())

    def field(self, quantity: str) -> np.ndarray:
        return {"position": self.positions, "momentum": self.momenta, "temperature": self.temperatures}[quantity]

    def errors(self, reference: "Snapshot") -> dict[str, float]:
        """The paper's §5.1.1 measure per quantity: the square root of the sum of the squared
        errors of every Cartesian component of every mass (positions, momenta) or of every
        spring's temperature."""
        return {q: float(np.sqrt(np.sum((self.field(q) - reference.field(q)) ** 2))) for q in QUANTITIES}

    def scales(self) -> dict[str, float]:
        """The size of each quantity (same norm), to judge an error against."""
        return {q: float(np.sqrt(np.sum(self.field(q) ** 2))) for q in QUANTITIES}

    def to_dict(self) -> dict:
        return {"positions": self.positions, "momenta": self.momenta, "temperatures": self.temperatures}
