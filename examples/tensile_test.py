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
Writes tensile_load_displacement.png and tensile_gauge.png. The same run from the command line:
``thermonet run scenes/tensile.toml`` then ``thermonet plot OUTDIR``.
"""

from __future__ import annotations

import argparse
import os

import numpy as np

from thermonet.probes import Probe, Probes
from thermonet.scenes import load_scene
from thermonet.studies.plots import pyplot

SCENE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes", "tensile.toml")


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="tensile-out")
    ap.add_argument("--smoke", action="store_true", help="a quarter of the pull (a quick check)")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    scene = load_scene(SCENE, ["integrator.t_end=3.0"] if args.smoke else [])
    sim = scene.build().simulation
    probes = Probes(sim, {"theta": Probe("gauge", "temperature"), "strain": Probe("gauge", "strain")})
    every = 60
    sim.run(steps=scene.total_steps(), diagnostics_every=every, observers=probes.observers(every))
    d = sim.diagnostics
    theta = np.array([r[2] for r in probes.series["theta"]])
    strain = np.array([r[2] for r in probes.series["strain"]])
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
    print(f"pulled {numbers['pull']:.3g} with force {numbers['force']:.4g}; gauge strain {numbers['gauge_strain']:.3g}, "
          f"mean temperature −{numbers['gauge_theta_drop']:.3g}; springs along the pull −{numbers['along_theta_drop']:.3g} "
          f"(closed form θ0 exp(−βL/C0) within {numbers['along_theta_error']:.2g}); "
          f"max |H − H(0) − W| / max |W| = {numbers['balance_relative']:.2g}")
    return numbers


if __name__ == "__main__":
    main()
