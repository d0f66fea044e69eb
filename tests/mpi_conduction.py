"""Run by tests/test_mpi.py under ``mpiexec``: a conducting scene advanced in calls of uneven
lengths that end inside conduction cycles (as a replay after a blow-up does), over all processes
and in each process alone, compared bit for bit (the state, every heat log, and the diagnostics
row every process makes from its share).

    mpiexec -n P python tests/mpi_conduction.py SCENE CALLS EVERY:PARTS ... [-- ARGS]

CALLS: the calls' lengths, comma-separated; per EVERY:PARTS (the cycle's steps k, or kxj with j
sub-sweeps; the partitioner) rank 0 prints "same" or "DIFFERENT: <what>", then "share only" where the processes
other than rank 0 hold nothing of the whole net's size after conducting calls and diagnostics
rows and a checkpoint (each process writes its piece), no whole state or heat log was put
together for them, and a piece that cannot be written keeps the previous checkpoint ("WHOLE:
<what>" else). ARGS: a ``thermonet`` command run
first over the same processes (the test's resumed run: one launch instead of two)."""

import os
import shutil
import sys
import tempfile
from contextlib import contextmanager

import numpy as np
from mpi4py import MPI
from mpi_held import builds_nothing_whole_here, whole_net_arrays

from thermonet.heat.logs import heat_logs
from thermonet.io import RunOutput
from thermonet.parallel import pieces
from thermonet.parallel.stepper import PARTITION_VARIABLE
from thermonet.parallel.world import LAUNCHER_VARIABLES
from thermonet.scenes import load_scene

ARGS = sys.argv[1:sys.argv.index("--")] if "--" in sys.argv else sys.argv[1:]
SCENE, CALLS, SPECS = ARGS[0], [int(n) for n in ARGS[1].split(",")], ARGS[2:]


def run(every: int, sweeps: int, alone: bool) -> dict:
    """The state's arrays and heat logs after the calls; ``alone``: as if not started by mpiexec."""
    saved = {k: os.environ.pop(k) for k in LAUNCHER_VARIABLES if k in os.environ} if alone else {}
    try:
        sim = load_scene(SCENE).build().simulation
    finally:
        os.environ.update(saved)
    assert (sim.comm is None) == alone
    state = sim.internal_state()
    heat_logs(state, sim.system.heat)["cycle"][:] = (every, 0, sweeps)
    for n in CALLS:
        sim.runner.advance(n)
    sim.record_diagnostics()  # (over processes: from the shares, the heat columns from the logs; on every process)
    row = sim.diagnostics.rows[-1]
    state = sim.internal_state()  # (over processes: put together from the shares)
    out = {k: getattr(state, k) for k in ("positions", "momenta", "thermal_displacement", "entropy")}
    out["row"] = np.array([row[k] for k in sorted(row)])
    out.update({f"heat_{k}": v for k, v in state.extra["heat"].items()})
    return out


def holds_its_share_only() -> str:
    """"only" where, after conducting calls with diagnostics rows, no process other than rank 0
    holds an array of the whole net's length (n, n + 1, 3n, m or 2m: nodes, incidence pointers,
    springs, incidences) and no whole state or heat log was put together for the rows; else
    what was found; the others never build the whole net (rank 0 sends them their parts)."""
    with builds_nothing_whole_here():
        sim = load_scene(SCENE).build().simulation
    sim.stability_guard.active = False
    gathers = []
    for holder in (sim.stepper._gather, sim.stepper._conduction):
        to_root = holder.to_root
        holder.to_root = lambda *args, _f=to_root, **kwargs: (gathers.append(1), _f(*args, **kwargs))
    sim.run(steps=4, diagnostics_every=2)
    folder = sim.comm.bcast(tempfile.mkdtemp() if sim.comm.Get_rank() == 0 else None)
    out = RunOutput.for_simulation(sim, folder, "shock", frames_every=0, checkpoint_every=4)
    out.write_checkpoint(sim)  # (each process its piece: nothing put together)
    found = ([f"{len(gathers)} gathers"] if gathers else []) + whole_net_arrays(sim)
    found += failed_piece_keeps_the_checkpoint(sim, out)
    found = sum(sim.comm.allgather(found), [])
    if sim.comm.Get_rank() == 0:
        shutil.rmtree(folder)
    return "only" if not found else "WHOLE: " + "; ".join(found)


def failed_piece_keeps_the_checkpoint(sim, out) -> list:
    """[] where a piece the last process cannot write stops the checkpoint on every process
    with an error naming it, and the previous checkpoint stays whole and readable; else what went
    wrong."""
    from thermonet.errors import OutputError
    from thermonet.io import load_checkpoint

    last = sim.comm.Get_size() - 1
    sim.run(steps=2)

    @contextmanager
    def full_disk(path, mode="wb"):
        raise OSError(28, "No space left on device", path)

    saved = pieces.atomic_write
    if sim.comm.Get_rank() == last:
        pieces.atomic_write = full_disk
    try:
        out.write_checkpoint(sim)
        return ["a piece that failed did not stop the checkpoint"]
    except OutputError as exc:
        if f"piece-{last:05d}.npz: No space left on device" not in str(exc) or "previous one is kept" not in str(exc):
            return [f"the error does not name the piece: {exc}"]
    finally:
        pieces.atomic_write = saved
    sim.comm.Barrier()
    state, _ = load_checkpoint(out.checkpoint_path)
    if state.step != 4 or len(os.listdir(pieces.pieces_folder(out.checkpoint_path))) != 1:
        return [f"the checkpoint kept is of step {state.step}, not 4, or the failed pieces were not removed"]
    return []


if "--" in sys.argv:
    from thermonet.cli.main import main

    assert main(sys.argv[sys.argv.index("--") + 1:]) == 0
for spec in SPECS:
    cycle, parts = spec.split(":")
    every, sweeps = (int(v) for v in (cycle.split("x") if "x" in cycle else (cycle, 1)))
    os.environ[PARTITION_VARIABLE] = parts
    many, one = run(every, sweeps, False), run(every, sweeps, True)
    different = [k for k in one if not np.array_equal(one[k], many[k])]
    different = sorted(set(sum(MPI.COMM_WORLD.allgather(different), [])))  # (every process's row too)
    if MPI.COMM_WORLD.Get_rank() == 0:
        print("same" if not different else f"DIFFERENT: {' '.join(different)}", flush=True)
held = holds_its_share_only()
if MPI.COMM_WORLD.Get_rank() == 0:
    print("share", held, flush=True)
