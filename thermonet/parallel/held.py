"""What a process other than rank 0 holds of the whole net: stand-ins that name what it is not.

Rank 0 alone builds the whole :class:`~thermonet.simulation.Simulation`; every other process
receives its own part of it (:mod:`.ship`), in which each whole-net array is a :class:`NotHeld`
stand-in (the net's arrays, the system's per-spring parameters, rest lengths and masses, the
layout's orders, spring ends and incidence lists, the heat setup's per-spring and per-entry
arrays, the loads' per-node arrays) and the net a :class:`RankNet` (its size and groups). Work
that reads them runs on rank 0 (``Simulation.on_root``: the diagnostics rows with loads, frames,
checkpoints' manifests, guards, reads of ``sim.state`` for every process, loaded states); a read of one
elsewhere fails with a :class:`NotHeldError` naming it. The lists of those arrays are here.
"""

from __future__ import annotations

import ctypes
import ctypes.util

from ..errors import SimulationError


class NotHeldError(SimulationError):
    """A process of a distributed run read a whole-net array that only rank 0 holds."""


class NotHeld:
    """Stands in for a whole-net array a process does not hold: any use of it raises a
    :class:`NotHeldError` naming it (what: e.g. "the net's positions")."""

    def __init__(self, what: str, length: int | None = None):
        self._what, self._length = what, length

    def __len__(self) -> int:
        """The array's length where it is known (a size every process keeps)."""
        if self._length is None:
            self._refuse()
        return self._length

    def _refuse(self, *args, **kwargs):
        raise NotHeldError(f"{self._what}: over MPI processes only rank 0 holds the whole net; read it there "
                           f"(sim.comm.Get_rank() == 0), or read sim.state, which every process reads together")

    __array__ = __getitem__ = __setitem__ = __iter__ = __float__ = _refuse

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        self._refuse()

    def __repr__(self) -> str:
        return f"<not held here: {self._what}>"


class RankNet:
    """What a process other than rank 0 keeps of the :class:`~thermonet.net.Net`: its size, its
    groups and where it came from; its arrays are :class:`NotHeld`."""

    def __init__(self, net):
        self.n_nodes, self.n_springs = net.n_nodes, net.n_springs
        self.node_groups, self.spring_groups = net.node_groups, net.spring_groups
        self.source, self.cell_dimension = net.source, net.cell_dimension
        for name in ("positions", "edges", "masses", "anchored", "rest_lengths", "point_ids", "spring_volumes"):
            setattr(self, name, NotHeld(f"the net's {name}"))

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        NotHeld(f"the net's {name}")._refuse()


#: the System's and Layout's whole-net arrays a process other than rank 0 receives as stand-ins
SYSTEM_ARRAYS = ("rest_lengths", "parameters", "masses", "inv_mass", "anchored")
LAYOUT_ARRAYS = ("edges", "inc_other", "inc_ptr", "inc_spring")
#: the HeatSetup's whole-net arrays (the distributed sweep keeps its part of them) and caches
HEAT_ARRAYS = ("capacity", "conductance", "wave_conductance", "bath_nodes", "entry_spring", "entry_kind", "entry_fn",
               "entry_rate")
HEAT_CACHES = ("_orders", "_factors", "_static", "_incidence", "_last_record", "_work_arrays")
LAYOUT_ORDERS = ("node_order", "node_rank", "spring_order", "spring_rank")


def give_back_freed_memory() -> None:
    """Return the C heap's free pages to the system (glibc's ``malloc_trim``): arrays freed
    inside the heap otherwise stay in the process's resident memory. Nothing elsewhere."""
    name = ctypes.util.find_library("c")
    try:
        trim = ctypes.CDLL(name).malloc_trim if name else None
    except (OSError, AttributeError):
        trim = None
    if trim is not None:
        trim(0)


__all__ = ["NotHeld", "NotHeldError", "RankNet", "give_back_freed_memory"]
