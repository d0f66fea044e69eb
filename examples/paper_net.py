"""The paper's thermo-elastic net, a triangle of three masses (Mata & Lew 2011, §5.2):
Figs. 17–19. CO2, h = 0.001, to t = 10.

    python examples/paper_net.py [--out DIR] [--smoke]

Fig. 17: trajectory of mass 1 in the e1–e3 and e1–e2 planes; Fig. 18: strain ln(l/l0) and
temperature of spring 2; Fig. 19: energy, total entropy, e2 linear and e2 angular momentum.
``--smoke`` stops at t = 1.
"""

from __future__ import annotations

import argparse
import os

import numpy as np

import thermonet as tn
from thermonet.studies.plots import pyplot

SPRING_2 = 1  # the paper's spring 2 joins masses 1 and 2 (thermonet.builders.triangle)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join("examples-out", "paper_net"))
    ap.add_argument("--smoke", action="store_true", help="t = 1 instead of 10")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    t_end = 1.0 if args.smoke else 10.0

    sim = tn.triangle_simulation("co2", h=1e-3)
    t, x1, strain, theta = [], [], [], []

    def observe(s):
        t.append(s.time)
        x1.append(s.state.positions[0])
        strain.append(s.strains()[SPRING_2])
        theta.append(s.temperatures()[SPRING_2])

    diag = sim.run(t_end=t_end, diagnostics_every=1, observers=[(1, observe)])
    t, x1, strain, theta = map(np.array, (t, x1, strain, theta))

    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(8.0, 3.8), dpi=100)
    for ax, j in zip(axes, (2, 1)):
        ax.plot(x1[:, 0], x1[:, j], lw=0.6)
        ax.set_xlabel("q1")
        ax.set_ylabel(f"q{j + 1}")
        ax.set_title(f"mass 1 in the e1–e{j + 1} plane", fontsize=9)
    fig.suptitle("Fig. 17: trajectory of mass 1 (CO2, h = 0.001)", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "fig17_mass1_trajectory.png"))
    plt.close(fig)

    fig, axes = plt.subplots(2, 1, figsize=(6.0, 4.6), dpi=100, sharex=True)
    axes[0].plot(t, strain, lw=0.6)
    axes[0].set_ylabel("strain ln(l/l0)")
    axes[1].plot(t, theta, lw=0.6, color="C3")
    axes[1].set_ylabel("temperature")
    axes[1].set_xlabel("time")
    axes[0].set_title("Fig. 18: spring 2", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "fig18_spring2.png"))
    plt.close(fig)

    fig, axes = plt.subplots(2, 2, figsize=(8.0, 5.2), dpi=100, sharex=True)
    series = (("total energy", diag.energy), ("total entropy", diag.entropy),
              ("e2 linear momentum", diag.py), ("e2 angular momentum", diag.Ly))
    for ax, (label, v) in zip(axes.ravel(), series):
        ax.plot(diag.time, v, lw=0.6)
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.set_title(f"{label}\n(max |change| {np.max(np.abs(v - v[0])):.2e})", fontsize=9)
    for ax in axes[1]:
        ax.set_xlabel("time")
    fig.suptitle("Fig. 19: conservation (CO2, h = 0.001)", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "fig19_conservation.png"))
    plt.close(fig)

    numbers = {
        "strain_range": (float(strain.min()), float(strain.max())),
        "temperature_range": (float(theta.min()), float(theta.max())),
        "py": float(diag.py[0]),
        "py_change": float(np.max(np.abs(diag.py - diag.py[0]))),
        "Ly_change": float(np.max(np.abs(diag.Ly - diag.Ly[0]))),
        "entropy_change": float(np.max(np.abs(diag.entropy - diag.entropy[0]))),
        "energy_range": float(np.ptp(diag.energy)),
        "energy": float(diag.energy[0]),
    }
    print(f"spring 2: strain in [{numbers['strain_range'][0]:.4f}, {numbers['strain_range'][1]:.4f}], "
          f"temperature in [{numbers['temperature_range'][0]:.2f}, {numbers['temperature_range'][1]:.2f}]")
    print(f"e2 linear momentum {numbers['py']:g} (max change {numbers['py_change']:.1e}), e2 angular momentum "
          f"max change {numbers['Ly_change']:.1e}, total entropy max change {numbers['entropy_change']:.1e}, "
          f"energy {numbers['energy']:.6f} oscillating by {numbers['energy_range']:.3e}; PNGs in {args.out}")
    return numbers


if __name__ == "__main__":
    main()
