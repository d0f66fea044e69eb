"""The CPU stepper of the explicit integrators: a :class:`~thermonet.explicit.splitting.Splitting`
bound to a system, holding the kernel's records and scratch buffers and calling the fused kernel
(:mod:`thermonet.explicit.cpu`) for whole chunks of steps. Its GPU twin is
:mod:`thermonet.explicit.cuda.stepper`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..blowup import blowup_failure
from ..diagnostics import row_sums, sums_of
from ..errors import InputError
from ..heat.logs import cycle_of, heat_logs
from ..integrators.base import Stepper
from ..kernels import records
from ..kernels.records import Run, StateArrays, no_heat_cpu
from ..kernels.specialize import kernel_parameters
from ..loads.elements import NO_LOADS
from ..loads.stepping import StepperLoads
from .cpu import splitting_kernels
from .schedule import flow_data

if TYPE_CHECKING:
    from .splitting import Splitting


_NO_HEAT = no_heat_cpu()


class SplittingStepper(Stepper):
    """A :class:`~thermonet.explicit.splitting.Splitting` bound to a system: owns the scratch
    buffers, calls the fused kernel."""

    def __init__(self, integrator: Splitting, system, parallel: bool = False):
        self.integrator = integrator
        self.system = system
        self.parallel = bool(parallel)
        P, uniform = kernel_parameters(system.parameters)
        flows = integrator.subflows
        conduction, waves = integrator.heat_rows
        heat = getattr(system, "heat", None)
        if (conduction or waves) and heat is None:
            raise InputError(f"{integrator.name} has heat-flow rows but the system has no heat flow set up")
        self._heat = heat
        self._conduction = conduction
        self._table = integrator.table_between_sweeps
        self.loads = StepperLoads.of(system, self._table)
        self._uniform = uniform
        self._advance = splitting_kernels(system.model, parallel, system.thermal, uniform, flows, conduction, waves,
                                          self.loads is not None)
        n, m = system.n_nodes, system.n_springs
        self._scratch = records.scratch(n, m, system.thermal)
        self._measured = None  # (state, step, sums) of the last call asked to measure its end
        # (state, step) whose forces and temperatures the last call's closing kick left in the
        # keep buffers: a call continuing from exactly there starts from them
        self._boundary = None
        self._no_thermal = np.empty(0)
        self._topology = records.topology(system.layout)
        self._springs = records.Springs(system.rest_lengths, P)
        self._nodes = records.nodes(system)
        self._effects = flow_data(flows, system)

    #: advance(..., measure=True) can reduce the end state's diagnostics sums on the way
    measures = True

    def advance(self, state, n_steps: int, h: float, measure: bool = False):
        """``n_steps`` steps of h from ``state`` (in place). With ``measure`` the closing kick
        also reduces the end state's diagnostics sums: :meth:`closing_sums` returns them."""
        self._measured = None
        if n_steps <= 0:
            return None
        thermal = self.system.thermal
        arrays = StateArrays(state.positions, state.momenta,
                             state.thermal_displacement if thermal else self._no_thermal,
                             state.entropy if thermal else self._no_thermal)
        lo, hi = self.system.stretch_bounds
        reuse = self._boundary is not None and self._boundary[0] is state and self._boundary[1] == state.step
        self._boundary = None
        every, cycle_step, sweeps = cycle_of(state, self._heat) if self._conduction else (1, 0, 1)
        run = Run(float(h), float(state.time), int(n_steps), bool(self.integrator.track_phi), float(lo), float(hi),
                  bool(reuse), bool(measure), every, cycle_step)
        loads = self.loads.arrays_for(state, h) if self.loads is not None else NO_LOADS  # loads
        done, detected, summed = self._advance(arrays, self._scratch, self._topology, self._springs, self._nodes,
                                               self._table, self._effects, self._heat_record(state, h, every, sweeps),
                                               run, loads)
        if not detected and self._table.carry != 0.0:
            self._boundary = (state, state.step + int(n_steps))
        if summed:
            self._measured = (state, state.step + int(n_steps), self._scratch.sums.copy())
        if detected:
            raise blowup_failure(self.system, state.positions, state.entropy, done)
        return None

    def _heat_record(self, state, h: float, every: int, sweeps: int):
        """The kernels' Heat record: conduction factors for the half sweeps of this h and a
        cycle of ``every`` steps with ``sweeps`` sub-sweeps (τ = k h / (2 j)), logs in the state."""
        if self._heat is None:
            return _NO_HEAT
        return self._heat.record(0.5 * every * h / sweeps, heat_logs(state, self._heat), sweeps=sweeps)

    def closing_sums(self, state) -> dict | None:
        """See :meth:`Stepper.closing_sums`: Σ U from the springs' energies the closing kick left
        (scratch.energy_buf) and its θ range, Σ η in a pass, the node sums the closing kick
        reduced (scratch.node_accs), all exactly rounded (:func:`thermonet.diagnostics.row_sums`)."""
        if self._measured is None:
            return None
        kept, step, sums = self._measured
        if kept is not state or step != state.step:
            return None
        system = self.system
        eta = state.entropy if system.thermal else self._no_thermal
        acc, tmin, tmax = row_sums(system, state.positions, state.momenta, eta, self._topology.edges, self._springs,
                                   self._nodes, self._uniform, parallel=self.parallel,
                                   closing=(self._scratch.energy_buf, sums[0], sums[1], self._scratch.node_accs))
        return sums_of(acc, tmin, tmax, system.thermal)
