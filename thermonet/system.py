"""What a stepper works on: the fixed :class:`System` and the evolving :class:`State`.

Both are in the engine's internal numbering (see :mod:`thermonet.layout`); the
:class:`~thermonet.simulation.Simulation` maps them to and from the user's numbering.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .layout import Layout
from .models.base import Model


@dataclass(frozen=True, eq=False)
class System:
    """Everything that does not change during a run, in internal numbering.

    model: the constitutive law.
    layout: numbering and incidence (edges (m, 2) int32, CSR node→spring lists).
    rest_lengths: (m,) l0.
    parameters: (k, m) per-spring model parameters in ``model.parameters`` order.
    masses: (n,) node masses; inv_mass: (n,) 1/m on free nodes, 0 on anchored ones.
    anchored: (n,) bool.
    reference_point: (3,) point about which angular momentum is measured.
    gravity: (3,) uniform acceleration, or None when the scene has no external field.
    thermal: False for a purely mechanical run (every spring held at its reference temperature;
        no entropies or thermal displacements exist).
    stretch_bounds: (lo, hi) admissible stretches l/l0; the explicit kernel stops a run outside.
    """

    model: Model
    layout: Layout
    rest_lengths: np.ndarray
    parameters: np.ndarray
    masses: np.ndarray
    inv_mass: np.ndarray
    anchored: np.ndarray
    reference_point: np.ndarray
    gravity: np.ndarray | None = None
    thermal: bool = True
    stretch_bounds: tuple[float, float] = (1e-4, 1e4)

    def __repr__(self) -> str:
        return (f"<System {self.n_nodes} nodes, {self.n_springs} springs, model {self.model.name}, "
                f"thermal {'on' if self.thermal else 'off'}, gravity {'off' if self.gravity is None else list(self.gravity)}>")

    @property
    def edges(self) -> np.ndarray:
        return self.layout.edges

    @property
    def kernel_parameters(self) -> tuple[np.ndarray, bool]:
        """(P, uniform): the parameters as the kernels read them, a shared (k, 1) column when
        every spring has the same ones (see :func:`thermonet.kernels.splitting.kernel_parameters`);
        computed once."""
        cached = self.__dict__.get("_kernel_parameters")
        if cached is None:
            from .kernels.splitting import kernel_parameters

            cached = kernel_parameters(self.parameters)
            object.__setattr__(self, "_kernel_parameters", cached)
        return cached

    @property
    def n_nodes(self) -> int:
        return self.layout.n_nodes

    @property
    def n_springs(self) -> int:
        return self.layout.n_springs

    @property
    def free(self) -> np.ndarray:
        return ~self.anchored


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
            {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in self.extra.items()},
        )
