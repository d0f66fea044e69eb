"""``thermonet study convergence|cost|energy SCENE``: what accuracy costs in time.

SCENE is a built-in scene ("chain", "triangle") or a scene file. Runs execute on a local Dask
cluster (one single-threaded worker per core) unless ``--serial``; ``--scheduler ADDRESS`` sends
them to an existing Dask cluster instead.
"""

from __future__ import annotations

import math
import os
import sys

from ..errors import InputError, UnknownNameError
from ..integrators import available_integrators, get_integrator
from ..step_policy import StepWarning

HELP = "convergence, cost (work-precision) and long-run energy studies of the integrators"

DEFAULT_INTEGRATORS = {"convergence": "gtr-0,gtr-1,gtr-1/2,co2,ho4,co4,omf4",
                       "cost": "gtr-0,gtr-1,gtr-1/2,co2,ho4,co4,omf4,co6,bm4,bm6", "energy": "co2,ho4"}


def add_args(p) -> None:
    sub = p.add_subparsers(dest="study", metavar="STUDY", required=True)
    for name, helptext in (("convergence", "error at t_end against h, with fitted orders (paper Figs. 6-8)"),
                           ("cost", "error against wall-clock time, with SciPy solve_ivp as baseline (paper Fig. 9)"),
                           ("energy", "energy, entropy and momenta over a long run (paper Fig. 15)")):
        s = sub.add_parser(name, help=helptext, description=helptext)
        s.add_argument("scene", help='built-in scene ("chain", "triangle", "lattice") or a scene file')
        s.add_argument("--integrators", default=None,
                       help=f"comma-separated integrator names (default {DEFAULT_INTEGRATORS[name]}, "
                            "those that exist in this installation)")
        s.add_argument("--out", default=None, help="output folder (default thermonet-out/study-<study>-<scene>)")
        s.add_argument("--scheduler", default=None, metavar="ADDRESS", help="address of an existing Dask scheduler")
        s.add_argument("--serial", action="store_true", help="run in this process, without Dask")
        s.add_argument("--workers", type=int, default=None, help="workers of the local cluster (default: one per core)")
        s.add_argument("--quiet", action="store_true", help="print nothing but errors")
        if name in ("convergence", "cost"):
            s.add_argument("--dt", type=float, default=None,
                           help="largest time step (default: 0.1 for the built-in scenes, else the scene's h; at "
                                "most 0.9 × the smallest stability limit of the integrators, a whole fraction of t_end)")
            s.add_argument("--halvings", type=int, default=8, help="time steps dt·2^-i, i = 0..halvings (default 8)")
            s.add_argument("--t-end", type=float, default=None,
                           help="time at which errors are measured (default: the scene's end, integrator.t_end "
                                "or steps × h; 1 for the built-in scenes)")
            s.add_argument("--reference-rtol", type=float, default=1e-13, help="DOP853 tolerance of the reference")
            s.add_argument("--check", default=None, metavar="INTEGRATOR:H",
                           help="solution the reference is checked against (default co6 at h = 5e-4, or at half its "
                                "stability limit where that is smaller; 'none' to skip). For a scene with heat flow "
                                "(conduction, thermal waves, baths, sources) or loads, which SciPy's DOP853 reference "
                                "leaves out, the reference itself, checked against the same integrator at 2H "
                                "(default co4 at the finest step / 16)")
        if name == "cost":
            s.add_argument("--repeats", type=int, default=5, help="timed repeats per run, median reported (default 5)")
            s.add_argument("--scipy", default="DOP853:1e-3..1e-12,RK45:1e-3..1e-9",
                           help="SciPy solve_ivp baselines METHOD:TOLMAX..TOLMIN (decades), comma-separated; 'none'")
            s.add_argument("--scipy-rhs", default="compiled", choices=("compiled", "numpy", "both"),
                           help="SciPy's right-hand side: Numba-compiled (default), NumPy, or both")
            s.add_argument("--one-at-a-time", action="store_true",
                           help="never run two timed runs at once (for a machine shared with other jobs)")
            s.add_argument("--accuracy", default=None,
                           help="comma-separated accuracies for the summary (default: every decade reached)")
        if name == "energy":
            s.add_argument("--h", type=float, default=None,
                           help="time step (default: the scene's integrator.h; 0.01 for the built-in scenes)")
            s.add_argument("--t-end", type=float, default=None,
                           help="final time (default: the scene's end; 100 for the built-in scenes)")
            s.add_argument("--every", type=int, default=1, help="diagnostics every k steps (default 1)")
            s.add_argument("--window", default=None, metavar="T0,T1", help="zoom window (default 0.42..0.45 t_end)")


def _integrators(text: str | None, study: str) -> list[str]:
    known = set(available_integrators())
    if text is None:
        return [n for n in DEFAULT_INTEGRATORS[study].split(",") if n in known]
    names = [n.strip().lower() for n in text.split(",") if n.strip()]
    for n in names:
        if n not in known:
            raise UnknownNameError("integrator", n, sorted(known))
    return names


def _check(text: str):
    if text.lower() == "none":
        return None
    try:
        name, h = text.split(":")
        name, h = name.strip().lower(), float(h)
    except ValueError:
        raise InputError(f"--check must be INTEGRATOR:H or none, got {text!r}") from None
    if name not in available_integrators():
        raise UnknownNameError("integrator", name, available_integrators())
    if not (math.isfinite(h) and h > 0):
        raise InputError(f"--check {text}: the step must be finite and > 0")
    return name, h


def _scipy(text: str) -> dict:
    if text.lower() == "none":
        return {}
    out = {}
    for item in text.split(","):
        try:
            method, tols = item.split(":")
            hi, lo = (float(t) for t in tols.split(".."))
            k_hi, k_lo = round(-__import__("math").log10(hi)), round(-__import__("math").log10(lo))
            out[method.strip().upper()] = [10.0**-k for k in range(k_hi, k_lo + 1)]
        except ValueError:
            raise InputError(f"--scipy items must look like DOP853:1e-3..1e-12, got {item!r}") from None
    return out


def handle(args) -> int:
    from ..studies import Runner, convergence_study, cost_study, energy_study

    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, file=sys.stdout, flush=True))
    plan = _plan(args)  # every argument checked, and the defaults resolved, before any work
    integrators = plan["integrators"]
    scene_tag = os.path.splitext(os.path.basename(args.scene))[0]
    out = args.out or os.path.join("thermonet-out", f"study-{args.study}-{scene_tag}")
    import warnings

    warnings.simplefilter("ignore", StepWarning)  # a run near its limit is measured, and reported if it fails
    with Runner(serial=args.serial, scheduler=args.scheduler, n_workers=args.workers) as runner:
        say(f"{args.study} study of {args.scene}: {', '.join(integrators)}; runs on {runner.description}")
        if plan["left_out"]:
            say(f"(left out {', '.join(plan['left_out'])}: implicit integrators need thermal coupling, which the "
                "scene switches off)")
        if args.study in ("convergence", "cost"):
            check = f"{plan['check'][0]} h={plan['check'][1]:g}" if plan["check"] else "none"
            if plan["effects"]:
                name, h = plan["check"]
                reference = (f"reference {name} h={h:g}, checked against {name} h={2 * h:g} (the scene's "
                             f"{', '.join(plan['effects'])} are not in Hamilton's equations, so no DOP853"
                             f"{' and no SciPy baseline' if args.study == 'cost' else ''})")
            else:
                reference = f"reference checked against {check}"
            say(f"time steps {plan['dt']:g}·2^-i, i = 0..{args.halvings}, to t = {plan['t_end']:g}; {reference}")
        if args.study == "convergence":
            study = convergence_study(args.scene, integrators, plan["dt"], args.halvings, plan["t_end"], runner=runner,
                                      rtol=args.reference_rtol, check=plan["check"])
            files = study.write(out)
        elif args.study == "cost":
            study = cost_study(args.scene, integrators, plan["dt"], args.halvings, plan["t_end"], repeats=args.repeats,
                               scipy=plan["scipy"], runner=runner, one_at_a_time=args.one_at_a_time,
                               rtol=args.reference_rtol, check=plan["check"], scipy_rhs=args.scipy_rhs)
            files = study.write(out, accuracies=plan["accuracies"])
            say(study.summary(accuracies=plan["accuracies"]))
        else:
            study = energy_study(args.scene, integrators, plan["h"], plan["t_end"], args.every, plan["window"],
                                 runner=runner)
            files = study.write(out)
    if args.study != "cost":
        say(study.summary())
    say("wrote " + ", ".join(os.path.relpath(f) for f in files))
    return 0


def _plan(args) -> dict:
    """The study's arguments checked, and its defaults resolved (from the scene's step and the
    integrators' stability limits), in this process, before a Dask cluster starts or a run is
    made: any problem is an InputError naming the argument."""
    from ..studies.convergence import default_check, default_time_step, time_steps
    from ..studies.scenes import check_scene, effects_beyond_hamilton, make_simulation, scene_time
    from ..studies.tasks import check_steps

    check_scene(args.scene)
    scene_h, scene_t_end = scene_time(args.scene)
    probe = make_simulation(args.scene, "co2", 1.0)  # (what the scene switches on)
    effects = effects_beyond_hamilton(probe)
    plan = {"integrators": _integrators(args.integrators, args.study), "left_out": []}
    if not plan["integrators"]:
        raise InputError("--integrators: none of the given integrators exists in this installation")
    if args.integrators is None and not probe.system.thermal:  # (named ones: the run says why not)
        plan["left_out"] = [n for n in plan["integrators"] if not get_integrator(n).explicit]
        plan["integrators"] = [n for n in plan["integrators"] if get_integrator(n).explicit]
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers must be >= 1, got {args.workers}")
    if args.study in ("convergence", "cost"):
        t_end = (1.0 if scene_t_end is None else scene_t_end) if args.t_end is None else args.t_end
        if not (math.isfinite(t_end) and t_end > 0):
            raise InputError(f"--t-end must be finite and > 0, got {t_end}")
        if args.dt is not None and not (math.isfinite(args.dt) and args.dt > 0):
            raise InputError(f"--dt must be finite and > 0, got {args.dt}")
        if not 0 <= args.halvings <= 30:
            raise InputError(f"--halvings must be in 0..30, got {args.halvings}")
        if not math.isfinite(args.reference_rtol) or not 0 < args.reference_rtol < 1:
            raise InputError(f"--reference-rtol must be in (0, 1), got {args.reference_rtol}")
        dt = default_time_step(args.scene, plan["integrators"], t_end) if args.dt is None else args.dt
        finest = time_steps(dt, args.halvings)[-1]
        check = default_check(args.scene, t_end, finest, effects) if args.check is None else _check(args.check)
        if effects and check is None:
            raise InputError(f"--check none: the scene has {', '.join(effects)}, which SciPy's DOP853 reference "
                             "leaves out; the reference is an integrator at a fine step, --check INTEGRATOR:H")
        for h in time_steps(dt, args.halvings):
            _whole(check_steps, t_end, h, "--dt and --t-end")
        if check is not None:
            _whole(check_steps, t_end, check[1], "--check")
            if effects:  # the reference's own check runs at twice its step
                _whole(check_steps, t_end, 2 * check[1], "--check (the reference's check at twice its step)")
        plan.update(t_end=t_end, dt=dt, check=check, effects=effects)
    if args.study == "cost":
        if args.repeats < 1:
            raise InputError(f"--repeats must be >= 1, got {args.repeats}")
        plan["scipy"] = _scipy(args.scipy)
        try:
            plan["accuracies"] = [float(a) for a in args.accuracy.split(",")] if args.accuracy else None
        except ValueError:
            raise InputError(f"--accuracy must be comma-separated numbers, got {args.accuracy!r}") from None
    if args.study == "energy":
        exchanging = [e for e in effects if e.startswith(("baths", "sources", "loads"))]
        if exchanging:
            raise InputError(f"{args.scene}: its {', '.join(exchanging)} exchange energy with the outside, so the "
                             "energy is not conserved and an energy study measures nothing; `thermonet run` writes "
                             "the energy balance (energy_balance in diagnostics.csv)")
        h = (0.01 if scene_t_end is None else scene_h) if args.h is None else args.h
        t_end = (100.0 if scene_t_end is None else scene_t_end) if args.t_end is None else args.t_end
        if not (math.isfinite(h) and h > 0):
            raise InputError(f"--h must be finite and > 0, got {h}")
        if not (math.isfinite(t_end) and t_end > 0):
            raise InputError(f"--t-end must be finite and > 0, got {t_end}")
        if args.every < 1:
            raise InputError(f"--every must be >= 1, got {args.every}")
        _whole(check_steps, t_end, h, "--t-end and --h")
        plan.update(h=h, t_end=t_end)
        try:
            plan["window"] = [float(v) for v in args.window.split(",")] if args.window else None
        except ValueError:
            raise InputError(f"--window must be T0,T1, got {args.window!r}") from None
        if plan["window"] is not None and len(plan["window"]) != 2:
            raise InputError(f"--window must be T0,T1, got {args.window!r}")
    return plan


def _whole(check_steps, t_end: float, h: float, what: str) -> None:
    try:
        check_steps(t_end, h)
    except InputError as exc:
        raise InputError(f"{what}: {exc}") from None
