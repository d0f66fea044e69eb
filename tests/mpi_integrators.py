"""Run by tests/test_mpi.py under ``mpiexec``: each explicit integrator named on the command line,
on a scene, over all processes and in each process alone, compared bit for bit (diagnostics rows
and state); rank 0 prints one line per integrator.

    mpiexec -n P python tests/mpi_integrators.py SCENE STEPS NAME ... [-- ARGS]

ARGS: a ``thermonet`` command run first over the same processes (one launch instead of two)."""

import os
import sys

import numpy as np
from mpi4py import MPI

from thermonet.parallel.world import LAUNCHER_VARIABLES
from thermonet.scenes import load_scene

ARGS = sys.argv[1:sys.argv.index("--")] if "--" in sys.argv else sys.argv[1:]
SCENE, STEPS, NAMES = ARGS[0], int(ARGS[1]), ARGS[2:]


def run(integrator: str, alone: bool):
    """(rows, x, p, Φ, η) of STEPS steps; ``alone``: as if not started by mpiexec (one process)."""
    saved = {k: os.environ.pop(k) for k in LAUNCHER_VARIABLES if k in os.environ} if alone else {}
    try:
        sim = load_scene(SCENE, [f'integrator.name="{integrator}"']).build().simulation
    finally:
        os.environ.update(saved)
    assert (sim.comm is None) == alone
    diag = sim.run(steps=STEPS, diagnostics_every=STEPS // 2)
    s = sim.state
    return [diag.rows, s.positions, s.momenta, s.thermal_displacement, s.entropy]


if "--" in sys.argv:
    from thermonet.cli.main import main

    assert main(sys.argv[sys.argv.index("--") + 1:]) == 0
for name in NAMES:
    many, one = run(name, False), run(name, True)
    same = many[0] == one[0] and all(np.array_equal(a, b) for a, b in zip(many[1:], one[1:]))
    if MPI.COMM_WORLD.Get_rank() == 0:
        print(name, "same" if same else "DIFFERENT", flush=True)
