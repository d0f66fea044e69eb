"""What a stepper works on that does not change: the :class:`System` (the evolving state is
:class:`~thermonet.state.State`).

Both are in the engine's internal numbering (see :mod:`thermonet.layout`); the
:class:`~thermonet.simulation.Simulation` maps them to and from the user's numbering.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kernels.specialize import kernel_parameters
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
    heat: the :class:`~thermonet.heat.setup.HeatSetup` (conduction, thermal waves, baths,
        sources), or None when heat does not flow (the paper's adiabatic nets).
    loads: the driven groups and forces (:class:`~thermonet.loads.arrays.LoadSet`), or None;
        nodes driven in every axis are among the ``anchored`` ones.
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
    heat: object = None
    loads: object = None  # loads

    def __repr__(self) -> str:
        return (f"<System {self.n_nodes} nodes, {self.n_springs} springs, model {self.model.name}, "
                f"thermal {'on' if self.thermal else 'off'}, gravity {'off' if self.gravity is None else list(self.gravity)}>")

    @property
    def edges(self) -> np.ndarray:
        return self.layout.edges

    @property
    def kernel_parameters(self) -> tuple[np.ndarray, bool]:
        """(P, uniform): the parameters as the kernels read them, a shared (k, 1) column when
        every spring has the same ones (see :func:`thermonet.kernels.specialize.kernel_parameters`);
        computed once."""
        cached = self.__dict__.get("_kernel_parameters")
        if cached is None:
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


from .state import State  # noqa: E402,F401  (importable from here as well)
