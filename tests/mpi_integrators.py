"""Run by tests/test_mpi.py under ``mpiexec``: each explicit integrator named on the command line,
on a scene, over all processes and in each process alone, compared bit for bit (diagnostics rows
and state); rank 0 prints one line per integrator."""

import os
import sys

import numpy as np
from mpi4py import MPI

from thermonet.parallel.world import LAUNCHER_VARIABLES
from thermonet.scenes import load_scene

SCENE, STEPS = sys.argv[1], int(sys.argv[2])


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


for name in sys.argv[3:]:
    many, one = run(name, False), run(name, True)
    same = many[0] == one[0] and all(np.array_equal(a, b) for a, b in zip(many[1:], one[1:]))
    if MPI.COMM_WORLD.Get_rank() == 0:
        print(name, "same" if same else "DIFFERENT", flush=True)
