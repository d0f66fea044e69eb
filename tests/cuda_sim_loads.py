"""Runs small loaded nets on the CPU and the CUDA backend and saves both, for
``tests/test_loads_cuda.py``; run as a script in a process of its own (``NUMBA_ENABLE_CUDASIM=1``
must be set before Numba is imported):

    python tests/cuda_sim_loads.py OUT.npz [STEPS]
"""

from __future__ import annotations

import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [ROOT]

import thermonet as tn  # noqa: E402
from thermonet.loads import Drive, Force  # noqa: E402

COLUMNS = ("energy", "work", "energy_balance", "pull_Rx", "pull_work", "push_work", "px", "py")


def loaded(backend, integrator):
    net = tn.lattice((2, 1, 1), neighbours=18, jitter=0.05, seed=3)
    x = net.positions
    net.node_groups.update(grip=np.flatnonzero(x[:, 0] > x[:, 0].max() - 0.3),
                           base=np.flatnonzero(x[:, 0] < 0.3), top=np.flatnonzero(x[:, 2] > x[:, 2].max() - 0.3))
    net.anchored[:] = False
    net.anchored[net.node_groups["base"]] = True
    top = np.setdiff1d(net.node_groups["top"], np.union1d(net.node_groups["grip"], net.node_groups["base"]))
    loads = {"pull": Drive("grip", {"x": {"rate": 0.5}, "z": {"amplitude": 0.02, "frequency": 5.0}}, free=True),
             "push": Force(top, {"y": {"table": [[0, 0], [0.004, 1.0], [1, 1.5]]}}, total=True)}
    rng = np.random.default_rng(1)
    return tn.Simulation(net, temperatures=300 + 100 * rng.random(net.n_springs), integrator=integrator, h=1e-3,
                         gravity=[0, 0, -2.0], backend=backend, loads=loads)


def main(path, steps):
    out = {}
    for integrator in ("co2", "f10", "co4"):
        for backend in ("cpu", "cuda"):
            sim = loaded(backend, integrator)
            sim.run(steps=steps, diagnostics_every=max(1, steps // 2))
            s = sim.state
            key = f"{integrator}/{backend}"
            out[f"{key}/positions"], out[f"{key}/momenta"] = s.positions, s.momenta
            out[f"{key}/phi"], out[f"{key}/load_work"] = s.thermal_displacement, s.extra["load_work"]
            for c in COLUMNS:
                out[f"{key}/{c}"] = sim.diagnostics.column(c)
    # in chunks (2 + rest) on the device: the same as in one call
    sim = loaded("cuda", "co2")
    sim.run(steps=2, diagnostics_every=1)
    sim.run(steps=steps - 2, diagnostics_every=max(1, steps // 2))
    out["chunks/positions"], out["chunks/load_work"] = sim.state.positions, sim.state.extra["load_work"]
    # with heat flow (conduction, a bath, a source; the CPU sweeping in the GPU's order, every
    # 2 steps): the CPU defers a kick past the sweeps, the device recomputes the temperatures instead
    from test_loads_heat import loaded_hot_strip

    for backend in ("cpu", "cuda"):
        sim = loaded_hot_strip(0.004, backend=backend, conduction_every=2)
        sim.system.heat.use_order_of("cuda")
        sim.run(steps=8 * steps, diagnostics_every=4 * steps)
        s = sim.state
        out[f"heat/{backend}/positions"], out[f"heat/{backend}/entropy"] = s.positions, s.entropy
        out[f"heat/{backend}/load_work"] = s.extra["load_work"]
        out[f"heat/{backend}/energy_balance"] = sim.diagnostics.column("energy_balance")
    np.savez(path, **out)


if __name__ == "__main__":
    from simulator_pace import pace

    pace()
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 6)
