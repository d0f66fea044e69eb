"""What the implicit integrators cost.

Part 0, ratio (the targets): the per-step cost of each implicit scheme (ho4, gtr-1/2,
and em2 where registered) relative to a CO2 step of the same net, on the paper's chain and on
jittered lattices of ``--sizes`` cells per side (5: 540 springs, 11: 4752, 25: 50 700, 32:
104 544), for each Newton path (``--paths``: compiled, sparse). All simulations of a net are
built and warmed up first, then ``--rounds`` rounds each time a chunk of every simulation in
turn (interleaved: a drift of a shared machine hits all alike); the ratio is the median over
rounds of (implicit step time / CO2 step time of the same round). ``--serial --cpu-time``: all
single-threaded, timed by CPU time (for a shared, oversubscribed machine).

Part 1, scaling: jittered 6-neighbour 3D lattices of about 1e2 … 1e5 springs, random momenta and
temperatures, h = 0.01 (about a fifth of CO2's stability limit there). For GTR-1/2, HO4 and EM2 with
each linear solver: seconds per step, Newton iterations per step (full, linearized ones), Jacobi
finishing steps per step (matfree), linear iterations per solve (matfree: sweeps, the Jacobi
steps' included; gmres: GMRES iterations), the split of a step's time into residual
evaluations, Jacobian assembly (matfree: per-spring coefficients), factorization (gmres:
block-Jacobi set-up) and solve, and the ratio to a CO2 step of the same net in the same
process (the median of six CO2 samples, three before and three after the implicit runs, so that
a drift of a shared machine does not decide the ratio). Steppers run threaded where the
Simulation would (≥ 16384 springs), CO2 included. ``--settle N`` first runs each implicit
simulation N untimed steps: the lattice heats up (strains 0.4–3.9 after 40 steps) and the
predictor's residual grows 10–100× at a few nodes, the later, harder regime of a run.

Part 2, the paper's chain: Newton iterations per step at h ≤ 0.01, and error in positions at
t = 100 against wall time for every integrator (the paper's Fig. 9), to find where HO4 starts
to pay off. The reference is DOP853 at rtol = atol = 1e-13 on Hamilton's equations.

    python benchmarks/implicit_cost.py                    # all parts
    python benchmarks/implicit_cost.py --part ratio --sizes 0 5 11 25 32
    python benchmarks/implicit_cost.py --part ratio --methods em2 --serial --cpu-time
    python benchmarks/implicit_cost.py --part scaling --sizes 3 7 15 32
    python benchmarks/implicit_cost.py --part scaling --sizes 32 --solvers matfree --settle 40
    python benchmarks/implicit_cost.py --part chain
    python benchmarks/implicit_cost.py --part crossover               # dense LU against sweeps (compiled)
    python benchmarks/implicit_cost.py --part study                   # the cost study on the chain
    python benchmarks/implicit_cost.py --quick      # every part, smallest: a smoke run (QUICK below)

Part 3, study: the cost study of docs/paper-reproduction.md (Fig. 9) on the chain, t = 10,
thermonet only: per accuracy, the cheapest of the paper's five integrators and the cheapest run
of each method (CO4 and CO6 included).
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

import thermonet as tn


def lattice_simulation(cells: int, integrator: str, h: float, parallel=None, model="hencky", **options) -> tn.Simulation:
    net = tn.lattice((cells, cells, cells), jitter=0.1, seed=1)
    rng = np.random.default_rng(0)
    return tn.Simulation(
        net, model=model, parameters=dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0),
        temperatures=rng.uniform(300.0, 600.0, net.n_springs), momenta=rng.normal(0.0, 1.0, (net.n_nodes, 3)),
        integrator=integrator, h=h, integrator_options=options, parallel=parallel,
        # the stepping alone: the run-time guards re-check the stable step at every run() call,
        # which in the short chunks timed here cost CO2 more than its steps at 5e4 springs
        stability_guard="off", energy_tolerance=None,
    )


def seconds_per_step(sim: tn.Simulation, steps: int) -> float:
    sim.run(steps=1, diagnostics_every=10**9)  # compile, first factorization, caches
    if hasattr(sim.stepper, "timers"):
        sim.stepper.timers.__init__()
        sim.stepper.totals.update(steps=0, iterations=0)
        sim.stepper.solver.iterations = 0
    t0 = time.perf_counter()
    sim.run(steps=steps, diagnostics_every=10**9)
    return (time.perf_counter() - t0) / steps


def scaling(sizes, steps, h, direct_max_springs, solvers, settle=0, co2_work=3e7):
    """Print the scaling table; returns its rows (dicts). ``co2_work``: spring-steps per CO2 sample."""
    print(f"lattice (k³ cells, 6 neighbours, jitter 0.1), h = {h}, {steps} steps per run"
          + (f" after {settle} untimed steps" if settle else "") + "\n")
    print("| springs | method | solver | ms/step | × CO2 | Newton it./step | Jacobi steps/step | linear it./solve | residual ms | assembly ms | factor. ms | solve ms |")
    print("|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    table = []
    for k in sizes:
        co2 = lattice_simulation(k, "co2", h)
        m = co2.net.n_springs
        n_steps = max(3, min(steps, int(2e6 / m)))
        co2_steps = max(50, int(co2_work / m))  # 3e7: ≈ 0.2 s per sample at 1e5 springs
        samples = [seconds_per_step(co2, co2_steps) for _ in range(3)]
        rows = []
        for method in ("gtr-1/2", "ho4", "em2"):
            for solver in solvers:
                if solver == "splu" and m > direct_max_springs:
                    continue
                sim = lattice_simulation(k, method, h, linear_solver=solver)
                if settle:  # into the later, harder regime of the run (larger predictor residuals)
                    sim.run(steps=settle, diagnostics_every=10**9)
                t = seconds_per_step(sim, 3 if (solver == "splu" and m > 5000) else n_steps)
                s = sim.stepper.summary()
                per = {key: 1e3 * s[f"time_{key}"] / s["steps"] for key in ("residual", "assembly", "factorization", "solve")}
                lin = getattr(sim.stepper.solver, "iterations", None)
                lin = f"{lin / max(1, sim.stepper.timers.linear_solves):.1f}" if lin is not None else "–"
                rows.append((method, solver, t, s, lin, per))
        samples += [seconds_per_step(co2, co2_steps) for _ in range(3)]
        t_co2 = statistics.median(samples)  # three samples before the implicit runs, three after
        print(f"| {m} | co2 | – | {1e3 * t_co2:.3f} | 1 | – | – | – | – | – | – | – |", flush=True)
        for method, solver, t, s, lin, per in rows:
            table.append({"springs": m, "method": method, "solver": solver, "seconds": t, "co2_seconds": t_co2,
                          "summary": s, "linear_per_solve": lin, "split_ms": per})
            print(f"| {m} | {method} | {solver} | {1e3 * t:.2f} | {t / t_co2:.1f} | {s['iterations_mean']:.2f} | "
                  f"{s['jacobi_steps'] / s['steps']:.2f} | {lin} | "
                  f"{per['residual']:.2f} | {per['assembly']:.2f} | {per['factorization']:.2f} | {per['solve']:.2f} |",
                  flush=True)
    return table


def ratio_nets(cells: int, method: str, h: float, parallel, **options) -> tn.Simulation:
    """cells 0: the paper's chain (h = 0.01); else the lattice of ``lattice_simulation``."""
    if cells == 0:
        return tn.chain_simulation(method, h=0.01, integrator_options=options, stability_guard="off",
                                   energy_tolerance=None)
    return lattice_simulation(cells, method, h, parallel=parallel, **options)


def ratio(sizes, h, paths, rounds, seconds, parallel=None, clock=time.perf_counter, methods=("ho4", "gtr-1/2", "em2")):
    """Print the ratio table; returns its rows: net, springs, CO2 seconds per step and
    (method, path) -> ratio."""
    methods = [m for m in methods if m in tn.available_integrators()]
    print(f"per-step cost × CO2 on the same net, median of {rounds} interleaved rounds "
          f"(h = 0.01 on the chain, {h} on the lattices; {'CPU' if clock is time.process_time else 'wall'} time, "
          f"{'serial' if parallel is False else 'threaded from 16384 springs'})\n")
    print("| net | springs | CO2 µs/step | " + " | ".join(f"{m} {p}" for m in methods for p in paths) + " |")
    print("|---|---:|---:|" + "---:|" * (len(methods) * len(paths)))
    rows = []
    for k in sizes:
        sims = {("co2", "-"): ratio_nets(k, "co2", h, parallel)}
        for m in methods:
            for p in paths:
                sims[(m, p)] = ratio_nets(k, m, h, parallel, newton_path=p)
        steps = {}
        for key, sim in sims.items():  # warm-up (compilation) and the chunk size of ~seconds
            sim.run(steps=2, diagnostics_every=10**9)
            n, t = 1, 0.0
            while t < 0.2 * seconds:
                t0 = clock()
                sim.run(steps=n, diagnostics_every=10**9)
                t = clock() - t0
                n *= 2
            steps[key] = max(1, int(n / 2 * seconds / max(t, 1e-9)))
        per = {key: [] for key in sims}
        for _ in range(rounds):
            for key, sim in sims.items():
                t0 = clock()
                sim.run(steps=steps[key], diagnostics_every=10**9)
                per[key].append((clock() - t0) / steps[key])
        co2 = per[("co2", "-")]
        ratios = {(m, p): statistics.median(a / b for a, b in zip(per[(m, p)], co2)) for m in methods for p in paths}
        cells = [f"{r:.1f}" for r in ratios.values()]
        name = "chain" if k == 0 else f"lattice {k}³"
        rows.append({"net": name, "springs": sims[("co2", "-")].net.n_springs, "co2": statistics.median(co2),
                     "ratios": ratios})
        print(f"| {name} | {sims[('co2', '-')].net.n_springs} | {1e6 * statistics.median(co2):.2f} | "
              + " | ".join(cells) + " |", flush=True)
    return rows


def chain(t_end, iterations_t_end=10.0):
    """Print the chain's tables; returns (Newton iteration rows (method, h, mean, max), error rows
    (method, h, error, wall seconds; error None where the run failed))."""
    from thermonet import reference as ref
    from thermonet.paper import CHAIN_MOMENTA, CHAIN_PARAMETERS, CHAIN_TEMPERATURES

    print(f"chain: Newton iterations per step to t = {iterations_t_end:g}")
    print("| method | h | mean | max |\n|---|---:|---:|---:|")
    iterations, errors = [], []
    for method in ("gtr-1/2", "ho4", "em2"):
        for h in (0.01, 0.005, 0.001):
            sim = tn.chain_simulation(method, h=h)
            sim.run(t_end=iterations_t_end, diagnostics_every=10**9)
            s = sim.stepper.summary()
            iterations.append((method, h, s["iterations_mean"], s["iterations_max"]))
            print(f"| {method} | {h} | {s['iterations_mean']:.2f} | {s['iterations_max']} |", flush=True)

    net = tn.chain()
    rnet = ref.ReferenceNet.build(net, "hencky", CHAIN_PARAMETERS)
    eta = rnet.entropies(net.positions, CHAIN_TEMPERATURES)
    start = ref.ReferenceState(net.positions.copy(), CHAIN_MOMENTA.copy(), np.zeros(3), eta)
    t0 = time.perf_counter()
    x_ref = ref.hamilton_solution(rnet, start, t_end, rtol=1e-13, atol=1e-13).x
    print(f"\nreference (DOP853, rtol = atol = 1e-13) to t = {t_end}: {time.perf_counter() - t0:.1f} s")
    print(f"\nchain: max error in positions at t = {t_end} against wall time")
    print("| method | h | error | wall s |\n|---|---:|---:|---:|")
    for method, exps in (("gtr-0", range(4, 10)), ("gtr-1", range(4, 10)), ("co2", range(1, 8)),
                         ("co4", range(1, 7)), ("co6", range(1, 6)), ("gtr-1/2", range(1, 8)), ("ho4", range(0, 6)),
                         ("em2", range(1, 8))):
        for i in exps:
            h = 0.1 * 2.0**-i
            sim = tn.chain_simulation(method, h=h)
            sim.run(steps=1, diagnostics_every=10**9)  # compile outside the timing
            sim = tn.chain_simulation(method, h=h)
            t0 = time.perf_counter()
            try:
                sim.run(t_end=t_end, diagnostics_every=10**9)
            except tn.SimulationError as exc:
                print(f"| {method} | {h:.3g} | failed: {str(exc)[:60]} | |")
                errors.append((method, h, None, None))
                continue
            wall = time.perf_counter() - t0
            err = np.abs(sim.state.positions - x_ref).max()
            errors.append((method, h, float(err), wall))
            print(f"| {method} | {h:.4g} | {err:.2e} | {wall:.3f} |", flush=True)
    return iterations, errors


CROSSOVER_SHAPES = ("chain", (1, 1, 1), (2, 1, 1), (2, 2, 1), (2, 2, 2), (3, 2, 2), (3, 3, 3))


def crossover(rounds, shapes=CROSSOVER_SHAPES, steps=200):
    """The compiled path's dense LU against its sweeps on the chain and small lattices: µs per step
    (CPU time, serial, median of interleaved rounds); returns the rows (shape, springs, method,
    unknowns, dense and sweeps seconds per step)."""
    print("compiled path, dense LU against matrix-free sweeps, µs per step (CPU time, serial)")
    print("| lattice | springs | method | unknowns | dense | sweeps |\n|---|---:|---|---:|---:|---:|")
    rng = np.random.default_rng(0)
    rows = []
    for shape in shapes:
        net = tn.chain() if shape == "chain" else tn.lattice(shape, jitter=0.1, seed=1)
        temps, moms = rng.uniform(300.0, 600.0, net.n_springs), rng.normal(0.0, 1.0, (net.n_nodes, 3))
        for method in ("gtr-1/2", "ho4"):
            sims = {}
            for kind, path in (("dense", "compiled-dense"), ("sweeps", "compiled")):
                if shape == "chain":
                    sims[kind] = tn.chain_simulation(method, h=0.01, integrator_options=dict(newton_path=path))
                else:
                    sims[kind] = tn.Simulation(
                        net, model="hencky", parameters=dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0),
                        temperatures=temps, momenta=moms, integrator=method, h=0.01, parallel=False,
                        integrator_options=dict(newton_path=path))
                sims[kind].run(steps=2, diagnostics_every=10**9)
            per = {kind: [] for kind in sims}
            for _ in range(rounds):
                for kind, sim in sims.items():
                    t0 = time.process_time()
                    sim.run(steps=steps, diagnostics_every=10**9)
                    per[kind].append((time.process_time() - t0) / steps)
            size = sims["dense"].stepper.pattern.size
            rows.append({"shape": shape, "springs": net.n_springs, "method": method, "unknowns": size,
                         "dense": statistics.median(per["dense"]), "sweeps": statistics.median(per["sweeps"])})
            print(f"| {shape} | {net.n_springs} | {method} | {size} | {1e6 * statistics.median(per['dense']):.1f} | "
                  f"{1e6 * statistics.median(per['sweeps']):.1f} |", flush=True)
    return rows


def study(t_end, repeats, halvings):
    """The cost study on the paper's chain (thermonet.studies.cost_study, no SciPy runs): per
    accuracy, the cheapest of the paper's five integrators and each method's interpolated time.
    Returns the study (thermonet.studies.CostStudy)."""
    from thermonet.studies import Runner, cost_study

    paper = ["gtr-0", "gtr-1", "gtr-1/2", "co2", "ho4"]
    names = paper + ["co4", "co6"]
    cost = cost_study("chain", names, dt=0.1, halvings=halvings, t_end=t_end, repeats=repeats, scipy={},
                      runner=Runner(serial=True))
    print(f"cost study, chain, error in position at t = {t_end} (median of {repeats}); the cheapest run of each "
          "method reaching the accuracy, ms (h)")
    print("| accuracy | cheapest of the paper's five | " + " | ".join(names) + " |")
    print("|---:|---|" + "---:|" * len(names))
    for acc in [10.0**-k for k in range(0, 11)]:
        cells = []
        for name in names:
            rows = [r for r in cost.rows if r["solver"] == name and math.isfinite(r["time"]) and r["position"] <= acc]
            best = min(rows, key=lambda r: r["time"]) if rows else None
            cells.append(f"{1e3 * best['time']:.3g} ({best['h']:.3g})" if best else "–")
        ok = [r for r in cost.rows if r["solver"] in paper and math.isfinite(r["time"]) and r["position"] <= acc]
        best = min(ok, key=lambda r: r["time"])["solver"] if ok else "–"
        print(f"| {acc:.0e} | {best} | " + " | ".join(cells) + " |", flush=True)
    return cost


#: --quick: every part at its smallest (the chain for the ratios; the 2³ lattice for scaling;
#: crossover on the chain and one cell; the chain's tables and the study to t = 1), one round
QUICK = dict(ratio_sizes=[0], scaling_sizes=[2], rounds=1, seconds=0.01, steps=3, co2_work=3e5,
             shapes=("chain", (1, 1, 1)), crossover_steps=20, t_end=1.0, iterations_t_end=1.0, study_t_end=1.0,
             study_repeats=1, study_halvings=2)


def main(argv=None) -> dict:
    """Run the benchmark (``argv``: its command line); returns each part's rows (part -> what its
    function returns)."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--part", choices=("ratio", "crossover", "scaling", "chain", "study", "all"), default="all")
    ap.add_argument("--study-t-end", type=float, default=10.0, help="study: t_end of the cost study")
    ap.add_argument("--study-repeats", type=int, default=3)
    ap.add_argument("--study-halvings", type=int, default=8)
    ap.add_argument("--sizes", type=int, nargs="+", default=None,
                    help="lattice cells per side (ratio: 0 is the paper's chain); default: ratio 0 5 11 25 32, "
                         "scaling 3 7 15 32")
    ap.add_argument("--paths", nargs="+", default=["compiled", "sparse"], help="Newton paths (ratio)")
    ap.add_argument("--methods", nargs="+", default=["ho4", "gtr-1/2", "em2"], help="implicit schemes (ratio)")
    ap.add_argument("--rounds", type=int, default=15, help="interleaved rounds (ratio)")
    ap.add_argument("--seconds", type=float, default=0.3,
                    help="seconds per timed chunk (ratio; shorter chunks time CO2 with the caches the "
                         "implicit runs left cold: 1.6x its steady cost at 5e4 springs at 0.03 s)")
    ap.add_argument("--serial", action="store_true",
                    help="single-threaded kernels at every size (ratio; default: threaded from 16384 springs)")
    ap.add_argument("--cpu-time", action="store_true",
                    help="time by the process's CPU time, not wall time (ratio, with --serial: on a shared, "
                         "oversubscribed machine the time a process waits for a core is left out)")
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--h", type=float, default=0.01)
    ap.add_argument("--direct-max-springs", type=int, default=12000,
                    help="skip the direct solver above this many springs (3D fill-in)")
    ap.add_argument("--solvers", nargs="+", default=["splu", "matfree", "gmres"],
                    help="linear solvers to time (splu, matfree, gmres)")
    ap.add_argument("--settle", type=int, default=0,
                    help="untimed steps of each implicit run before the timed ones (the later regime)")
    ap.add_argument("--t-end", type=float, default=100.0)
    ap.add_argument("--quick", action="store_true", help="every part (or --part) at its smallest, one round: a smoke "
                    "run (QUICK)")
    args = ap.parse_args(argv)
    q = dict(ratio_sizes=[0, 5, 11, 25, 32], scaling_sizes=[3, 7, 15, 32], co2_work=3e7, shapes=CROSSOVER_SHAPES,
             crossover_steps=200, iterations_t_end=10.0)
    if args.quick:
        q.update(QUICK)
        for key in ("rounds", "seconds", "steps", "t_end", "study_t_end", "study_repeats", "study_halvings"):
            setattr(args, key, q[key])
    out = {}
    if args.part in ("ratio", "all"):
        out["ratio"] = ratio(args.sizes or q["ratio_sizes"], args.h, args.paths, args.rounds, args.seconds,
                             False if args.serial else None, time.process_time if args.cpu_time else time.perf_counter,
                             args.methods)
        print()
    if args.part in ("crossover", "all"):
        out["crossover"] = crossover(args.rounds, q["shapes"], q["crossover_steps"])
        print()
    if args.part in ("scaling", "all"):
        out["scaling"] = scaling(args.sizes or q["scaling_sizes"], args.steps, args.h, args.direct_max_springs,
                                 args.solvers, args.settle, q["co2_work"])
        print()
    if args.part in ("chain", "all"):
        out["chain"] = chain(args.t_end, q["iterations_t_end"])
        print()
    if args.part in ("study", "all"):
        out["study"] = study(args.study_t_end, args.study_repeats, args.study_halvings)
    return out


if __name__ == "__main__":
    main()
