"""Memory of each process of a conducting net run over MPI processes, against one process.

    python benchmarks/mpi_memory.py [--springs 1e6]                       # one process
    NUMBA_NUM_THREADS=1 mpiexec -n 2 python benchmarks/mpi_memory.py      # each of two
    python benchmarks/mpi_memory.py --quick                               # a tiny net (a smoke run)

Over several processes the script builds the net on rank 0 only and passes None elsewhere (rank 0
alone builds the Simulation and sends each process its part); ``--net-everywhere`` builds it on
every process, as a script written for one process does.

A 6-neighbour lattice of about ``--springs`` springs (jitter 0.1) with conduction (g = 4, every 2
steps) and a bath on one face, 4 steps; each process prints its resident memory after building
the Simulation, after the steps and its peak until then (rank 0's and one process's: building
the whole Simulation; the others': their share), the bytes
of the whole state with its heat logs (as ``internal_state()`` puts it together, after the
measurements) and, over several processes, those of its share's arrays (the stepping state and
buffers, the incidence lists, the conduction sweep's arrays: the share plus the halo). What each
process holds whole and what per share: docs/parallel.md, "Memory".
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np


def resident_mb() -> float:
    """This process's resident memory now (Linux), MB."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def share_bytes(stepper) -> int:
    """Bytes of the arrays a distributed stepper holds for its share only."""
    sh, conduction = stepper.share, stepper._conduction
    arrays = [stepper._x, stepper._p, stepper._phi, stepper._eta, *stepper._scratch, *sh.topology]
    if conduction is not None:
        sweep = conduction._sweep
        arrays += [conduction._length, conduction._s_before, conduction._theta_log, sweep.theta, sweep.theta_start,
                   sweep.produced, *sweep.pending.values(), sweep.part.inc_ptr, sweep.part.inc_spring,
                   sweep._capacity, sweep._inv_capacity, sweep._conductance]
    return sum(a.nbytes for a in arrays)


def main(argv=None) -> None:
    import thermonet as tn
    from thermonet.heat import Bath

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--springs", type=float, default=1e6)
    parser.add_argument("--quick", action="store_true", help="a lattice of about 600 springs (a smoke run)")
    parser.add_argument("--net-everywhere", action="store_true",
                        help="build the net on every process (default: on rank 0 only)")
    args = parser.parse_args(argv)
    if args.quick:
        args.springs = 600
    k = max(1, int(round((args.springs / 3.0) ** (1.0 / 3.0))))
    from thermonet.parallel.world import launched_by_mpi

    rank = 0
    if launched_by_mpi():
        from mpi4py import MPI

        rank = MPI.COMM_WORLD.Get_rank()
    net = None
    if rank == 0 or args.net_everywhere:
        net = tn.lattice((k, k, k), jitter=0.1, seed=1)
        net.node_groups["hot"] = np.arange(k * k)
    start = time.perf_counter()
    sim = tn.Simulation(net, parameters=dict(c=100.0, beta=0.002, C0=1.0, theta0=300.0, g=4.0), h=0.01, threads=1,
                        parallel=False, conduction=True, conduction_every=2, stability_guard="off",
                        energy_tolerance=None, baths={"hot": Bath("hot", 900.0)})
    del net  # (the Simulation's own: on processes other than rank 0 only its size and groups)
    built, after_build = time.perf_counter() - start, resident_mb()
    sim.run(steps=4, diagnostics_every=4)
    after_steps = resident_mb()  # (before reading the state: over processes, a read puts it together)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    state = sim.internal_state()
    whole = sum(a.nbytes for a in (state.positions, state.momenta, state.thermal_displacement, state.entropy))
    whole += sum(v.nbytes for v in state.extra["heat"].values())
    line = (f"process {rank}: {sim.net.n_springs} springs, {sim.net.n_nodes} nodes; whole state and heat logs "
            f"{whole / 2**20:.1f} MB; resident after building {after_build:.0f} MB (built in {built:.1f} s), after 4 "
            f"steps {after_steps:.0f} MB, peak {peak:.0f} MB")
    if sim.comm is not None:
        sh = sim.stepper.share
        line += (f"; share: {len(sh.nodes)} nodes ({sh.ghosts} ghosts), {len(sh.springs)} springs, arrays "
                 f"{share_bytes(sim.stepper) / 2**20:.1f} MB")
    lines = [line] if sim.comm is None else sim.comm.gather(line, root=0)  # printed in rank order by rank 0
    if rank == 0:
        print("\n".join(lines), flush=True)


if __name__ == "__main__":
    main()
