"""``thermonet study convergence|cost|energy SCENE``: what accuracy costs in time.

SCENE is a built-in scene ("chain", "triangle") or a scene file. Runs execute on a local Dask
cluster (one single-threaded worker per core) unless ``--serial``; ``--scheduler ADDRESS`` sends
them to an existing Dask cluster instead.
"""

from __future__ import annotations

import os
import sys

HELP = "convergence, cost (work-precision) and long-run energy studies of the integrators"

DEFAULT_INTEGRATORS = {"convergence": "gtr-0,gtr-1,gtr-1/2,co2,ho4,co4",
                       "cost": "gtr-0,gtr-1,gtr-1/2,co2,ho4,co4,co6,bm4,bm6", "energy": "co2,ho4"}


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
            s.add_argument("--dt", type=float, default=0.1, help="largest time step (default 0.1)")
            s.add_argument("--halvings", type=int, default=8, help="time steps dt·2^-i, i = 0..halvings (default 8)")
            s.add_argument("--t-end", type=float, default=1.0, help="time at which errors are measured (default 1)")
            s.add_argument("--reference-rtol", type=float, default=1e-13, help="DOP853 tolerance of the reference")
            s.add_argument("--check", default="co6:5e-4", metavar="INTEGRATOR:H",
                           help="solution the reference is checked against (default co6:5e-4; 'none' to skip)")
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
            s.add_argument("--h", type=float, default=0.01, help="time step (default 0.01)")
            s.add_argument("--t-end", type=float, default=100.0, help="final time (default 100)")
            s.add_argument("--every", type=int, default=1, help="diagnostics every k steps (default 1)")
            s.add_argument("--window", default=None, metavar="T0,T1", help="zoom window (default 0.42..0.45 t_end)")


def _integrators(text: str | None, study: str) -> list[str]:
    from ..integrators import available_integrators
    from ..errors import UnknownNameError

    known = set(available_integrators())
    if text is None:
        return [n for n in DEFAULT_INTEGRATORS[study].split(",") if n in known]
    names = [n.strip().lower() for n in text.split(",") if n.strip()]
    for n in names:
        if n not in known:
            raise UnknownNameError("integrator", n, sorted(known))
    return names


def _check(text: str):
    from ..errors import InputError

    if text.lower() == "none":
        return None
    try:
        name, h = text.split(":")
        return name.strip().lower(), float(h)
    except ValueError:
        raise InputError(f"--check must be INTEGRATOR:H or none, got {text!r}") from None


def _scipy(text: str) -> dict:
    from ..errors import InputError

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
    integrators = _integrators(args.integrators, args.study)
    scene_tag = os.path.splitext(os.path.basename(args.scene))[0]
    out = args.out or os.path.join("thermonet-out", f"study-{args.study}-{scene_tag}")
    with Runner(serial=args.serial, scheduler=args.scheduler, n_workers=args.workers) as runner:
        say(f"{args.study} study of {args.scene}: {', '.join(integrators)}; runs on {runner.description}")
        if args.study == "convergence":
            study = convergence_study(args.scene, integrators, args.dt, args.halvings, args.t_end, runner=runner,
                                      rtol=args.reference_rtol, check=_check(args.check))
            files = study.write(out)
        elif args.study == "cost":
            acc = [float(a) for a in args.accuracy.split(",")] if args.accuracy else None
            study = cost_study(args.scene, integrators, args.dt, args.halvings, args.t_end, repeats=args.repeats,
                               scipy=_scipy(args.scipy), runner=runner, one_at_a_time=args.one_at_a_time,
                               rtol=args.reference_rtol, check=_check(args.check), scipy_rhs=args.scipy_rhs)
            files = study.write(out, accuracies=acc)
            say(study.summary(accuracies=acc))
        else:
            window = [float(v) for v in args.window.split(",")] if args.window else None
            study = energy_study(args.scene, integrators, args.h, args.t_end, args.every, window, runner=runner)
            files = study.write(out)
    if args.study != "cost":
        say(study.summary())
    say("wrote " + ", ".join(os.path.relpath(f) for f in files))
    return 0
