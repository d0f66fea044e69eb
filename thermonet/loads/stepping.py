"""A stepper's side of the loads: the kernels' :class:`~thermonet.loads.arrays.LoadArrays` for
one system and stage table, and per call the clock and the state's work accumulators."""

from __future__ import annotations

import numpy as np

from .arrays import LoadArrays, kernel_arrays

#: the key of a state's ``extra`` that holds the loads' work accumulators (L,)
WORK = "load_work"


class StepperLoads:
    """The loads of one stepper. ``time_origin() -> (step, time)``: where the run's clock starts
    (the Simulation points it at its own; a stage's time is origin + (steps since it) h, so it does
    not depend on how a run is cut into calls)."""

    def __init__(self, arrays: LoadArrays):
        self.arrays = arrays
        self.time_origin = lambda: (0, 0.0)

    @classmethod
    def of(cls, system, table) -> "StepperLoads | None":
        load_set = getattr(system, "loads", None)
        if load_set is None:
            return None
        return cls(kernel_arrays(load_set, system.layout, table))

    def arrays_for(self, state, h: float) -> LoadArrays:
        """The record of a call from ``state``: its work accumulators and the clock."""
        work = work_of(state, len(self.arrays.work))
        step0, t0 = self.time_origin()
        clock = self.arrays.clock
        clock[0] = float(t0)
        clock[1] = float(state.step - step0)
        return self.arrays._replace(work=work)

    @property
    def reaction(self) -> np.ndarray:
        """(L, 3) the reactions of the drives at the last kick of the last call."""
        return self.arrays.reaction


def work_of(state, n_loads: int) -> np.ndarray:
    """The state's work accumulators (L,), created (zero) on first use."""
    work = state.extra.get(WORK)
    if work is None or len(work) != n_loads:
        work = state.extra[WORK] = np.zeros(n_loads)
    return work
