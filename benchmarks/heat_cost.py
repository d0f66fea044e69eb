"""What Fourier conduction costs per step: CO2 with conduction against the same thermal run
without it (adiabatic), on a jittered 6-neighbour lattice and on a gmsh tetrahedral bar, with
one thread (serial kernels) and the default thread count.

    python benchmarks/heat_cost.py [--cells 32] [--mesh-size 0.06] [--steps 200] [--repeats 5]
    python benchmarks/heat_cost.py --cells 69 --mesh-size 0.03 --steps 5 --repeats 3   # ~1e6

Per net and thread count the runs alternate once per repeat after a warm-up (adiabatic,
conduction, conduction with g = 0, the sweeps alone, the star sketch), so that drifts of a
shared machine hit all alike; times are medians over the repeats and the ratio is the median
of the per-repeat ratios. Also reported: the pair count per spring
(``thermonet.heat.graph.pairs_per_spring``) and the colours of the pair graph. Target
(issue 17): the whole step with conduction ≤ 2× the adiabatic thermal step.

"g = 0" runs the conduction step with g = 0: the same schedule (sweeps at both ends of the
step, so CO2's closing kick is no longer shared with the next step's opening kick) without a
pair to exchange. "sweeps" times ``conduction_sweep`` forward and reverse over h/2 (what one
step runs) on a copy of the state. "star" times a sketch that is not the engine's model:
node-star exchanges (the springs at a node relax together toward their weighted mean
temperature; energy exact, entropy non-decreasing; nodes coloured so that a colour's nodes share
no spring), two visits per spring instead of one per pair.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import tempfile
import time

import numba
import numpy as np
from numba import njit, prange

import thermonet as tn
from thermonet.heat.graph import pairs_per_spring
from thermonet.kernels import records
from thermonet.kernels.heat_passes import heat_kernels
from thermonet.stability import stable_step

PARAMETERS = dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0)
G = 1.0


def tetra_bar(mesh_size: float) -> tn.Net:
    """The tetrahedral bar [0, 4] × [0, 1] × [0, 1] meshed by gmsh at ``mesh_size``."""
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.model.add("bar")
        gmsh.model.occ.addBox(0, 0, 0, 4, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [1], name="bar")
        gmsh.option.setNumber("Mesh.MeshSizeMin", mesh_size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", mesh_size)
        gmsh.option.setNumber("Mesh.Algorithm3D", 10)   # HXT: parallel, fast at 1e6 springs
        gmsh.model.mesh.generate(3)
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, "bar.msh")
            gmsh.write(path)
            gmsh.finalize()
            return tn.read_mesh(path, cell_types=["tetra"])
    finally:
        if gmsh.isInitialized():
            gmsh.finalize()


def simulations(net: tn.Net, threads: int | None):
    """(adiabatic, conduction, conduction with g = 0) simulations of ``net``: same parameters,
    temperatures (300 ± 50, seeded), velocities and step (0.4× the adiabatic CO2 stability
    limit). With g = 0 the step runs conduction's schedule with no pair to exchange."""
    rng = np.random.default_rng(1)
    theta = 300.0 + rng.uniform(-50.0, 50.0, net.n_springs)
    v = rng.uniform(-0.01, 0.01, (net.n_nodes, 3))
    common = dict(model="hencky", temperatures=theta, velocities=v, integrator="co2", threads=threads,
                  energy_tolerance=None, stability_guard="off")
    adiabatic = tn.Simulation(net, parameters=PARAMETERS, h=1.0, **common)
    h = 0.4 * stable_step(adiabatic)["h_max"]
    adiabatic.h = h
    conduction = tn.Simulation(net, parameters={**PARAMETERS, "g": G}, conduction=True, h=h, **common)
    empty = tn.Simulation(net, parameters={**PARAMETERS, "g": 0.0}, conduction=True, h=h, **common)
    return adiabatic, conduction, empty


def step_seconds(sim, steps: int) -> float:
    t0 = time.perf_counter()
    sim.run(steps=steps, diagnostics_every=steps)
    return (time.perf_counter() - t0) / steps


class Sweeps:
    """The two conduction sweeps of one step (over h/2, forward then reverse) on a copy of the
    state of ``sim``, with the engine's sweep and with the node-star sketch."""

    def __init__(self, sim):
        system = sim.system
        self.heat = system.heat
        P, uniform = system.kernel_parameters
        temperature_pass, self.sweep = heat_kernels(system.model, sim.parallel, uniform)
        s = sim.internal_state()
        self.theta = np.empty(system.n_springs)
        temperature_pass(s.positions, s.entropy, records.topology(system.layout),
                         records.Springs(system.rest_lengths, P), self.theta, np.empty(system.n_springs))
        self.theta0 = self.theta.copy()
        self.theta_start = np.empty_like(self.theta)
        self.eta = s.entropy.copy()
        self.logs = self.heat.new_logs()
        self.tau = 0.5 * sim.h
        self.record = self.heat.record(self.tau, self.logs)
        self.parallel = sim.parallel
        layout = system.layout
        self.inc_ptr = layout.inc_ptr.astype(np.int64)
        self.inc_spring = layout.inc_spring.astype(np.int64)
        colour = _node_colours(self.inc_ptr, layout.inc_other.astype(np.int64))
        self.node_order = np.argsort(colour, kind="stable")
        self.node_colour_ptr = np.r_[0, np.cumsum(np.bincount(colour))].astype(np.int64)
        C, g = self.heat.capacity, self.heat.conductance
        self.weight = -C * np.expm1(-g * self.tau / C)
        self.rate = self.weight / C

    def engine(self) -> float:
        np.copyto(self.theta, self.theta0)
        t0 = time.perf_counter()
        self.sweep(self.record, self.theta, self.theta_start, self.eta, self.tau, 0.0, False)
        self.sweep(self.record, self.theta, self.theta_start, self.eta, self.tau, 0.0, True)
        return time.perf_counter() - t0

    def star(self) -> float:
        np.copyto(self.theta, self.theta0)
        fn = _star_par if self.parallel else _star_ser
        args = (self.node_order, self.node_colour_ptr, self.inc_ptr, self.inc_spring, self.weight, self.rate,
                self.heat.capacity, self.theta, self.eta, self.record.produced)
        t0 = time.perf_counter()
        fn(*args, False)
        fn(*args, True)
        return time.perf_counter() - t0


@njit(cache=True)
def _node_colours(inc_ptr, inc_other):
    """Greedy colouring of the nodes: two nodes joined by a spring differ."""
    n = inc_ptr.shape[0] - 1
    colour = np.full(n, -1, dtype=np.int64)
    used = np.full(256, -1, dtype=np.int64)
    for i in range(n):
        for s in range(inc_ptr[i], inc_ptr[i + 1]):
            c = colour[inc_other[s]]
            if c >= 0:
                used[c] = i
        c = 0
        while used[c] == i:
            c += 1
        colour[i] = c
    return colour


def _star(order, colour_ptr, inc_ptr, inc_spring, weight, rate, capacity, theta, eta, produced, reverse):
    """Node-star exchanges on θ alone, node colour by node colour: the springs at node i relax
    toward their weighted mean θ_i = Σ a θ / Σ a, θ_e += (a_e/C_e)(θ_i − θ_e), with
    a_e = C_e (1 − exp(−g_e τ / C_e)) (energy exact, entropy non-decreasing by Jensen); then
    one logarithm per spring."""
    m = theta.shape[0]
    start = np.empty(m)
    for e in prange(m):
        start[e] = theta[e]
    n_colours = colour_ptr.shape[0] - 1
    for j in range(n_colours):
        c = n_colours - 1 - j if reverse else j
        for k in prange(colour_ptr[c], colour_ptr[c + 1]):
            i = order[k]
            num = 0.0
            den = 0.0
            for s in range(inc_ptr[i], inc_ptr[i + 1]):
                e = inc_spring[s]
                num += weight[e] * theta[e]
                den += weight[e]
            if den > 0.0:
                mean = num / den
                for s in range(inc_ptr[i], inc_ptr[i + 1]):
                    e = inc_spring[s]
                    theta[e] += rate[e] * (mean - theta[e])
    for e in prange(m):
        d = capacity[e] * math.log(theta[e] / start[e])
        eta[e] += d
        produced[e] += d


_star_par = njit(parallel=True, cache=True, error_model="numpy", boundscheck=False)(_star)
_star_ser = njit(cache=True, error_model="numpy", boundscheck=False)(_star)


def measure(name: str, net: tn.Net, threads: int | None, steps: int, repeats: int) -> dict:
    adiabatic, conduction, empty = simulations(net, threads)
    sweeps = Sweeps(conduction)
    for sim in (adiabatic, conduction, empty):  # warm-up: compile or load the kernels, touch the memory
        sim.run(steps=2, diagnostics_every=2)
    sweeps.engine(), sweeps.star()
    samples = {"adiabatic": [], "conduction": [], "schedule": [], "sweeps": [], "star": []}
    for _ in range(repeats):
        samples["adiabatic"].append(step_seconds(adiabatic, steps))
        samples["conduction"].append(step_seconds(conduction, steps))
        samples["schedule"].append(step_seconds(empty, steps))
        samples["sweeps"].append(statistics.median(sweeps.engine() for _ in range(3)))
        samples["star"].append(statistics.median(sweeps.star() for _ in range(3)))
    graph = conduction.system.heat.graph
    return {
        "net": name, "springs": net.n_springs, "threads": threads or numba.config.NUMBA_NUM_THREADS,
        "kernels": "parallel" if conduction.parallel else "serial",
        "pairs_per_spring": pairs_per_spring(graph, net.n_springs), "colours": graph.n_colours,
        **{k: statistics.median(v) for k, v in samples.items()},
        "ratio": statistics.median(c / a for a, c in zip(samples["adiabatic"], samples["conduction"])),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=32, help="lattice cells per axis (32: about 1e5 springs)")
    ap.add_argument("--mesh-size", type=float, default=0.06, help="gmsh size of the tetrahedral bar "
                    "(0.06: about 1.2e5 springs)")
    ap.add_argument("--steps", type=int, default=200, help="steps per timed run")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--threads", default="1,default", help="comma-separated thread counts ('default': Numba's)")
    ap.add_argument("--nets", default="lattice,tetra")
    args = ap.parse_args()
    nets = {}
    for which in args.nets.split(","):
        t0 = time.perf_counter()
        if which == "lattice":
            net = tn.lattice((args.cells,) * 3, neighbours=6, jitter=0.1, seed=1)
            nets[f"lattice {args.cells}³ (6 neighbours)"] = net
        else:
            net = tetra_bar(args.mesh_size)
            nets[f"gmsh tetra bar, size {args.mesh_size:g}"] = net
        print(f"built {which}: {net.n_springs} springs in {time.perf_counter() - t0:.1f} s", flush=True)
    rows = []
    for name, net in nets.items():
        for t in args.threads.split(","):
            rows.append(measure(name, net, None if t == "default" else int(t), args.steps, args.repeats))
            print(rows[-1], flush=True)
    load = os.getloadavg()[0]
    print(f"\nco2, hencky, g = {G}, {args.steps} steps per run, {args.repeats} interleaved repeats, "
          f"{os.cpu_count()} cores, load average {load:.2f}\n")
    print("| net | springs | pairs/spring | colours | threads | adiabatic ms/step | conduction ms/step | "
          "ratio | g = 0 ms/step | sweeps ms/step | star ms/step |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['net']} | {r['springs']:,} | {r['pairs_per_spring']:.1f} | {r['colours']} | {r['threads']} "
              f"({r['kernels']}) | {1e3 * r['adiabatic']:.3g} | {1e3 * r['conduction']:.3g} | "
              f"**{r['ratio']:.2f}×** | {1e3 * r['schedule']:.3g} | {1e3 * r['sweeps']:.3g} | "
              f"{1e3 * r['star']:.3g} |")


if __name__ == "__main__":
    main()
