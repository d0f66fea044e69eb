"""Rank 0 builds every process's part of a distributed Simulation and sends it: the other
processes never build, hold or receive the whole net.

Rank 0 builds the whole :class:`~thermonet.simulation.Simulation` (it writes the frames,
the checkpoints' manifests and rows with loads from it); the others wait. It then builds, for each other
process q, q's :class:`~thermonet.parallel.stepper.DistributedStepper` from the whole net (its
share, records, halo lists, conduction plan and part of the setup, loads, and its share of the
initial state and heat logs: :meth:`~thermonet.parallel.stepper.DistributedStepper.for_rank`)
and sends q the Simulation with that stepper, pickled with every whole-net array replaced by a
:class:`~thermonet.parallel.held.NotHeld` stand-in (the state's whole arrays by the empty arrays
the stepper leaves between reads) and the net by a :class:`~thermonet.parallel.held.RankNet`.
What cannot travel is named instead and found again on arrival: the Simulation itself (its runner
and guards refer to it), the communicator, the model, and the compiled passes (the receiving
process gets the same ones from its own disk cache). An error on rank 0 while building or
sending is raised on every process waiting for its part.

A process other than rank 0 thus holds, at its peak, what it holds from then on: its share plus
the halo, with the net its script passed (docs/parallel.md, "Memory").
"""

from __future__ import annotations

import gc
import io
import pickle
from contextlib import contextmanager

import numpy as np

from ..heat.logs import ENTRY_LOGS, PER_SPRING_LOGS
from .held import (HEAT_ARRAYS, HEAT_CACHES, LAYOUT_ARRAYS, LAYOUT_ORDERS, SYSTEM_ARRAYS, NotHeld, RankNet,
                   give_back_freed_memory)
from .stepper import _RELEASED_NODES, _RELEASED_SPRINGS, compiled_parts

#: message tags: rank 0's word ("built" or "error", then the pickled part with its buffers' sizes),
#: then the buffers' bytes
TAG_SIZE, TAG_BYTES = 41, 42


def _tell_error(comm, processes, exc: Exception) -> None:
    """Send rank 0's error to ``processes`` (each raises it), as itself where it pickles."""
    from ..errors import SimulationError

    for q in processes:
        try:
            comm.send(("error", exc), dest=q, tag=TAG_SIZE)
        except Exception:  # (an error that does not pickle: its message)
            comm.send(("error", SimulationError(f"{type(exc).__name__}: {exc}")), dest=q, tag=TAG_SIZE)


def _whole_arrays(sim) -> dict:
    """id -> (array, stand-in) of the whole-net arrays of ``sim`` (rank 0's, built whole): what
    no other process receives. The stand-in: ("held", what, length) or ("released", kind)."""
    found = {}

    def held(array, what, length=False):
        if isinstance(array, np.ndarray):
            found[id(array)] = (array, ("held", what, len(array) if length else None))

    net, system, layout = sim.net, sim.system, sim.layout
    for name in SYSTEM_ARRAYS:
        held(getattr(system, name), f"the system's {name}")
    P, uniform = system.kernel_parameters
    if not uniform:
        held(P, "the system's kernel parameters")
    for name in LAYOUT_ARRAYS:
        held(getattr(layout, name), f"the layout's {name}")
    for name in LAYOUT_ORDERS:
        held(getattr(layout, name), f"the layout's {name}", length=True)
    heat = system.heat
    if heat is not None:
        heat.fastest_rate()  # (cached: a run choosing its conduction cycle reads it on every process)
        for name in HEAT_ARRAYS:
            held(getattr(heat, name), f"the heat setup's {name}", length=True)
    if system.loads is not None:
        for name in ("fully_driven", "positions", "masses"):
            held(getattr(system.loads, name), f"the loads' {name}", length=True)
        arrays = sim.stepper.loads.arrays
        for name in ("node_force", "node_drive", "node_weight"):
            held(getattr(arrays, name), f"the loads' {name}", length=True)
    state = sim._state
    for name, kind in (("positions", "nodes"), ("momenta", "nodes"), ("thermal_displacement", "springs"),
                       ("entropy", "springs")):
        a = getattr(state, name)
        if isinstance(a, np.ndarray):
            found[id(a)] = (a, ("released", kind))
    logs = state.extra.get("heat") or {}
    for name in PER_SPRING_LOGS + ENTRY_LOGS:
        if name in logs:
            found[id(logs[name])] = (logs[name], ("released", "springs"))
    found[id(net)] = (net, ("net",))
    return found


class _Pickler(pickle.Pickler):
    def __init__(self, file, whole: dict, named: dict, buffers: list):
        # (protocol 5: the arrays' bytes go apart, sent as they are and received in place)
        super().__init__(file, protocol=5, buffer_callback=buffers.append)
        self._whole, self._named = whole, named

    def persistent_id(self, obj):
        key = self._named.get(id(obj))
        if key is not None:
            return key
        entry = self._whole.get(id(obj))
        if entry is None:
            return None
        return entry[1] if entry[1][0] != "net" else None

    def reducer_override(self, obj):
        entry = self._whole.get(id(obj))
        if entry is not None and entry[1][0] == "net":
            return _rank_net, (RankNet(obj).__dict__,)
        return NotImplemented


def _rank_net(fields: dict) -> RankNet:
    out = RankNet.__new__(RankNet)
    out.__dict__.update(fields)
    return out


class _Unpickler(pickle.Unpickler):
    def __init__(self, file, named: dict, buffers: list):
        super().__init__(file, buffers=buffers)
        self._named = named

    def persistent_load(self, key):
        if key[0] == "held":
            return NotHeld(key[1], key[2])
        if key[0] == "released":
            return _RELEASED_NODES if key[1] == "nodes" else _RELEASED_SPRINGS
        return self._named[key]


def _named_objects(sim, comm, model, parts) -> dict:
    """key -> object of what is named instead of pickled (see the module docstring): the
    Simulation itself (its runner and guards refer to it), the communicator, the model, the
    compiled passes."""
    named = {("sim",): sim, ("comm",): comm, ("model",): model}
    for i, fn in enumerate(parts):
        named[("compiled", i)] = fn
    return named


def _compiled_key(sim) -> tuple:
    """The arguments of :func:`~thermonet.parallel.stepper.compiled_parts` for ``sim``."""
    system = sim.system
    return (bool(sim.parallel), bool(system.thermal), bool(system.kernel_parameters[1]), system.loads is not None,
            bool(sim.integrator.heat_rows[0]))


@contextmanager
def errors_told_to_others(comm):
    """Rank 0 building its Simulation: an error raised inside is sent to every other process
    (waiting in :func:`receive_simulation`, each raises it too), then raised here."""
    try:
        yield
    except Exception as exc:
        _tell_error(comm, range(1, comm.Get_size()), exc)
        raise


def send_parts(sim, comm) -> None:
    """Rank 0, its whole Simulation ``sim`` built (its stepper distributed): every other
    process's part sent to it, then rank 0 keeps its own share."""
    from .stepper import threads_per_process

    key = _compiled_key(sim)
    for q in range(1, comm.Get_size()):
        comm.send(("built", key), dest=q, tag=TAG_SIZE)
    threads = threads_per_process(comm)  # (every process takes part)
    if sim.threads is None:  # the machine's cores shared among its processes, not each taking all
        sim.threads = threads
    send_simulation(sim, comm, key)
    sim.stepper.keep_share(sim._state)


def send_simulation(sim, comm, key) -> None:
    """Rank 0, its Simulation built: every other process's part sent to it (see the module
    docstring; each process calls :func:`receive_simulation` at the same time)."""
    stepper = sim.stepper
    whole = _whole_arrays(sim)
    named = {id(obj): k for k, obj in _named_objects(sim, comm, sim.model, compiled_parts(sim.model, *key)).items()}
    state = sim._state
    for q in range(1, comm.Get_size()):
        try:
            part = stepper.for_rank(q, state)
            file, buffers = io.BytesIO(), []
            heat = sim.system.heat
            caches = {k: heat.__dict__.pop(k) for k in HEAT_CACHES if heat is not None and k in heat.__dict__}
            try:  # (the heat setup's caches, whole-net arrays built on demand, stay here)
                _Pickler(file, whole, named, buffers).dump({**sim.__dict__, "stepper": part})
            finally:
                if caches:
                    heat.__dict__.update(caches)
        except Exception as exc:  # (the processes still waiting learn it and stop too)
            _tell_error(comm, range(q, comm.Get_size()), exc)
            raise
        views = [b.raw() for b in buffers]
        comm.send(("part", file.getvalue(), [v.nbytes for v in views]), dest=q, tag=TAG_SIZE)
        for v in views:
            comm.Send(v, dest=q, tag=TAG_BYTES)
        del part, file, buffers, views
        gc.collect()  # (a stepper and its conduction refer to each other: freed by the collector)
    give_back_freed_memory()


def receive_simulation(sim, comm, model, threads) -> None:
    """A process other than rank 0: its part of the Simulation rank 0 built (the attributes of
    ``sim``), or rank 0's error raised; model, threads: as the script named them (the same as rank
    0's; threads None: this process's share of its machine's cores)."""
    from ..models import get_model
    from .stepper import threads_per_process

    message = comm.recv(source=0, tag=TAG_SIZE)
    if message[0] == "error":
        raise message[1]
    key = message[1]
    here = threads_per_process(comm)  # (every process takes part)
    message = comm.recv(source=0, tag=TAG_SIZE)
    if message[0] == "error":
        raise message[1]
    _, stream, sizes = message
    buffers = [np.empty(n, dtype=np.uint8) for n in sizes]  # (the arrays are made on these, not copied)
    for b in buffers:
        comm.Recv(b, source=0, tag=TAG_BYTES)
    try:
        model = get_model(model)
        named = _named_objects(sim, comm, model, compiled_parts(model, *key))
        attributes = _Unpickler(io.BytesIO(stream), named, buffers).load()
    except Exception:  # (rank 0 goes on: a process that cannot take its part stops the job)
        import sys
        import traceback

        traceback.print_exc()
        print(f"thermonet: process {comm.Get_rank()} could not take its part of the net from rank 0; "
              f"stopping every process", file=sys.stderr, flush=True)
        comm.Abort(1)
    del stream, buffers
    sim.__dict__.update(attributes)
    if threads is None:  # (this machine's cores, not rank 0's)
        sim.threads = here


__all__ = ["errors_told_to_others", "send_parts", "send_simulation", "receive_simulation"]
