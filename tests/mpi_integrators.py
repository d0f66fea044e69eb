"""Run by tests/test_mpi.py under ``mpiexec``: each explicit integrator named on the command line,
on a scene, over all processes and in each process alone, compared bit for bit (diagnostics rows
and state); rank 0 prints one line per integrator, then "share only" where every process steps
its share only, make their diagnostics rows without putting the whole state together, and those
other than rank 0 hold no whole-net arrays (thermonet.parallel.held).

    mpiexec -n P python tests/mpi_integrators.py SCENE STEPS NAME ... [-- ARGS]

NAME@H: the integrator run STEPS steps, then at step size H until the run stops (a blow-up
replayed from the runner's backup, or a guard's rewind): the message is compared too.
ARGS: a ``thermonet`` command run first over the same processes (one launch instead of two)."""

import os
import sys

import numpy as np
from mpi4py import MPI
from mpi_held import builds_nothing_whole_here, whole_net_arrays

from thermonet.errors import SimulationError
from thermonet.parallel.held import NotHeldError
from thermonet.parallel.world import LAUNCHER_VARIABLES
from thermonet.scenes import load_scene

ARGS = sys.argv[1:sys.argv.index("--")] if "--" in sys.argv else sys.argv[1:]
SCENE, STEPS, NAMES = ARGS[0], int(ARGS[1]), ARGS[2:]


def run(name: str, alone: bool):
    """(rows, x, p, Φ, η, the message that stopped the run) of STEPS steps (NAME@H: then more at
    H, see above); ``alone``: as if not started by mpiexec (one process)."""
    integrator, _, h = name.partition("@")
    saved = {k: os.environ.pop(k) for k in LAUNCHER_VARIABLES if k in os.environ} if alone else {}
    try:
        sim = load_scene(SCENE, [f'integrator.name="{integrator}"']).build().simulation
    finally:
        os.environ.update(saved)
    assert (sim.comm is None) == alone
    diag = sim.run(steps=STEPS, diagnostics_every=STEPS // 2)
    message = None
    if h:
        sim.h = float(h)
        try:
            sim.run(steps=100 * STEPS, diagnostics_every=STEPS // 2)
        except SimulationError as exc:
            message = str(exc)
        assert message is not None, "the run was meant to stop"
    s = sim.state
    return [diag.rows, s.positions, s.momenta, s.thermal_displacement, s.entropy, message]


def holds_its_share_only() -> bool:
    """Whether, on every process, the stepping arrays are the share's (owned nodes and one layer
    of ghosts, fewer than the net's), the diagnostics rows are reduced on the shares (no state
    gathered for them: the stability guard, which reads the whole state, is off here; but with
    loads, whose rows rank 0 makes from the state gathered there), and, on
    processes other than rank 0, the whole net's arrays are let go of (a read raises
    NotHeldError; nothing of the whole net's length is held) while ``sim.state`` is still read
    whole."""
    with builds_nothing_whole_here():  # (rank 0 alone builds the whole net)
        sim = load_scene(SCENE).build().simulation
    sim.stability_guard.active = False
    gathers = []
    to_root = sim.stepper._gather.to_root
    sim.stepper._gather.to_root = lambda *args, **kwargs: (gathers.append(args), to_root(*args, **kwargs))
    sim.run(steps=2, diagnostics_every=1)
    n, m = sim.net.n_nodes, sim.net.n_springs
    sh = sim.stepper.share
    ok = len(sim.diagnostics.rows) == 3 and (not gathers or sim.loads is not None)  # (loads: rank 0 makes the rows)
    ok = ok and len(sh.nodes) < n and len(sh.springs) < m and sim.stepper._x.shape == (len(sh.nodes), 3)
    state, v, strains = sim.state, sim.velocities(), sim.strains()  # (read together, whole on every process)
    if sim.comm.Get_rank() > 0:
        ok = ok and sim._state.positions.size == sim._state.entropy.size == 0 and sim.stepper.decomposition is None
        ok = ok and not whole_net_arrays(sim)  # (nothing of the whole net's length)
        for read in (lambda: sim.net.positions.sum(), lambda: np.asarray(sim.system.parameters),
                     lambda: sim.layout.edges[0], lambda: sim.net.masses[0], lambda: sim.layout.nodes_to_user(v)):
            try:
                read()
                ok = False
            except NotHeldError:
                pass
    ok = ok and state.positions.shape == v.shape == (n, 3) and state.entropy.shape == strains.shape == (m,)
    return all(sim.comm.allgather(ok))


if "--" in sys.argv:
    from thermonet.cli.main import main

    assert main(sys.argv[sys.argv.index("--") + 1:]) == 0
for name in NAMES:
    many, one = run(name, False), run(name, True)
    same = many[0] == one[0] and many[-1] == one[-1] and all(np.array_equal(a, b) for a, b in zip(many[1:-1], one[1:-1]))
    same = all(MPI.COMM_WORLD.allgather(same))  # (the rows every process made, not only rank 0's)
    if MPI.COMM_WORLD.Get_rank() == 0:
        print(name, "same" if same else "DIFFERENT", flush=True)
held = holds_its_share_only()
if MPI.COMM_WORLD.Get_rank() == 0:
    print("share", "only" if held else "WHOLE", flush=True)
