"""What a process other than rank 0 keeps of the whole net once its share is built.

Every process builds the same :class:`~thermonet.simulation.Simulation` from the whole net; once
its stepper holds its share (:mod:`.stepper`), a process other than rank 0 lets go of the whole
net's arrays that only rank 0 reads from then on (it measures the diagnostics rows, writes the
frames and checkpoints, runs the guards, reads ``sim.state`` for every process and loads states:
``Simulation.on_root``): the net's arrays, the system's per-spring parameters, rest lengths and
masses, the layout's orders, spring ends and incidence lists, the heat setup's per-spring and
per-entry arrays, the loads' per-node arrays, the decomposition, and the whole x, p, Φ, η and
heat logs. A read of one of them there fails with a :class:`NotHeldError` naming it.

The share's heat logs and its part of the conduction setup are the distributed sweep's
(:mod:`.sweep`, :mod:`.conduction`); what stays whole on every process is the net's size, its
groups and the baths' and sources' names and time functions.
"""

from __future__ import annotations

import ctypes
import ctypes.util

from ..errors import SimulationError


class NotHeldError(SimulationError):
    """A process of a distributed run read a whole-net array that only rank 0 holds."""


class NotHeld:
    """Stands in for a whole-net array a process let go of: any use of it raises a
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


#: the System's and Layout's whole-net arrays a process other than rank 0 lets go of
SYSTEM_ARRAYS = ("rest_lengths", "parameters", "masses", "inv_mass", "anchored")
LAYOUT_ARRAYS = ("edges", "inc_other", "inc_ptr", "inc_spring")
#: the HeatSetup's whole-net arrays (the distributed sweep keeps its part of them) and caches
HEAT_ARRAYS = ("capacity", "conductance", "wave_conductance", "bath_nodes", "entry_spring", "entry_kind", "entry_fn",
               "entry_rate")
HEAT_CACHES = ("_orders", "_factors", "_static", "_incidence", "_last_record", "_work_arrays")
LAYOUT_ORDERS = ("node_order", "node_rank", "spring_order", "spring_rank")


def let_go(sim) -> None:
    """Every process of a distributed ``sim`` (its stepper built, its state made), together: the
    stepper keeps its share of the state; then a process other than rank 0 replaces the whole-net
    arrays only rank 0 reads by :class:`NotHeld` (module doc) and gives the freed memory back to
    the system."""
    stepper = sim.stepper
    stepper.keep_share(sim._state)
    if stepper.rank == 0:
        return
    system, layout = sim.system, sim.layout
    for name in SYSTEM_ARRAYS:
        object.__setattr__(system, name, NotHeld(f"the system's {name}"))
    system.__dict__.pop("_kernel_parameters", None)  # (its cached parameters)
    heat = system.heat
    if heat is not None:
        heat.fastest_rate()  # (cached: a run choosing its conduction cycle reads it on every process)
        for name in HEAT_ARRAYS:
            object.__setattr__(heat, name, NotHeld(f"the heat setup's {name}", len(getattr(heat, name))))
        for name in HEAT_CACHES:
            heat.__dict__.pop(name, None)
    for name in LAYOUT_ARRAYS:
        object.__setattr__(layout, name, NotHeld(f"the layout's {name}"))
    for name in LAYOUT_ORDERS:  # (their lengths are the net's counts, which every process keeps)
        object.__setattr__(layout, name, NotHeld(f"the layout's {name}", len(getattr(layout, name))))
    if system.loads is not None:  # (the share's load arrays are cut from these)
        for name in ("fully_driven", "positions", "masses"):
            object.__setattr__(system.loads, name, NotHeld(f"the loads' {name}", len(getattr(system.loads, name))))
        stepper._loads.let_go()
    sim.net = RankNet(sim.net)
    stepper.decomposition = None
    give_back_freed_memory()


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


__all__ = ["NotHeld", "NotHeldError", "RankNet", "let_go", "give_back_freed_memory"]
