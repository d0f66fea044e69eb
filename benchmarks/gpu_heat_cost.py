"""What Fourier conduction costs per step on the GPU: CO2 with conduction against the same thermal
CO2 run without it, on a jittered 6-neighbour lattice, both launch modes, conduction every step
and every k steps as "auto" picks k.

    python benchmarks/gpu_heat_cost.py [--sizes 3e5,3e6] [--seconds 2]
    NUMBA_ENABLE_CUDASIM=1 python benchmarks/gpu_heat_cost.py --quick   # a smoke run (tests/test_benchmarks.py)

Needs an NVIDIA GPU and numba-cuda (``pip install '.[cuda]'``, docs/gpu.md says how to carry the
wheels to a machine without the package index). Per net it prints a markdown table: G
spring-steps/s of the adiabatic run and of the run with conduction (``stepper.advance`` timed
with the device synchronized, medians of three runs of about ``--seconds`` each after a warm-up
that compiles the kernels), their ratio, and the grid-wide conduction phases of a step with
conduction every step (:func:`phases_per_step`). Then, per net, a launch profile of the step with
conduction (:func:`launch_profile`): host and wall µs of each launch of a half sweep, which says
whether the host or the device bounds it. Hencky springs at 250–350 K, g = 1, C0 = 5,
h = 0.4× the stable step. Target: conduction every step ≤ 2.5× the adiabatic step at 3e6 springs.

``--quick`` runs a tiny net for a few steps and accepts Numba's CUDA simulator: it checks that
the script runs, its timings mean nothing.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import thermonet as tn  # noqa: E402
from gpu_throughput import gpu_rate  # noqa: E402
from thermonet.explicit.cuda import cuda_problem, simulator_enabled  # noqa: E402
from thermonet.kernels import records  # noqa: E402
from thermonet.heat.multirate import choose_cycle  # noqa: E402
from thermonet.stability import stable_step  # noqa: E402

PARAMETERS = dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0)
G = 1.0


def simulations(target_springs: int) -> dict:
    """name -> CUDA simulation of one 6-neighbour lattice of about ``target_springs`` springs:
    adiabatic, conduction every step, conduction every k steps ("auto"'s k, no output cadence)."""
    k = max(1, int(round((target_springs / 3.0) ** (1.0 / 3.0))))
    net = tn.lattice((k, k, k), neighbours=6, jitter=0.1, seed=1)
    rng = np.random.default_rng(1)
    common = dict(temperatures=250.0 + 100.0 * rng.random(net.n_springs),
                  velocities=rng.normal(0.0, 0.01, (net.n_nodes, 3)), integrator="co2",
                  stability_guard="off", energy_tolerance=None)
    probe = tn.Simulation(net, parameters=PARAMETERS, h=1.0, **common)
    h = 0.4 * stable_step(probe)["h_max"]
    conduction = dict(parameters={**PARAMETERS, "g": G}, conduction=True)
    every = tn.Simulation(net, h=h, conduction_every=1, **conduction, **common)
    auto_k = choose_cycle("auto", every.system.heat.fastest_rate(), h, [])[0]
    return {"adiabatic": tn.Simulation(net, parameters=PARAMETERS, h=h, backend="cuda", **common),
            "every step": tn.Simulation(net, h=h, conduction_every=1, backend="cuda", **conduction, **common),
            f"every {auto_k} steps": tn.Simulation(net, h=h, conduction_every=auto_k, backend="cuda", **conduction,
                                                   **common)}


def rate(sim, cuda, seconds: float, fused: bool, quick: bool) -> float:
    """Spring-steps/s of ``sim``'s CUDA stepper (:func:`gpu_throughput.gpu_rate`, calls in
    whole conduction cycles; quick: one short call after the compiling one)."""
    cycle = int(sim.conduction_every) if sim.system.heat is not None else 1
    return gpu_rate(sim, cuda, seconds, fused, cycle, quick=quick)


def phases_per_step(sim) -> int:
    """Grid-wide conduction phases of a step of ``sim`` inside a call (conduction every step, one
    sweep), as the stepper runs them (:func:`thermonet.heat.cuda.conduction_plan`): the reverse
    row's but its start (the kick before it keeps θ as the start) and finish (left to the forward
    row after it), the forward row's but its start and finish (the kick after it runs the finish
    of both), the meeting colours of the two as one phase where no baths or sources stand between
    them, empty phases left out."""
    from thermonet.heat.cuda import conduction_plan
    from thermonet.heat.rows import CONDUCTION_FORWARD, CONDUCTION_REVERSE

    heat = sim.stepper._heat
    n_colours = len(heat.star_colour_ptr) - 1
    total = 0
    for code, finish_pending, joined, follows in ((CONDUCTION_REVERSE, False, False, True),
                                                  (CONDUCTION_FORWARD, True, True, False)):
        phases = heat.phases(code)
        lo, hi, skip = conduction_plan(code, len(phases), n_colours, 1, heat.n_bound, True, finish_pending, joined,
                                       follows, False)[:3]
        total += sum(1 for phase, count in phases[lo:hi] if count > 0 and phase != skip)
    return total


def launch_profile(sim, cuda, repeats: int) -> list[dict]:
    """Where a conduction step's time goes with two launches per stage: each launch of a
    forward half sweep (the temperature pass, the spring pass of a kick plain, keeping θ for the
    sweep after it and finishing the sweep before it, then the half sweep's phases),
    ``repeats`` times back to back. Per launch: the host's time to enqueue it (the loop before
    the device is synchronized) and the wall time (after it): wall ≈ host means the host
    bounds that launch, wall > host means the device does. The runs leave the state
    meaningless (phases repeated on their own), so this comes after the timed runs."""
    from thermonet.heat.cuda import BLOCKS, BOUNDARY, FINISH, JOINED, PLAIN, START, _phase_span, colours_meet
    from thermonet.heat.rows import CONDUCTION_FORWARD

    stepper, m = sim.stepper, sim.net.n_springs
    stepper.fused = False
    stepper.advance(sim._state, 2, sim.h)  # compile and upload
    heat, k, code = stepper._heat.record(sim.h, 1), stepper._k, CONDUCTION_FORWARD
    tau = 0.5 * sim.h
    launches = [("temperature pass", m, lambda: stepper._launch(
        k.temperature, k.blocks(m), k.threads, stepper._x, stepper._eta, stepper._topology.edges, stepper._springs,
        heat, stepper._flag))]
    run = records.Run(sim.h, 0.0, 1, True, *(float(b) for b in sim.system.stretch_bounds), False, False, 1, 0)

    def spring_pass(keep: bool, finish: bool):
        return lambda: stepper._spring_pass(stepper._s, (0.5 * sim.h, 0.0), run, (0, 0, 0), keep, finish)

    launches += [("spring pass of a kick", m, spring_pass(False, False)),
                 ("the same, keeping θ and l for the sweep after it", m, spring_pass(True, False)),
                 ("the same, finishing the forward sweep before it", m, spring_pass(False, True))]
    n = sim.net.n_nodes

    def node_pass(split: bool):
        return lambda: stepper._launch(k.node, k.blocks(n), k.threads, stepper._x, stepper._x_buf, stepper._p,
                                       stepper._s, stepper._topology, stepper._nodes,
                                       (0.5 * sim.h if split else 0.0, 0.5 * sim.h, sim.h, True, split), stepper._flag,
                                       stepper._loads, stepper._heat.s_before if split else stepper._s)

    launches += [("node pass of a kick and drift", n, node_pass(False)),
                 ("the same, first the closing kick with the forces from before the sweep", n, node_pass(True))]
    kinds = {START: "θ start", BOUNDARY: "baths and sources", BLOCKS: "star colour", FINISH: "finish (η)"}
    dh = stepper._heat
    for phase, count in dh.phases(code):
        kind = _phase_span(code, phase, dh.colour_ptr, dh.star_colour_ptr, dh.n_bound, dh.m, 1)[0]
        if count > 0:
            launches.append((f"phase {phase}: {kinds[kind]}", count, lambda phase=phase, count=count: stepper._launch(
                k.sweep, k.blocks(count), k.threads, code, phase, heat, tau, 0.0, stepper._phi, stepper._eta,
                stepper._flag, PLAIN)))
    if colours_meet(1, dh.n_bound, len(dh.star_colour_ptr) - 1):
        launches.append(("phase 2 joined: star colour in reverse, then forward", dh.phases(code)[2][1],
                         lambda: stepper._launch(k.sweep, k.blocks(dh.phases(code)[2][1]), k.threads, code, 2, heat,
                                                 tau, 0.0, stepper._phi, stepper._eta, stepper._flag, JOINED)))
    rows = []
    for name, elements, launch in launches:
        launch()
        cuda.synchronize()
        t0 = time.perf_counter()
        for _ in range(repeats):
            launch()
        host = time.perf_counter() - t0
        cuda.synchronize()
        wall = time.perf_counter() - t0
        rows.append(dict(launch=name, elements=elements, host_us=1e6 * host / repeats, wall_us=1e6 * wall / repeats))
    t0 = time.perf_counter()
    stepper.advance(sim._state, repeats, sim.h)
    cuda.synchronize()
    rows.append(dict(launch="whole step (two launches per stage)", elements=m, host_us=float("nan"),
                     wall_us=1e6 * (time.perf_counter() - t0) / repeats))
    return rows


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="3e5,3e6", help="comma-separated spring counts")
    ap.add_argument("--seconds", type=float, default=2.0, help="length of each timed run")
    ap.add_argument("--quick", action="store_true", help="a tiny net, a few steps; the CUDA simulator allowed")
    ap.add_argument("--repeats", type=int, default=50, help="back-to-back launches per row of the launch profile")
    args = ap.parse_args(argv)
    if args.quick:
        args.sizes = "40"
    problem = cuda_problem()
    if problem is None and simulator_enabled() and not args.quick:
        problem = "Numba's CUDA simulator is on (NUMBA_ENABLE_CUDASIM): its timings mean nothing"
    if problem is not None:
        print(f"gpu_heat_cost: needs a CUDA GPU: {problem}", file=sys.stderr)
        raise SystemExit(2)
    from numba import cuda

    rows = []
    print("| springs | launch | run | G spring-steps/s | × the adiabatic step | conduction phases per step |")
    print("|---:|---|---|---:|---:|---:|")
    for size in (int(float(s)) for s in args.sizes.split(",")):
        sims = simulations(size)
        phases = phases_per_step(sims["every step"])
        for fused in (True, False):
            rates = {name: rate(sim, cuda, args.seconds, fused, args.quick) for name, sim in sims.items()}
            for name, r in rates.items():
                row = dict(springs=sims[name].net.n_springs, launch="fused" if fused else "two per stage", run=name,
                           rate=r, ratio=rates["adiabatic"] / r, phases=0 if name == "adiabatic" else phases)
                rows.append(row)
                print(f"| {row['springs']:,} | {row['launch']} | {name} | {r / 1e9:.3g} | {row['ratio']:.2f}× | "
                      f"{row['phases'] or '–'} |")
        repeats = 2 if args.quick else args.repeats
        print(f"\nlaunch profile, {sims['every step'].net.n_springs:,} springs, conduction every step "
              f"(µs per launch, {repeats} back to back):\n")
        print("| launch | elements | host µs | wall µs |")
        print("|---|---:|---:|---:|")
        for row in launch_profile(sims["every step"], cuda, repeats):
            rows.append(dict(springs=sims["every step"].net.n_springs, **row))
            print(f"| {row['launch']} | {row['elements']:,} | {row['host_us']:.1f} | {row['wall_us']:.1f} |")
    if args.quick:
        print("(quick: timings mean nothing)")
    return rows


if __name__ == "__main__":
    main()
