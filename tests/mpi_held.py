"""What the MPI test scripts (tests/mpi_*.py, run under ``mpiexec``) check a process holds."""

from contextlib import contextmanager
from dataclasses import fields, is_dataclass

import numpy as np


def whole_sized(root, sizes: set) -> list:
    """The paths from ``root`` (through thermonet's objects, dicts, lists, tuples and dataclass
    fields) to NumPy arrays with a length in ``sizes``; but for the net's groups (the index lists
    the user named, which every process keeps)."""
    found, seen = [], set()

    def walk(value, path):
        if id(value) in seen:
            return
        seen.add(id(value))
        if isinstance(value, np.ndarray):
            if value.ndim and value.shape[0] in sizes:
                found.append(f"{path} {value.shape}")
        elif isinstance(value, dict):
            for k, v in value.items():
                if not path.endswith("_groups"):
                    walk(v, f"{path}[{k!r}]")
        elif isinstance(value, (list, tuple)):
            for i, v in enumerate(value):
                walk(v, f"{path}[{i}]")
        elif type(value).__module__.startswith("thermonet"):
            names = [f.name for f in fields(value)] if is_dataclass(value) else []
            for k in dict.fromkeys(names + list(getattr(value, "__dict__", {}))):
                walk(object.__getattribute__(value, k), f"{path}.{k}")

    walk(root, "sim")
    return found


def whole_net_arrays(sim) -> list:
    """On a process other than rank 0 of a distributed ``sim``: the paths to arrays of the whole
    net's length (n, n + 1, 3n, m or 2m: nodes, incidence pointers, springs, incidences) it
    holds; on rank 0 (which holds the whole net) none."""
    if sim.comm.Get_rank() == 0:
        return []
    n, m = sim.net.n_nodes, sim.net.n_springs
    return whole_sized(sim, {n, n + 1, 3 * n, m, 2 * m})


@contextmanager
def builds_nothing_whole_here():
    """Within: on a process other than rank 0, the builders of the whole net's layout, system,
    heat setup and initial state fail if called (only rank 0 builds them)."""
    from mpi4py import MPI

    import thermonet.simulation as simulation

    names = ("build_layout", "build_system", "build_heat", "initial_state")
    saved = {name: getattr(simulation, name) for name in names}

    def refuse(*args, **kwargs):
        raise AssertionError("a process other than rank 0 built a whole-net structure")

    if MPI.COMM_WORLD.Get_rank() > 0:
        for name in names:
            setattr(simulation, name, refuse)
    try:
        yield
    finally:
        for name, fn in saved.items():
            setattr(simulation, name, fn)
