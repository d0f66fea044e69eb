"""Run by tests/test_mpi.py under ``mpiexec``: ``thermonet ARGS`` killed on the last process once
it reaches step K (``MPI_Abort``, as a failing node or a job's time limit stops a job: every
process ends at once, with no checkpoint or flush at the stop).

    mpiexec -n P python tests/mpi_killed.py K ARGS
"""

import sys

from mpi4py import MPI

from thermonet.cli.main import main
from thermonet.io import series

K = int(sys.argv[1])
world = MPI.COMM_WORLD
write_csv = series.RunOutput._maybe_write_csv


def killed(self, sim):  # (an observer at the diagnostics cadence)
    if sim.step >= K and world.Get_rank() == world.Get_size() - 1:
        world.Abort(9)
    write_csv(self, sim)


series.RunOutput._maybe_write_csv = killed
main(sys.argv[2:])
