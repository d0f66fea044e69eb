"""What Fourier conduction costs per step: CO2 with conduction against the same thermal run
without it (adiabatic), on a jittered 6-neighbour lattice and on a gmsh tetrahedral bar, with
one thread (serial kernels) and the default thread count; and with multirate conduction
(``conduction_every = "auto"``) on two parts run as users run them: a steel part in SI units at
the explicit stable step and the thermal-shock scene.

    python benchmarks/heat_cost.py [--cells 32] [--mesh-size 0.06] [--steps 200] [--repeats 5]
    python benchmarks/heat_cost.py --cells 69 --mesh-size 0.03 --steps 20 --repeats 3   # ~1e6
    python benchmarks/heat_cost.py --nets lattice,tetra --passes 9   # and each pass of a conducting step alone
    python benchmarks/heat_cost.py --quick        # a smoke run (tests/test_benchmarks.py runs it)

Per net and thread count the runs alternate once per repeat after a warm-up (adiabatic,
conduction every step, conduction every step with g = 0, the sweeps alone, conduction "auto"),
so that drifts of a shared machine hit all alike; times are medians over the repeats and the
ratio is the median of the per-repeat ratios. "g = 0" runs conduction's step with nothing to
exchange (the schedule's own cost: a refresh of the forces after the sweeps, the deferred kick's
second force sum, the entropy update); "sweeps" times the two half sweeps of one step boundary
alone (``conduction_sweep``, reverse then forward over h/2, on a copy of the state). Also
reported: the grid-wide phases per step a GPU runs for conduction, with the earlier pairwise
sweep (2 × (pair colours + 3)) and with node stars as the GPU runs them (:func:`gpu_phases`:
2 j node colours a boundary, less one where the two halves' meeting colours run as one phase,
divided by k). On a part where "auto" takes sub-sweeps (j > 1), the cycle it would take with one sweep per
boundary runs too, interleaved ("one sweep"). With ``--passes ROUNDS`` each pass of the conducting
step (spring pass, with and without keeping θ, l and the strain; node pass with one and two force
sums; the star exchanges; the refresh; the entropy update) is also timed alone, interleaved
(:func:`pass_seconds`), with what a step boundary adds by its passes, in adiabatic steps. Targets: the whole step ≤ 2× the adiabatic thermal
step with conduction every step, ≤ 1.25× with "auto" on the parts.
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

import thermonet as tn
from thermonet.explicit.codes import FORCE_DEFERRED, FORCE_GATHER
from thermonet.heat.graph import pair_graph, pairs_per_spring
from thermonet.heat.passes import DEFER_FINISH, FORWARD, REVERSE, heat_kernels
from thermonet.kernels import records
from thermonet.scenes.scene import load_scene
from thermonet.stability import stable_step

PARAMETERS = dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0)
G = 1.0
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


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
    """(adiabatic, conduction every step, the same with g = 0, conduction "auto") simulations of
    ``net``: same parameters, temperatures (300 ± 50, seeded), velocities and step (0.4× the
    adiabatic CO2 stability limit)."""
    rng = np.random.default_rng(1)
    theta = 300.0 + rng.uniform(-50.0, 50.0, net.n_springs)
    v = rng.uniform(-0.01, 0.01, (net.n_nodes, 3))
    common = dict(model="hencky", temperatures=theta, velocities=v, integrator="co2", threads=threads,
                  energy_tolerance=None, stability_guard="off")
    adiabatic = tn.Simulation(net, parameters=PARAMETERS, h=1.0, **common)
    h = 0.4 * stable_step(adiabatic)["h_max"]
    adiabatic.h = h
    conduction = tn.Simulation(net, parameters={**PARAMETERS, "g": G}, conduction=True, h=h, conduction_every=1,
                               **common)
    empty = tn.Simulation(net, parameters={**PARAMETERS, "g": 0.0}, conduction=True, h=h, conduction_every=1,
                          **common)
    auto = tn.Simulation(net, parameters={**PARAMETERS, "g": G}, conduction=True, h=h, **common)
    return adiabatic, conduction, empty, auto


def step_seconds(sim, steps: int) -> float:
    t0 = time.perf_counter()
    sim.run(steps=steps, diagnostics_every=steps)
    return (time.perf_counter() - t0) / steps


class Sweeps:
    """The two half sweeps of one step boundary (reverse then forward, over h/2 each) on a copy
    of the state of ``sim``."""

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
        self.tau = 0.5 * sim.h
        self.record = self.heat.record(self.tau, self.heat.new_logs())

    def seconds(self) -> float:
        np.copyto(self.theta, self.theta0)
        t0 = time.perf_counter()
        self.sweep(self.record, self.theta, self.theta_start, self.eta, self.tau, 0.0, FORWARD | REVERSE)
        return time.perf_counter() - t0


#: the passes :func:`pass_seconds` times, in the order of its table
PASSES = ("spring pass", "spring pass keeping θ, l, L", "node pass", "node pass, deferred kick", "star exchanges",
          "exchanges + θ copy + entropy update", "refresh", "entropy update + refresh")


def pass_seconds(sim, rounds: int, calls: int) -> dict:
    """Each pass of a conducting CO2 step of ``sim`` (conduction every step) called alone, from the
    arguments its kernel took in a step (so the kernel variant its runs compiled): seconds per
    call, the median over ``rounds`` rounds of ``calls`` calls of each in turn. Kicks and drifts
    of 0 (momenta and positions stay; θ, η and the scratch change, so ``sim`` is spent
    afterwards). Keys: :data:`PASSES`."""
    from thermonet.explicit.cpu import kernel_passes

    stepper = sim.stepper
    kernel = stepper._advance
    taken = []
    stepper._advance = lambda *a: taken.append(a) or kernel(*a)
    try:
        sim.run(steps=2, diagnostics_every=2)
    finally:
        stepper._advance = kernel
    state, scratch, topology, springs, nodes, _, _, heat, run, loads = taken[-1]
    ns = kernel_passes(kernel)
    x, x_new, p, eta, phi = state.x, scratch.x_buf, state.p, state.eta, state.phi
    none = records.KickDrift(0.0, 0.0, 0.0, True)
    tau = 0.5 * run.h
    theta, start = scratch.theta_keep, heat.theta_start
    calls_of = {
        "spring pass": lambda: ns["spring_pass"](x, eta, phi, topology, springs, scratch, (0.0, 0.0), run, False,
                                                 heat.length, heat.strain),
        "spring pass keeping θ, l, L": lambda: ns["spring_pass"](x, eta, phi, topology, springs, scratch, (0.0, 0.0),
                                                                 run, True, heat.length, heat.strain),
        "node pass": lambda: ns["node_pass"](x, x_new, p, topology, nodes, scratch, none, np.int64(FORCE_GATHER),
                                             False, (heat.s_before, loads)),
        "node pass, deferred kick": lambda: ns["node_pass"](x, x_new, p, topology, nodes, scratch, none,
                                                            np.int64(FORCE_DEFERRED), False, (heat.s_before, loads)),
        "star exchanges": lambda: ns["conduction_sweep"](heat, theta, start, eta, tau, 0.0,
                                                         FORWARD | REVERSE | DEFER_FINISH),
        "exchanges + θ copy + entropy update": lambda: ns["conduction_sweep"](heat, theta, start, eta, tau, 0.0,
                                                                              FORWARD | REVERSE),
        "refresh": lambda: ns["refresh_pass"](theta, heat.length, heat.strain, True, phi, springs, scratch.s,
                                              (0.0, 0.0), run),
        "entropy update + refresh": lambda: ns["finish_refresh_pass"](heat, theta, eta, phi, springs, scratch.s,
                                                                      (0.0, 0.0), run, True),
    }
    for name in PASSES:  # (a first call from Python may compile or load its entry point)
        calls_of[name]()
    samples = {name: [] for name in PASSES}
    for _ in range(rounds):
        for name in PASSES:
            call = calls_of[name]
            t0 = time.perf_counter()
            for _ in range(calls):
                call()
            samples[name].append((time.perf_counter() - t0) / calls)
    return {name: statistics.median(v) for name, v in samples.items()}


def boundary_in_steps(passes: dict) -> float:
    """What a step boundary adds by its passes alone, in adiabatic steps (spring pass + node pass):
    keeping θ, l, L; the star exchanges; the entropy update fused with the refresh; the deferred
    kick's second force sum."""
    step = passes["spring pass"] + passes["node pass"]
    extra = (passes["spring pass keeping θ, l, L"] - passes["spring pass"] + passes["star exchanges"]
             + passes["entropy update + refresh"] + passes["node pass, deferred kick"] - passes["node pass"])
    return extra / step


def gpu_phases(net: tn.Net, sim) -> tuple[int, int]:
    """Grid-wide phases per step of conduction on the GPU: (pairwise sweeps, node-star sweeps at
    the run's k and sub-sweeps j). A cycle boundary inside a call runs 2j half sweeps, each its
    node colours and, where the net has baths or sources, their phase; with j = 1 and none, the
    meeting colours of the reverse and forward half as one phase (thermonet.heat.cuda.conduction_plan);
    no start or finish phases (the kicks' spring passes do their work); divided by k."""
    heat = sim.system.heat
    pairs = pair_graph(sim.system.layout, heat.conductance[None, :], junction=heat.bath_nodes < 0)
    stars = heat.star_order("cuda")
    k, j = (sim.conduction_cycle.k, sim.conduction_cycle.sweeps) if sim.conduction_cycle else (1, 1)
    entries = 1 if len(heat.entry_spring) > 0 else 0
    meet = 1 if j == 1 and not entries and stars.n_colours > 1 else 0
    return 2 * (pairs.n_colours + 3), (2 * j * (stars.n_colours + entries) - meet) / k


def measure(name: str, net: tn.Net, threads: int | None, steps: int, repeats: int, passes: int = 0) -> dict:
    """The runs of one net at one thread count, interleaved; with ``passes`` > 0 also each pass
    of the conducting step alone (:func:`pass_seconds`, that many rounds, afterwards: it spends
    the conducting simulation)."""
    adiabatic, conduction, empty, auto = simulations(net, threads)
    sweeps = Sweeps(conduction)
    runs = {"adiabatic": adiabatic, "conduction": conduction, "schedule": empty, "auto": auto}
    for sim in runs.values():  # warm-up: compile or load the kernels, touch the memory
        sim.run(steps=steps, diagnostics_every=steps)
    sweeps.seconds()
    samples = {k: [] for k in (*runs, "sweeps")}
    for _ in range(repeats):
        for key, sim in runs.items():
            samples[key].append(step_seconds(sim, steps))
        samples["sweeps"].append(statistics.median(sweeps.seconds() for _ in range(3)))
    order = conduction.system.heat.star_order("cpu")
    pair_phases, star_phases = gpu_phases(net, auto)
    timed_passes = pass_seconds(conduction, passes, 10) if passes else None
    return {
        "passes": timed_passes,
        "net": name, "springs": net.n_springs, "threads": threads or numba.config.NUMBA_NUM_THREADS,
        "kernels": "parallel" if conduction.parallel else "serial",
        "blocks": order.n_blocks, "colours": order.n_colours, "k": auto.conduction_cycle.k,
        "sweeps_auto": auto.conduction_cycle.sweeps,
        "gpu_pair_phases": pair_phases, "gpu_star_phases": star_phases,
        **{k: statistics.median(v) for k, v in samples.items()},
        "ratio": statistics.median(c / a for a, c in zip(samples["adiabatic"], samples["conduction"])),
        "auto_ratio": statistics.median(c / a for a, c in zip(samples["adiabatic"], samples["auto"])),
    }


def part_simulations(scene_path: str, overrides, threads: int | None, one_sweep: int | None = None):
    """(adiabatic, auto) simulations of a scene: its own step and outputs, conduction "auto";
    the adiabatic one with conduction and baths switched off; with ``one_sweep`` = k also the
    scene with conduction every k steps and one sweep per boundary."""
    from thermonet.scenes.build import build_scene

    extra = [f"integrator.threads={threads}"] if threads else []
    auto = build_scene(load_scene(scene_path, list(overrides) + extra)).simulation
    off = list(overrides) + extra + ["effects.conduction=false", "baths={}", "sources={}"]
    adiabatic = build_scene(load_scene(scene_path, off)).simulation
    sims = [adiabatic, auto]
    if one_sweep is not None:
        sims.append(build_scene(load_scene(scene_path, list(overrides) + extra
                                           + [f"effects.conduction_every={one_sweep}"])).simulation)
    for sim in sims:
        sim.energy_tolerance = None
        sim.stability_guard.active = False
    return tuple(sims)


def measure_part(name: str, scene_path: str, overrides, threads, steps: int, repeats: int, cadence: int) -> dict:
    """The part's "auto" against its adiabatic run, and where "auto" takes sub-sweeps, the cycle it
    would take with one sweep per boundary ("one sweep")."""
    from thermonet.heat.multirate import one_sweep_cycle

    adiabatic, auto = part_simulations(scene_path, overrides, threads)
    auto.run(steps=steps, diagnostics_every=cadence)
    runs = {"adiabatic": adiabatic, "auto": auto}
    one_k = None
    if auto.conduction_cycle.sweeps > 1:
        one_k = one_sweep_cycle(auto.system.heat.fastest_rate(), auto.h, [cadence, steps])
        runs["one sweep"] = part_simulations(scene_path, overrides, threads, one_k)[2]
    for sim in runs.values():
        sim.run(steps=steps, diagnostics_every=cadence)
    samples = {k: [] for k in runs}
    for _ in range(repeats):
        for key, sim in runs.items():
            t0 = time.perf_counter()
            sim.run(steps=steps, diagnostics_every=cadence)
            samples[key].append((time.perf_counter() - t0) / steps)
    ratio = {k: statistics.median(c / a for a, c in zip(samples["adiabatic"], v)) for k, v in samples.items()}
    return {"net": name, "springs": auto.net.n_springs, "threads": threads or numba.config.NUMBA_NUM_THREADS,
            "kernels": "parallel" if auto.parallel else "serial", "h": auto.h, "k": auto.conduction_cycle.k,
            "sweeps_auto": auto.conduction_cycle.sweeps, "why": auto.conduction_cycle.why,
            **{k: statistics.median(v) for k, v in samples.items()},
            "auto_ratio": ratio["auto"], "one_sweep_k": one_k, "one_sweep_ratio": ratio.get("one sweep")}


STEEL = ["materials.bracket.youngs_modulus=200e9", "materials.bracket.thermal_expansion=12e-6",
         "materials.bracket.density=7850.0", "materials.bracket.heat_capacity=3.6e6",
         "materials.bracket.conductivity=50.0"]


def main(argv=None) -> tuple[list, list]:
    """Run the benchmark (``argv``: its command line); returns its rows (lattice and tetrahedra)
    and parts (steel, thermal shock) as dicts."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=32, help="lattice cells per axis (32: about 1e5 springs)")
    ap.add_argument("--mesh-size", type=float, default=0.06, help="gmsh size of the tetrahedral bar "
                    "(0.06: about 1.2e5 springs)")
    ap.add_argument("--steps", type=int, default=200, help="steps per timed run")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--threads", default="1,default", help="comma-separated thread counts ('default': Numba's)")
    ap.add_argument("--nets", default="lattice,tetra,steel,shock")
    ap.add_argument("--passes", type=int, default=0, metavar="ROUNDS",
                    help="also time each pass of a conducting step alone on the lattice and tetrahedra "
                         "(ROUNDS rounds of 10 calls each, interleaved; 9 is enough)")
    ap.add_argument("--quick", action="store_true", help="small nets, few steps, one repeat (a smoke run)")
    args = ap.parse_args(argv)
    if args.quick:
        args.cells, args.mesh_size, args.steps, args.repeats, args.threads = 6, 0.5, 20, 1, "1"
        args.passes = args.passes or 1
    steel_h = None
    rows, parts = [], []
    for which in args.nets.split(","):
        t0 = time.perf_counter()
        if which in ("lattice", "tetra"):
            if which == "lattice":
                net, name = tn.lattice((args.cells,) * 3, neighbours=6, jitter=0.1, seed=1), \
                    f"lattice {args.cells}³ (6 neighbours)"
            else:
                net, name = tetra_bar(args.mesh_size), f"gmsh tetra bar, size {args.mesh_size:g}"
            print(f"built {which}: {net.n_springs} springs in {time.perf_counter() - t0:.1f} s", flush=True)
            for t in args.threads.split(","):
                rows.append(measure(name, net, None if t == "default" else int(t), args.steps, args.repeats,
                                    args.passes))
                print(rows[-1], flush=True)
            continue
        if which == "steel":  # the bracket in steel at 0.9× the explicit stable step
            path = os.path.join(ROOT, "scenes", "bracket.toml")
            if steel_h is None:  # at most 0.9× the stable step, a whole number of steps to the scene's t_end
                probe = part_simulations(path, STEEL, 1)[0]
                t_end = load_scene(path).data["integrator"]["t_end"]
                steel_h = t_end / math.ceil(t_end / (0.9 * stable_step(probe)["h_max"]))
            overrides, name, cadence = STEEL + [f"integrator.h={steel_h!r}"], "steel bracket (SI, 5 mm tetrahedra)", 100
        else:
            path, overrides, name, cadence = os.path.join(ROOT, "scenes", "thermal_shock.toml"), [], \
                "scenes/thermal_shock.toml", 10
        for t in args.threads.split(","):
            steps = max(cadence, args.steps // cadence * cadence)
            parts.append(measure_part(name, path, overrides, None if t == "default" else int(t), steps,
                                      args.repeats, cadence))
            print(parts[-1], flush=True)
    load = os.getloadavg()[0]
    print(f"\nco2, hencky, {args.steps} steps per run, {args.repeats} interleaved repeats, {os.cpu_count()} cores, "
          f"load average {load:.2f}\n")
    if rows:
        print(f"g = {G}, h = 0.4× the adiabatic stable step:\n")
        print("| net | springs | threads | CPU blocks / colours | adiabatic ms/step | conduction ms/step | ratio "
              "| g = 0 ms/step | sweeps ms/step | auto: k (j) | auto ratio | GPU phases/step: pairs → stars |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for r in rows:
            print(f"| {r['net']} | {r['springs']:,} | {r['threads']} ({r['kernels']}) | {r['blocks']} / {r['colours']} "
                  f"| {1e3 * r['adiabatic']:.3g} | {1e3 * r['conduction']:.3g} | **{r['ratio']:.2f}×** | "
                  f"{1e3 * r['schedule']:.3g} | {1e3 * r['sweeps']:.3g} | {r['k']} ({r['sweeps_auto']}) | "
                  f"{r['auto_ratio']:.2f}× | "
                  f"{r['gpu_pair_phases']} → {r['gpu_star_phases']:.3g} |")
    timed = [r for r in rows if r["passes"]]
    if timed:
        print("\nEach pass of a conducting step alone, ms per call (median of the rounds; the kernel variant the "
              "runs above compiled):\n")
        print("| net | threads | " + " | ".join(PASSES) + " | a boundary by its passes, adiabatic steps |")
        print("|---|---:|" + "---:|" * (len(PASSES) + 1))
        for r in timed:
            print(f"| {r['net']} | {r['threads']} ({r['kernels']}) | "
                  + " | ".join(f"{1e3 * r['passes'][name]:.3g}" for name in PASSES)
                  + f" | {boundary_in_steps(r['passes']):.2f} |")
    if parts:
        print("\nconduction_every = \"auto\" on parts run as users run them:\n")
        print("| part | springs | threads | h | k (j) | adiabatic ms/step | auto ms/step | ratio "
              "| one sweep per boundary: k, ratio |")
        print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
        for r in parts:
            one = f"{r['one_sweep_k']}, {r['one_sweep_ratio']:.2f}×" if r["one_sweep_k"] else "–"
            print(f"| {r['net']} | {r['springs']:,} | {r['threads']} ({r['kernels']}) | {r['h']:.3g} | "
                  f"{r['k']} ({r['sweeps_auto']}) | "
                  f"{1e3 * r['adiabatic']:.3g} | {1e3 * r['auto']:.3g} | **{r['auto_ratio']:.2f}×** | {one} |")
    return rows, parts


if __name__ == "__main__":
    main()
