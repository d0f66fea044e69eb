"""One net over several processes: MPI domain decomposition through mpi4py (docs/parallel.md).

A :class:`~thermonet.simulation.Simulation` started by ``mpiexec -n P`` (or given ``comm=``)
partitions its nodes into P parts (:mod:`.partition`); each process owns one part and keeps the
springs that touch it, with one layer of ghost nodes (:mod:`.domain`); the explicit step runs the
CPU kernel's own passes over those and exchanges the ghosts' positions once per stage
(:mod:`.halo`, :mod:`.stepper`); heat conduction runs the kernel's conducting sequence
(:mod:`.conduction`) with each process sweeping its blocks of junctions and the border
temperatures exchanged between the sweep's phases (:mod:`.heat_share`, :mod:`.sweep`). Results
are bit for bit those of one process. Effects the distributed step does not carry are refused by
name (:mod:`.support`). mpi4py is optional: a run of one process never imports it (:mod:`.world`).
"""

from .world import world

__all__ = ["world"]
