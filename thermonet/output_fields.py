"""A simulation's output fields written straight into the caller's arrays, in the user's numbering.

One pass over the nodes (:mod:`thermonet.kernels.gather`: positions, displacement, velocity,
momentum) and one over the springs (:func:`thermonet.kernels.springs.frame_spring_kernel`:
temperature, tension, strain computed and scattered, entropy and Φ copied), threaded where the
stepping kernels are; ``node_temperature`` (the mean temperature of the springs meeting at a
node; with conduction the junction temperature Σ g θ / Σ g) is a sum in incidence order; with
conduction ``heat_rate`` is each spring's net heat inflow (:mod:`thermonet.heat.fields`). Values equal the public accessors' bit for bit (``sim.state``,
``sim.temperatures()``, ``sim.strains()``, ...). Output writers (:mod:`thermonet.io`) hand in the
arrays of a frame image and never see the internal numbering.
"""

from __future__ import annotations

import numpy as np

from .heat.fields import heat_rate, junction_temperature
from .kernels.gather import as_index, passes
from .kernels.records import Springs
from .kernels.springs import FrameFields, frame_spring_kernel

#: spring fields, in the order the frame spring pass takes their targets
SPRING_FIELDS = FrameFields._fields  # ("temperature", "tension", "strain", "entropy", "thermal_displacement")
#: spring fields of heat flow, computed from the temperatures (thermonet.heat.fields)
HEAT_SPRING_FIELDS = ("heat_rate",)
#: node fields the node pass writes (positions always)
NODE_FIELDS = ("displacement", "velocity", "momentum")


class OutputFields:
    """Writes the fields of ``sim`` into fixed target arrays, user numbering, at each :meth:`write`.

    points: (n, 3) target of the positions; point: name -> (n, 3) or (n,) target of node fields
    (``displacement``, ``velocity``, ``momentum``, ``node_temperature``); cell: name -> (m,)
    target of spring fields (:data:`SPRING_FIELDS`). Unknown names are an error.
    """

    def __init__(self, sim, points: np.ndarray, point: dict, cell: dict):
        unknown = [n for n in point if n not in (*NODE_FIELDS, "node_temperature")] + [
            n for n in cell if n not in SPRING_FIELDS + HEAT_SPRING_FIELDS]
        if unknown:
            raise ValueError(f"no such output field: {unknown[0]!r}")
        self.sim, self.points, self.point, self.cell = sim, points, dict(point), dict(cell)
        lay = sim.layout
        self._node_order, self._spring_order = as_index(lay.node_order), as_index(lay.spring_order)
        self._passes = passes(sim.parallel)
        self._none = np.empty(0)
        self._no_rows = np.empty((0, 3))
        m = sim.net.n_springs
        if "heat_rate" in cell and (sim.system.heat is None or not sim.system.heat.conduction):
            raise ValueError("output field 'heat_rate' needs conduction")
        self._with_springs = bool(self.cell) or "node_temperature" in self.point
        if self._with_springs:
            system = sim.system
            self._spring_pass = frame_spring_kernel(system.model, system.thermal, sim.parallel)
            self._edges = system.edges.view(np.uint32)
            self._scratch = np.empty((4, m))
        self._theta_internal = np.empty(m if "node_temperature" in self.point or "heat_rate" in cell else 0)

    def write(self) -> None:
        """Write the simulation's fields now into the targets."""
        sim, point, cell = self.sim, self.point, self.cell
        net, lay = sim.net, sim.layout
        state = sim.internal_state()
        k = self._passes
        k.node_fields_to_user(self.points, point.get("displacement", self._no_rows), point.get("velocity", self._no_rows),
                              point.get("momentum", self._no_rows), state.positions, state.momenta, net.positions,
                              net.masses, self._node_order)
        if self._with_springs:
            system = sim.system
            none = self._none
            eta = state.entropy if system.thermal else none
            phi = state.thermal_displacement if system.thermal else none
            springs = Springs(system.rest_lengths, system.parameters)
            fields = FrameFields(**{name: cell.get(name, none) for name in SPRING_FIELDS})
            self._spring_pass(state.positions, eta, phi, springs, self._edges, self._spring_order, self._scratch, fields,
                              self._theta_internal)
        heat = sim.system.heat
        if heat is not None and heat.conduction and ("node_temperature" in point or "heat_rate" in cell):
            self._write_heat_fields(heat, state.time)
        elif "node_temperature" in point:
            k.node_means_to_user(point["node_temperature"], self._theta_internal, lay.inc_ptr, lay.inc_spring,
                                 self._node_order)

    def _write_heat_fields(self, heat, t: float) -> None:
        """node_temperature as junction temperatures, heat_rate per spring (user numbering)."""
        lay = self.sim.layout
        if "node_temperature" in self.point:
            self.point["node_temperature"][lay.node_order] = junction_temperature(heat, lay, self._theta_internal, t)
        if "heat_rate" in self.cell:
            self.cell["heat_rate"][lay.spring_order] = heat_rate(heat, self._theta_internal, t)
