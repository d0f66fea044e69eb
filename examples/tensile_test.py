"""A tensile test with thermoelastic cooling: the shipped scene ``scenes/tensile.toml`` (a flat
gmsh dog-bone clamped at its left grip, its right grip pulled at constant velocity, thermal
coupling on) run through the Python API.

    python examples/tensile_test.py [--out DIR] [--smoke]

It reports the load–displacement curve (the grip's reaction against its displacement), the
gauge's mean temperature against its mean strain, and the energy balance H − H(0) − W, and
checks the cooling against the adiabatic closed form of the Hencky model: a spring stretched at
constant entropy from θ0 to the log strain L has θ = θ0 exp(−β L / C0) (β > 0: it cools), which
holds to round-off because no kick, drive or force ever writes a spring's entropy. The
gauge's springs lying along the pull cool; those across it, squeezed by the contraction, warm.
With ``--conduction G`` (default 5; 0: skip) it pulls a second specimen whose springs conduct
heat (conductance G) and whose grips are heat baths at 300 K: the cooled gauge warms back from
the grips, and the energy balance then counts the baths' heat too, H − H(0) − W − ΣQ.
Writes tensile_load_displacement.png, tensile_gauge.png and tensile_warming.png. The same runs
from the command line: ``thermonet run scenes/tensile.toml`` (add ``--set`` with the
:data:`CONDUCTION` overrides for the second) then ``thermonet plot OUTDIR``.
"""

from __future__ import annotations

import argparse
import os

import numpy as np

from thermonet.probes import Probe, Probes
from thermonet.scenes import load_scene
from thermonet.studies.plots import pyplot

SCENE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes", "tensile.toml")
#: the scene overrides of the conducting pull (the conductance g is added by main)
CONDUCTION = ("effects.conduction=true", 'baths.left.group="grip_left"', "baths.left.temperature=300.0",
              'baths.right.group="grip_right"', "baths.right.temperature=300.0")


def pull(overrides) -> tuple:
    """The scene pulled with ``overrides``: (simulation, times, gauge mean temperatures, gauge mean strains)."""
    scene = load_scene(SCENE, overrides)
    sim = scene.build().simulation
    probes = Probes(sim, {"theta": Probe("gauge", "temperature"), "strain": Probe("gauge", "strain")})
    every = 60
    sim.run(steps=scene.total_steps(), diagnostics_every=every, observers=probes.observers(every))
    series = [np.array([r[k] for r in probes.series[name]]) for name, k in (("theta", 1), ("theta", 2), ("strain", 2))]
    return (sim, scene, *series)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="tensile-out")
    ap.add_argument("--smoke", action="store_true", help="a quarter of the pull (a quick check)")
    ap.add_argument("--conduction", type=float, default=5.0, metavar="G",
                    help="conductance of the second, conducting pull with grip baths (0: skip it)")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    base = ["integrator.t_end=3.0"] if args.smoke else []
    sim, scene, t, theta, strain = pull(base)
    d = sim.diagnostics
    P = scene.data["materials"]["all"]
    # the springs of the gauge lying along the pull (within 10° of x): their cooling vs the closed form
    lay = sim.net
    gauge = lay.spring_groups["gauge"]
    d_x = lay.positions[lay.edges[gauge, 1]] - lay.positions[lay.edges[gauge, 0]]
    along = gauge[np.abs(d_x[:, 0]) > np.cos(np.radians(10)) * np.linalg.norm(d_x, axis=1)]
    L = sim.strains()[along]
    predicted = P["theta0"] * np.exp(-P["beta"] * L / P["C0"])
    numbers = {
        "pull": float(d.pull_ux[-1]), "force": float(-d.pull_Rx[-1]),
        "gauge_theta_drop": float(theta[0] - theta[-1]), "gauge_strain": float(strain[-1]),
        "along_theta_error": float(np.max(np.abs(sim.temperatures()[along] - predicted))),
        "along_theta_drop": float(P["theta0"] - sim.temperatures()[along].mean()),
        "balance_relative": float(np.max(np.abs(d.energy_balance)) / np.max(np.abs(d.work))),
    }
    if args.conduction > 0:
        warm, _, t_warm, theta_warm, _ = pull(base + [f"materials.all.g={args.conduction}", *CONDUCTION])
        dw = warm.diagnostics
        numbers.update({
            "conducting_theta_drop": float(theta_warm[0] - theta_warm[-1]),
            "heat_in": float(dw.heat_in[-1] - dw.heat_in[0]),
            "conducting_balance_relative": float(np.max(np.abs(dw.energy_balance))
                                                 / max(np.max(np.abs(dw.work)), np.max(np.abs(dw.heat_in - dw.heat_in[0])))),
        })
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.plot(d.pull_ux, -d.pull_Rx)
    ax.set_xlabel("grip displacement")
    ax.set_ylabel("pulling force (−reaction)")
    ax.set_title("tensile test: load–displacement")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "tensile_load_displacement.png"), dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.plot(strain, theta)
    ax.set_xlabel("gauge mean log strain")
    ax.set_ylabel("gauge mean temperature")
    ax.set_title("thermoelastic cooling (Kelvin effect)")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "tensile_gauge.png"), dpi=110)
    plt.close(fig)
    if args.conduction > 0:
        fig, ax = plt.subplots(figsize=(6, 4.5))
        ax.plot(t, theta, label="adiabatic")
        ax.plot(t_warm, theta_warm, label=f"conducting (g = {args.conduction:g}), grips at 300 K")
        ax.set_xlabel("time")
        ax.set_ylabel("gauge mean temperature")
        ax.set_title("the cooled gauge warms back from the grips")
        ax.legend()
        fig.tight_layout()
        fig.savefig(os.path.join(args.out, "tensile_warming.png"), dpi=110)
        plt.close(fig)
        print(f"conducting pull: gauge mean temperature −{numbers['conducting_theta_drop']:.3g} "
              f"(adiabatic −{numbers['gauge_theta_drop']:.3g}); heat from the grips {numbers['heat_in']:.4g}; "
              f"max |H − H(0) − W − ΣQ| / max(|W|, |ΣQ|) = {numbers['conducting_balance_relative']:.2g}")
    print(f"pulled {numbers['pull']:.3g} with force {numbers['force']:.4g}; gauge strain {numbers['gauge_strain']:.3g}, "
          f"mean temperature −{numbers['gauge_theta_drop']:.3g}; springs along the pull −{numbers['along_theta_drop']:.3g} "
          f"(closed form θ0 exp(−βL/C0) within {numbers['along_theta_error']:.2g}); "
          f"max |H − H(0) − W| / max |W| = {numbers['balance_relative']:.2g}")
    return numbers


if __name__ == "__main__":
    main()
