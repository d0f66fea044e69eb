"""``thermonet run``: run a scene (default: the paper's triangle net) and report conservation."""

from __future__ import annotations

import os
import sys

HELP = "run a simulation and print its conservation summary"

DEFAULT_SCENE = "triangle"


def add_args(p) -> None:
    p.add_argument("scene", nargs="?", default=None, help="scene to run (default: the paper's triangle net)")
    p.add_argument("--out", default=None, help="output folder (default ./thermonet-out/<scene>)")
    p.add_argument("--integrator", default=None, help="integrator name (default co2)")
    p.add_argument("--h", type=float, default=None, help="time step")
    p.add_argument("--t-end", type=float, default=None, help="final time")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")


def handle(args) -> int:
    from ..paper import chain_simulation, triangle_simulation
    from .report import format_summary

    scene = args.scene or DEFAULT_SCENE
    builtin = {"triangle": (triangle_simulation, 1e-3, 10.0), "chain": (chain_simulation, 1e-2, 100.0)}
    if scene not in builtin:
        from ..errors import UnknownNameError

        raise UnknownNameError("scene", scene, builtin)
    factory, h, t_end = builtin[scene]
    sim = factory(integrator=args.integrator or "co2", h=args.h or h)
    out = args.out or os.path.join("thermonet-out", scene)
    os.makedirs(out, exist_ok=True)
    sim.run(t_end=args.t_end if args.t_end is not None else t_end)
    sim.diagnostics.to_csv(os.path.join(out, "diagnostics.csv"))
    if not args.quiet:
        print(format_summary(sim, scene, out), file=sys.stdout)
    return 0
