"""EM2's accuracy far above the explicit limit where it is meant to be used: the slow
(quasi-static) response of a part heated and loaded slowly, against CO2 at a fine step.

The part is em2_paths.py's steel L-bracket (``part``: bolted base that is also a heat bath
ramping 293.15 → 393.15 K, a force ramping to 2 kN on the flange's top face, conduction),
meshed coarsely (``--mesh-size``, default 0.01 m), with the ramps over ``--duration`` seconds
(default 0.05 s: about a hundred periods of the part's slowest mode, so the response is
quasi-static) and a conductivity raised so that heat crosses the part within that time
(``--conductivity``, default 3e4 W/(m K), about 700× steel's: with steel's own, heat would move
one element in the seconds only a much longer run reaches). At t = duration it compares

- the temperature field: max over springs |θ − θ_ref|, relative to the largest rise θ_ref − θ0;
- the displacement of the loaded face (the mean of its nodes' x displacement), relative;

of EM2 at ``--factors`` × CO2's stable step against CO2 at 0.9× its stable step with conduction
at every step (the reference), whose own error is shown by CO2 at half that step.

    python benchmarks/em2_accuracy.py                       # factors 10 100 1000 1e4
    python benchmarks/em2_accuracy.py --factors 30 300 3000
    python benchmarks/em2_accuracy.py --quick               # a shorter run (the test's)
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from em2_paths import part_simulation  # noqa: E402

from thermonet.stability import stable_step  # noqa: E402

THETA0 = 293.15


def response(size: float, integrator: str, h: float, duration: float, conductivity: float, **options):
    """(θ per spring, mean x displacement of the loaded face, steps, wall s, the stepper's summary
    or None) at t = duration, from rest."""
    sim = part_simulation(size, integrator, h, threads=1, conductivity=conductivity, duration=duration,
                          **options)
    steps = int(round(duration / h))
    top = sim.net.node_groups["top"]
    x0 = sim.state.positions[top, 0].copy()
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (CO2's step guard at its own 0.9× limit)
        sim.run(steps=steps, diagnostics_every=steps)
    wall = time.perf_counter() - t0
    summary = sim.stepper.summary() if hasattr(sim.stepper, "summary") else None
    return sim.temperatures(), float(np.mean(sim.state.positions[top, 0] - x0)), steps, wall, summary


def errors(theta, ux, ref) -> tuple[float, float]:
    """(temperature error relative to the largest rise, displacement error relative)."""
    theta_ref, ux_ref = ref[0], ref[1]
    return (float(np.max(np.abs(theta - theta_ref)) / np.max(theta_ref - THETA0)),
            abs(ux - ux_ref) / abs(ux_ref))


def study(size: float, duration: float, conductivity: float, factors, out=print, own_error: bool = True) -> list[dict]:
    """The table: CO2 at half the reference step (``own_error``), then EM2 at each factor;
    returns its rows."""
    probe = part_simulation(size, "co2", 1e-7, threads=1, conductivity=conductivity, duration=duration)
    h_max = stable_step(probe)["h_max"]
    h_ref = duration / np.ceil(duration / (0.9 * h_max))  # (a whole number of steps)
    ref = response(size, "co2", h_ref, duration, conductivity, conduction_every=1)
    out(f"part: {probe.net.n_springs} springs, mesh size {size:g} m; ramps over {duration:g} s, conductivity "
        f"{conductivity:g} W/(m K); CO2's stable step {h_max:.3g} s; reference: CO2 at {h_ref:.3g} s "
        f"({ref[2]} steps, {ref[3]:.1f} s): largest rise {np.max(ref[0]) - THETA0:.4g} K, loaded face "
        f"moved {ref[1]:.4g} m\n")
    out("| integrator | step ÷ CO2's stable step | h (s) | steps | temperature error | displacement error "
        "| Newton it./step | wall s |")
    out("|---|---:|---:|---:|---:|---:|---:|---:|")
    rows = []
    if own_error:
        half = response(size, "co2", h_ref / 2, duration, conductivity, conduction_every=1)
        e = errors(half[0], half[1], ref)
        out(f"| co2 (the reference's own error) | {h_ref / 2 / h_max:.2g} | {h_ref / 2:.3g} | {half[2]} | {e[0]:.2e} | "
            f"{e[1]:.2e} | | {half[3]:.1f} |")
        rows.append(dict(integrator="co2", factor=h_ref / 2 / h_max, theta_error=e[0], ux_error=e[1]))
    for factor in factors:
        steps = max(1, int(round(duration / (factor * h_max))))
        h = duration / steps
        got = response(size, "em2", h, duration, conductivity)
        e = errors(got[0], got[1], ref)
        out(f"| em2 | {h / h_max:.3g} | {h:.3g} | {steps} | {e[0]:.2e} | {e[1]:.2e} | "
            f"{got[4]['iterations_mean']:.2f} | {got[3]:.1f} |")
        rows.append(dict(integrator="em2", factor=h / h_max, theta_error=e[0], ux_error=e[1]))
    return rows


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mesh-size", type=float, default=0.01)
    ap.add_argument("--duration", type=float, default=0.05, help="the ramps' duration and the run's (s)")
    ap.add_argument("--conductivity", type=float, default=3e4, help="W/(m K)")
    ap.add_argument("--factors", nargs="+", type=float, default=[10, 100, 1000, 1e4])
    ap.add_argument("--quick", action="store_true", help="duration 0.02 s, factors 100 and 1000, no CO2 at half "
                    "the reference's step")
    args = ap.parse_args(argv)
    if args.quick:
        args.duration, args.factors = 0.02, [100, 1000]
    print(f"EM2's quasi-static accuracy; load: {os.getloadavg()[0]:.2f} (1-min average)\n")
    return study(args.mesh_size, args.duration, args.conductivity, args.factors, own_error=not args.quick)


if __name__ == "__main__":
    main()
