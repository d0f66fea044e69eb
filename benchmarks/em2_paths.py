"""EM2's Newton paths against the step: where "auto" should switch from the compiled path's
matrix-free sweeps to the sparse path's SuperLU.

For each net and each step h = factor × CO2's stable step (h·ω_max = 2 factor), runs EM2 on
each path and prints milliseconds per step, Newton iterations per step, the steps redone as
substeps and the steps solved by continuation, the path "auto" chose (and its reason), and the
simulated time per wall time against CO2's at 0.9× its stable step on the same net (> 1: EM2
gets through simulated time faster):

- ``sweeps``: ``newton_path = "compiled"`` (inertia-preconditioned matrix-free sweeps);
- ``splu``: ``newton_path = "sparse"``, ``linear_solver = "splu"`` (a factorization per iteration);
- ``splu-reuse``: ``newton_path = "sparse"``, ``linear_solver = "splu-reuse"`` (kept factorizations
  in single precision; on large nets solved on their elimination tree once the run has made 60
  solves with SuperLU's own solve);
- ``splu-reuse-double`` (not run unless named): the same with double-precision factors;
- ``splu-reuse-superlu``, ``splu-reuse-tree`` (not run unless named): ``splu-reuse`` always with
  SuperLU's own solves, and switching to the tree on a net of any size (the tree solve's A/B);
- ``auto``: the default.

Nets: ``part``, the steel L-bracket of examples/steel_bracket.py meshed by gmsh at ``--mesh-size``
(tetrahedra; 0.003 m: 9 270 springs, 0.0012 m: 97 958), slowly heated through its bolted base
(a bath ramping 293.15 → 393.15 K over a second) and slowly pushed on its flange's top face (a
force ramping to 2 kN over a second), with conduction: the quasi-static use EM2 is meant for;
``lattice``, a jittered 18-neighbour 3D lattice of ``--cells`` cells per side (hencky,
c = 100, θ0 = 300), its bottom face clamped, at rest and 50 K above θ0 (thermal stress, a slow
expansion; with 6 neighbours the cubic cells would be mechanisms, held only by the springs'
tension); ``bracket``, scenes/bracket.toml (a gmsh tetrahedral aluminium part, SI units, hot
flange, conduction). The paths of one net and step run interleaved: ``--warmup`` untimed steps each (default: one
round's ``--steps``; compilation, first factorization), then ``--rounds`` rounds of ``--steps`` steps of each path
in turn, ms/step the median over the rounds; a path that fails a step is reported as failed.

    python benchmarks/em2_paths.py                        # both nets, factors 1 3 10 100 1e4
    python benchmarks/em2_paths.py --nets bracket --factors 1 2 3 5 10
    python benchmarks/em2_paths.py --quick                # a small lattice, 2 steps (the test's)
    python benchmarks/em2_paths.py --scenes               # substepped steps on the shipped scenes, 10× and 100×
    python benchmarks/em2_paths.py --nets part --mesh-size 0.003 --threads 1 2 --factors 10 100 1e4

``--threads``: each measurement at each thread count (``integrator.threads``; 1: the serial kernels).
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
import warnings

import numpy as np

import thermonet as tn
from thermonet.stability import stable_step

HERE = os.path.dirname(os.path.abspath(__file__))
#: CO2's step in the speed-up column: this fraction of its stable step (the step policy's SAFETY)
CO2_FRACTION = 0.9
PATHS = {
    "sweeps": dict(newton_path="compiled"),
    "splu": dict(newton_path="sparse", linear_solver="splu"),
    "splu-reuse": dict(newton_path="sparse", linear_solver="splu-reuse"),
    # (the kept factors never solved on their elimination tree, thermonet.solvers.tree_solve,
    # always SuperLU's own solve: the A/B against splu-reuse, which switches to it)
    "splu-reuse-superlu": dict(newton_path="sparse", linear_solver="splu-reuse"),
    # (the same switch on a net of any size: the A/B below TREE_MIN_UNKNOWNS)
    "splu-reuse-tree": dict(newton_path="sparse", linear_solver="splu-reuse"),
    # (kept factors in double precision: the A/B of splu-reuse's single-precision factors)
    "splu-reuse-double": dict(newton_path="sparse", linear_solver="splu-reuse-double"),
    "auto": {},
}
#: the paths measured unless --paths names others
DEFAULT_PATHS = ("sweeps", "splu", "splu-reuse", "auto")


def lattice_simulation(cells: int, integrator: str, h: float, **options) -> tn.Simulation:
    """The benchmark's lattice: bottom face clamped, at rest, 50 K above θ0."""
    net = tn.lattice((cells, cells, cells), neighbours=18, jitter=0.1, seed=1)
    anchored = net.positions[:, 2] < 0.5
    net = tn.Net(net.positions, net.edges, net.masses, anchored)
    return tn.Simulation(net, model="hencky", parameters=dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0),
                         temperatures=350.0, integrator=integrator, h=h, integrator_options=options,
                         stability_guard="off", energy_tolerance=None, threads=THREADS[0])


def bracket_simulation(integrator: str, h: float, **options) -> tn.Simulation:
    """scenes/bracket.toml with the given integrator, step and Newton options."""
    from thermonet.scenes.build import build_scene
    from thermonet.scenes.scene import load_scene

    sets = [f"integrator.name={integrator}", f"integrator.h={h!r}", "integrator.check_step=false",
            f"integrator.t_end={h * 1000!r}"] + [f"integrator.{k}={v}" for k, v in options.items()]
    sets += [f"integrator.threads={THREADS[0]}"] if THREADS[0] else []
    return build_scene(load_scene(os.path.join(HERE, "..", "scenes", "bracket.toml"), sets)).simulation


#: the steel part (``part``): examples/steel_bracket.py's material and base bath, a force on the
#: flange's top face; the mesh at {mesh}, the step {h}, the threads {threads}
PART_SCENE = """name = "steel_part"
[net]
mesh = "{mesh}"
[materials.bracket]
model = "hencky"
youngs_modulus = 200e9
thermal_expansion = 12e-6
density = 7850.0
heat_capacity = 3.6e6
conductivity = {conductivity!r}
theta0 = 293.15
[initial.temperature]
uniform = 293.15
[effects]
thermal = true
conduction = true
anchors = ["clamp"]
{effects}
[baths.machine]
group = "clamp"
temperature = {{ start = 293.15, end = 393.15, duration = {duration!r} }}
[loads.push]
type = "force"
group = "top"
force = {{ start = 0.0, end = 2000.0, duration = {duration!r} }}
direction = [1, 0, 0]
total = true
[integrator]
name = "{integrator}"
h = {h!r}
t_end = {t_end!r}
check_step = false
energy_tolerance = false
{threads}
{options}
[output]
frames_every = 1000000
diagnostics_every = {diagnostics}
checkpoint_every = 0
"""
#: the part's meshes made so far, by size (a temporary folder per process)
_PART_MESHES: dict = {}


def part_mesh(size: float) -> str:
    """The part's mesh at gmsh size ``size`` (m): meshes/make_meshes.py's bracket with the node
    groups "clamp" (the bolted end face) and "top" (the flange's top face); made once per size."""
    if size in _PART_MESHES:
        return _PART_MESHES[size]
    import tempfile

    import gmsh

    path = os.path.join(tempfile.mkdtemp(prefix="em2_part_"), f"part_{size:g}.msh")
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.model.add("part")
        occ = gmsh.model.occ
        base = occ.addBox(0, 0, 0, 0.06, 0.04, 0.006)
        flange = occ.addBox(0, 0, 0.006, 0.006, 0.04, 0.046)
        occ.fragment([(3, base)], [(3, flange)])
        occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMin", size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.model.addPhysicalGroup(3, [t for _, t in gmsh.model.getEntities(3)], name="bracket")
        box = gmsh.model.getEntitiesInBoundingBox
        gmsh.model.addPhysicalGroup(2, [t for _, t in box(0.0599, -1e-4, -1e-4, 0.0601, 0.0401, 0.0061, dim=2)],
                                    name="clamp")
        gmsh.model.addPhysicalGroup(2, [t for _, t in box(-1e-4, -1e-4, 0.0519, 0.0061, 0.0401, 0.0521, dim=2)],
                                    name="top")
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.option.setNumber("Mesh.RandomSeed", 1)
        gmsh.model.mesh.generate(3)
        gmsh.write(path)
    finally:
        gmsh.finalize()
    _PART_MESHES[size] = path
    return path


def part_simulation(size: float, integrator: str, h: float, threads: int | None = None, conductivity: float = 45.0,
                    duration: float = 1.0, diagnostics: int = 1000000, **options) -> tn.Simulation:
    """The steel part (``part``) at mesh size ``size``, step h, ``threads`` (None: Numba's
    default), the given Newton options; the conductivity (W/(m K)) and the ramps' duration (s)
    may be changed (em2_accuracy.py)."""
    from thermonet.scenes.build import build_scene
    from thermonet.scenes.scene import scene_from_text

    h = float(h)
    text = PART_SCENE.format(mesh=part_mesh(size), integrator=integrator, h=h, t_end=h * max(1000, math.ceil(duration / h)),
                             conductivity=float(conductivity), duration=float(duration), diagnostics=diagnostics,
                             effects=f"conduction_every = {options.pop('conduction_every')}"
                             if "conduction_every" in options else "",
                             threads=f"threads = {threads}" if threads else "",
                             options="\n".join(f"{k} = {v!r}".replace("'", '"') for k, v in options.items()))
    return build_scene(scene_from_text(text)).simulation


def scene_simulation(name: str, integrator: str, h: float, steps: int) -> tn.Simulation:
    """A shipped scene (scenes/<name>.toml) with the given integrator and step, t_end ``steps`` steps."""
    from thermonet.scenes.build import build_scene
    from thermonet.scenes.scene import load_scene

    sets = [f"integrator.name={integrator}", f"integrator.h={h!r}", "integrator.check_step=false",
            f"integrator.t_end={h * steps!r}"]
    return build_scene(load_scene(os.path.join(HERE, "..", "scenes", f"{name}.toml"), sets)).simulation


#: the part's mesh size and the threads of the measurement under way (main's --mesh-size, --threads)
MESH_SIZE = [0.003]
THREADS = [None]
SCENES = ("lattice2d", "chain", "triangle", "default", "spinning_lattice", "thermal_shock", "tensile", "bracket")


def scene_fractions(names, factors, steps: int, out=print) -> list[dict]:
    """EM2 ("auto") on shipped scenes at each factor × CO2's stable step there (estimated at the
    scene's initial state): ``steps`` steps each, the steps redone as substeps, the steps solved
    by continuation, Newton iterations per step, wall seconds, or the failure."""
    out("| scene | springs | factor | h | steps run | substepped | most substeps | continued | Newton it./step "
        "| path | wall s | failure |")
    out("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---|")
    rows = []
    for name in names:
        probe = scene_simulation(name, "co2", 1e-7 if name == "bracket" else 1e-3, 1)
        h_max = stable_step(probe)["h_max"]
        for factor in factors:
            sim = scene_simulation(name, "em2", factor * h_max, steps)
            failure = ""
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                try:
                    sim.run(steps=steps, diagnostics_every=max(1, steps // 10))
                except tn.SimulationError as exc:
                    failure = str(exc).split(";")[0]
            wall = time.perf_counter() - t0
            s = sim.stepper.summary()
            rows.append(dict(scene=name, factor=factor, summary=s, failure=failure))
            out(f"| {name} | {sim.net.n_springs} | {factor:g} | {sim.h:.3g} | {s['steps']} | {s['retried_steps']} "
                f"({100 * s['substep_fraction']:.0f} %) | {s['substeps_max']} | {s['continued_steps']} | "
                f"{s['iterations_mean']:.1f} | {s['linear_solver']} | {wall:.1f} | {failure[:90]} |")
    return rows


def make(net: str, cells: int, integrator: str, h: float, **options) -> tn.Simulation:
    if net == "part":
        return part_simulation(MESH_SIZE[0], integrator, h, THREADS[0], **options)
    if net == "lattice":
        return lattice_simulation(cells, integrator, h, **options)
    return bracket_simulation(integrator, h, **options)


def run_paths(net: str, cells: int, h: float, paths, steps: int, rounds: int, co2=None, co2_steps: int = 0,
              warmup: int | None = None) -> list[dict]:
    """The paths at one step, interleaved (a drift of a shared machine hits all alike): each
    simulation takes ``warmup`` untimed steps (None: ``steps``, so that every timed call starts on a
    multiple of ``steps`` and "auto" conduction may take a cycle dividing it; compilation, first
    factorization), then ``rounds``
    rounds each time ``steps`` steps of every path in turn, and ``co2_steps`` of the CO2
    simulation ``co2`` where given; ms/step is the median over the rounds. Returns a row per
    path: ms/step, CO2's ms/step in the same rounds (``co2_ms``) and the stepper's summary (or
    the failure)."""
    sims = {path: make(net, cells, "em2", h, **PATHS[path]) for path in paths}
    if "splu-reuse-superlu" in sims:
        sims["splu-reuse-superlu"].stepper.solver.tree_after = math.inf
        sims["splu-reuse-superlu"].stepper.solver.tree_after_laid_out = math.inf
    if "splu-reuse-tree" in sims:
        sims["splu-reuse-tree"].stepper.solver.tree_min_unknowns = 0
    times = {path: [] for path in paths}
    co2_times = []
    failed = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # substeps are reported in the table
        for r in range(rounds + 1):
            for path, sim in sims.items():
                if path in failed:
                    continue
                try:
                    t0 = time.perf_counter()
                    sim.run(steps=(warmup or steps) if r == 0 else steps, diagnostics_every=10**9)
                    if r:
                        times[path].append((time.perf_counter() - t0) / steps)
                except tn.SimulationError as exc:
                    failed[path] = str(exc).split(";")[0]
            if co2 is not None and r:
                t0 = time.perf_counter()
                co2.run(steps=co2_steps, diagnostics_every=10**9)
                co2_times.append(1e3 * (time.perf_counter() - t0) / co2_steps)
    co2_ms = statistics.median(co2_times) if co2_times else math.nan
    return [dict(path=path, failed=failed.get(path), co2_ms=co2_ms,
                 ms=math.inf if path in failed else 1e3 * statistics.median(times[path]),
                 summary=sim.stepper.summary(), springs=sim.net.n_springs) for path, sim in sims.items()]


def measure(nets, cells: int, factors, steps: int, paths=DEFAULT_PATHS, out=print,
            sweeps_max_factor: float = math.inf, rounds: int = 3, warmup: int | None = None) -> list[dict]:
    """The table's rows: per net and factor, each path's row (``run_paths``) with net, factor,
    springs, h and h·ω_max added; prints them as a markdown table."""
    rows = []
    out("| net | springs | factor | h·ω_max | path | ms/step | Newton it./step | substepped | continued "
        "| factorizations (kept) | auto chose | simulated time per wall time ÷ CO2's |")
    out("|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---|---:|")
    for net in nets:
        est = stable_step(make(net, cells, "co2", 1.0 if net == "lattice" else 1e-7))
        co2 = make(net, cells, "co2", CO2_FRACTION * est["h_max"])
        # its stable-step guard off: its 0.1 s allowance and 5 % of the running time are a large
        # share of the few short calls timed here (a re-estimate of ω_max, a Lanczos run, cost 4×
        # CO2's step time on the bracket)
        co2.stability_guard.active = False
        n_co2 = max(20, 20 * steps)
        # warmed up by a whole round: its calls then start on multiples of n_co2, so that "auto"
        # conduction may take a cycle k dividing n_co2, as a run's would divide its output
        # cadences (after a 1-step warm-up every call started on an odd step: k = 1)
        co2.run(steps=n_co2, diagnostics_every=10**9)
        for factor in factors:
            h = factor * est["h_max"]
            if "sweeps" in paths and factor > sweeps_max_factor:
                out(f"| {net} | | {factor:g} | {h * est['omega_max']:.3g} | sweeps | not run (above "
                    f"--sweeps-max-factor {sweeps_max_factor:g}) | | | | | | |")
            done = run_paths(net, cells, h, [p for p in paths if p != "sweeps" or factor <= sweeps_max_factor],
                             steps, rounds, co2, n_co2, warmup)
            co2_ms = done[0]["co2_ms"]
            co2_rate = co2_ms / (CO2_FRACTION * est["h_max"])  # ms per unit of simulated time
            k = co2.conduction_cycle[0] if co2.conduction_cycle else "–"
            out(f"| {net} | {co2.net.n_springs} | {CO2_FRACTION:g} | {2 * CO2_FRACTION:.3g} | co2 | {co2_ms:.3f} | | | "
                f"| | (CO2 at {CO2_FRACTION:g}× its stable step, conduction every {k} steps, in the same rounds: "
                f"the speed-up column's reference) | 1 |")
            for row in done:
                path = row["path"]
                s = row["summary"]
                row.update(net=net, factor=factor, h=h, h_omega=h * est["omega_max"],
                           speedup=co2_rate / (row["ms"] / h))
                rows.append(row)
                chose = f"{s['linear_solver']}: {s['path_reason']}" if path == "auto" else ""
                if row["failed"]:
                    out(f"| {net} | {row['springs']} | {factor:g} | {row['h_omega']:.3g} | {path} "
                        f"| failed: {row['failed'][:60]} "
                        f"| | | | | {chose} | |")
                    continue
                out(f"| {net} | {row['springs']} | {factor:g} | {row['h_omega']:.3g} | {path} | {row['ms']:.2f} | "
                    f"{s['iterations_mean']:.2f} | {s['retried_steps']}/{s['steps']} | {s['continued_steps']} | "
                    f"{s['factorizations']} ({s['reused_factorizations']}"
                    + (f"; {s['tree_solves']} solves on the tree" if s.get("tree_solves") else "")
                    + f") | {chose} | {row['speedup']:.3g} |")
    return rows


def fastest(rows: list[dict]) -> dict:
    """{(net, factor): the fastest measured path other than auto}, and auto's ratio to it as
    {(net, factor, "auto"): ratio}."""
    best, out = {}, {}
    for r in rows:
        if r["path"] == "auto":
            continue
        key = (r["net"], r["factor"])
        if not math.isfinite(r["ms"]):
            continue
        if key not in best or r["ms"] < best[key]["ms"]:
            best[key] = r
    for r in rows:
        if r["path"] == "auto" and (r["net"], r["factor"]) in best:
            key = (r["net"], r["factor"])
            out[key] = best[key]["path"]
            out[key + ("auto",)] = r["ms"] / best[key]["ms"]
    return out


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--nets", nargs="+", default=["lattice", "bracket"], choices=["part", "lattice", "bracket"])
    ap.add_argument("--mesh-size", nargs="+", type=float, default=[0.003],
                    help="the part's gmsh size(s) in m (0.003: 9 270 springs, 0.0012: 97 958)")
    ap.add_argument("--threads", nargs="+", type=int, default=[0],
                    help="thread counts, each measured in turn (0: Numba's default)")
    ap.add_argument("--cells", type=int, default=8, help="lattice cells per side (8: 6 048 springs)")
    ap.add_argument("--factors", nargs="+", type=float, default=[1, 3, 10, 100, 1e4],
                    help="steps as multiples of CO2's stable step")
    ap.add_argument("--steps", type=int, default=4, help="steps per round")
    ap.add_argument("--rounds", type=int, default=3, help="interleaved rounds (ms/step: their median)")
    ap.add_argument("--warmup", type=int, default=None,
                    help="untimed steps of each path before the rounds (default: a round's --steps)")
    ap.add_argument("--paths", nargs="+", default=list(DEFAULT_PATHS), choices=list(PATHS),
                    help="splu-reuse-superlu: splu-reuse whose kept factors are never solved on their "
                         "elimination tree (an A/B against splu-reuse; give --warmup 110 so that "
                         "splu-reuse's rounds run on the tree); splu-reuse-tree: switches to it on a net "
                         "of any size")
    ap.add_argument("--sweeps-max-factor", type=float, default=1000.0,
                    help="skip the sweeps above this factor (at 1e4× on the bracket a step did not converge "
                         "in 30 iterations of up to 40 sweeps and GMRES each, minutes per step)")
    ap.add_argument("--quick", action="store_true", help="a 3-cell lattice, factors 1 and 100, 2 steps")
    ap.add_argument("--scenes", nargs="*", default=None,
                    help="instead: the substepped steps of EM2 on these shipped scenes (none named: all) at "
                         "--factors (default here 10 100), --steps (default here 50) steps each")
    args = ap.parse_args(argv)
    if args.scenes is not None:
        given = sys.argv[1:] if argv is None else argv
        factors = args.factors if "--factors" in given else [10, 100]
        steps = args.steps if "--steps" in given else 50
        print(f"EM2 on the shipped scenes; load: {os.getloadavg()[0]:.2f} (1-min average), {os.cpu_count()} CPUs\n")
        return scene_fractions(args.scenes or SCENES, factors, steps)
    if args.quick:
        args.nets, args.cells, args.factors, args.steps, args.rounds = ["lattice"], 3, [1, 100], 2, 1
        args.paths = ["sweeps", "splu-reuse", "auto"]
    rows = []
    for size in args.mesh_size if "part" in args.nets else args.mesh_size[:1]:
        for threads in args.threads:
            MESH_SIZE[0], THREADS[0] = size, threads or None
            print(f"\nEM2 per path; {threads or 'default'} thread(s)"
                  + (f", the part at mesh size {size:g} m" if "part" in args.nets else "")
                  + f"; load: {os.getloadavg()[0]:.2f} (1-min average), {os.cpu_count()} CPUs\n")
            part = measure(args.nets, args.cells, args.factors, args.steps, args.paths,
                           sweeps_max_factor=args.sweeps_max_factor, rounds=args.rounds, warmup=args.warmup)
            for r in part:
                r.update(threads=threads, mesh_size=size)
            rows += part
            best = fastest(part) if "auto" in args.paths else {}
            if best:
                print("\n| net | factor | fastest | auto / fastest |\n|---|---:|---|---:|")
                for key, path in best.items():
                    if len(key) == 2:
                        print(f"| {key[0]} | {key[1]:g} | {path} | {best[key + ('auto',)]:.2f} |")
            print(f"(load at the end: {os.getloadavg()[0]:.2f})")
    return rows


if __name__ == "__main__":
    main()
