"""Which communicator a run uses, without importing mpi4py in a run of one process.

Importing ``mpi4py.MPI`` initializes MPI, which costs time and, outside ``mpiexec``, is of no
use: it is imported only where the environment shows an MPI launcher (or a communicator is
given), so the package runs where mpi4py is not installed.
"""

from __future__ import annotations

import os

from ..errors import InputError

#: environment variables set by MPI launchers (MPICH/Hydra, Open MPI, PMIx, Slurm's PMI)
LAUNCHER_VARIABLES = ("PMI_SIZE", "PMI_RANK", "OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "MPI_LOCALNRANKS")


def launched_by_mpi() -> bool:
    """Whether this process was started by an MPI launcher (``mpiexec``, ``mpirun``, ``srun``)."""
    return any(v in os.environ for v in LAUNCHER_VARIABLES)


def world(comm=None):
    """The communicator a Simulation is distributed over, or None for one process.

    comm: an mpi4py communicator (used as given when it has more than one process), or None:
    ``MPI.COMM_WORLD`` when this process was started by an MPI launcher with more than one
    process. A communicator of one process is None: the ordinary run.
    """
    if comm is None:
        if not launched_by_mpi():
            return None
        try:
            from mpi4py import MPI
        except ImportError:
            raise InputError("this process was started by an MPI launcher but mpi4py is not installed: "
                             "pip install 'thermonet[mpi]' (or run without mpiexec)") from None
        comm = MPI.COMM_WORLD
    if not hasattr(comm, "Get_size"):
        raise InputError(f"comm must be an mpi4py communicator, got {type(comm).__name__}")
    return comm if comm.Get_size() > 1 else None


def is_root(comm) -> bool:
    """Whether this process writes the run's shared files (rank 0, or no communicator)."""
    return comm is None or comm.Get_rank() == 0


def on_root(comm, fn, *args):
    """``fn(*args)`` run by rank 0 only (a folder prepared, a name chosen), its result or its
    error on every process: no process waits for a root that failed."""
    if comm is None:
        return fn(*args)
    result = error = None
    if comm.Get_rank() == 0:
        try:
            result = fn(*args)
        except Exception as exc:  # sent to the others, raised everywhere
            error = exc
    result, error = comm.bcast((result, error), root=0)
    if error is not None:
        raise error
    return result
