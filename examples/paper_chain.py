"""The paper's chain of three thermo-elastic springs (Mata & Lew 2011, §5.1): Figs. 6–15.

    python examples/paper_chain.py [--out DIR] [--smoke] [--serial | --scheduler ADDRESS]

Convergence at t = 1 (Figs. 6–8), work against precision (Fig. 9, at t = 10: see
docs/paper-reproduction.md for why not t = 100), and a CO2 run with h = 0.01 to t = 100 for the
trajectories (Figs. 10–11), temperatures (12), entropies (13), angular momentum (14) and energy
at three scales (15), CO2 against the paper's HO4. The paper's five integrators (GTR-0, GTR-1,
GTR-1/2, CO2, HO4) are in every convergence and cost figure; the explicit compositions CO4 and
CO6 are drawn beside them as extra curves.
``--smoke`` runs a reduced version in seconds.
"""

from __future__ import annotations

import argparse
import os

import numpy as np

import thermonet as tn
from thermonet.studies import Runner, convergence_study, cost_study, energy_study
from thermonet.studies.plots import convergence_figure, cost_figure, pyplot

PAPER_INTEGRATORS = ["gtr-0", "gtr-1", "gtr-1/2", "co2", "ho4"]
EXTRA_INTEGRATORS = ["co4", "co6"]   # not in the paper: the explicit 4th/6th-order compositions
HIGH_ORDER = "ho4"                   # the paper's implicit 4th-order integrator (Fig. 13–15)


def record_run(integrator: str, h: float, t_end: float) -> dict:
    """Positions (k, n, 3), temperatures and entropies (k, m) at every step, and diagnostics."""
    sim = tn.chain_simulation(integrator, h)
    t, x, theta, eta = [], [], [], []

    def observe(s):
        st = s.state
        t.append(st.time)
        x.append(st.positions)
        theta.append(s.temperatures())
        eta.append(st.entropy)

    sim.run(t_end=t_end, diagnostics_every=1, observers=[(1, observe)])
    return {"t": np.array(t), "x": np.array(x), "theta": np.array(theta), "eta": np.array(eta),
            "t_diag": sim.diagnostics.time, "L": sim.diagnostics.angular_momentum}


def save(fig, out, name):
    path = os.path.join(out, name)
    fig.tight_layout()
    fig.savefig(path)
    pyplot().close(fig)
    return path


def trajectory_figures(run, out):
    plt = pyplot()
    paths = []
    for fig_no, (i, j) in ((10, (0, 1)), (11, (0, 2))):
        fig, ax = plt.subplots(figsize=(5.0, 4.6), dpi=100)
        for node in (1, 2, 3):
            ax.plot(run["x"][:, node, i], run["x"][:, node, j], lw=0.3, label=f"mass {node}")
        ax.set_xlabel(f"q{i + 1}")
        ax.set_ylabel(f"q{j + 1}")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(f"Fig. {fig_no}: trajectories in the e{i + 1}–e{j + 1} plane (CO2, h = 0.01)", fontsize=9)
        ax.legend(fontsize=7, markerscale=4)
        paths.append(save(fig, out, f"fig{fig_no}_trajectories_e{i + 1}e{j + 1}.png"))
    return paths


def thermal_figures(co2, ho, ho_name, out):
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.0, 3.6), dpi=100)
    for e in range(3):
        ax.plot(co2["t"], co2["theta"][:, e], lw=0.5, label=f"θ{e + 1}")
    ax.set_xlabel("time")
    ax.set_ylabel("temperature")
    ax.set_title("Fig. 12: spring temperatures (CO2, h = 0.01)", fontsize=9)
    ax.legend(fontsize=7)
    paths = [save(fig, out, "fig12_temperatures.png")]

    fig, ax = plt.subplots(figsize=(6.0, 3.6), dpi=100)
    for run, style, name in ((co2, "-", "CO2"), (ho, ":", ho_name.upper())):
        eta = run["eta"]
        for e in range(3):
            ax.plot(run["t"], eta[:, e], style, lw=1.2, label=f"η{e + 1} {name}")
        ax.plot(run["t"], eta.sum(axis=1), style, lw=1.2, label=f"ηt {name}")
    ax.set_xlabel("time")
    ax.set_ylabel("entropy")
    ax.set_title("Fig. 13: spring entropies and their total", fontsize=9)
    ax.legend(fontsize=6, ncol=2)
    paths.append(save(fig, out, "fig13_entropies.png"))

    fig, ax = plt.subplots(figsize=(6.0, 3.6), dpi=100)
    for run, style, name in ((co2, "-", "CO2"), (ho, ":", ho_name.upper())):
        for k in range(3):
            ax.plot(run["t_diag"], run["L"][:, k], style, lw=1.2, label=f"A{k + 1} {name}")
    ax.set_xlabel("time")
    ax.set_ylabel("angular momentum")
    ax.set_title("Fig. 14: angular momentum about the anchor", fontsize=9)
    ax.legend(fontsize=6, ncol=2)
    paths.append(save(fig, out, "fig14_angular_momentum.png"))
    return paths


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join("examples-out", "paper_chain"))
    ap.add_argument("--smoke", action="store_true", help="a reduced run, seconds")
    ap.add_argument("--serial", action="store_true", help="no Dask")
    ap.add_argument("--scheduler", default=None, help="an existing Dask scheduler")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    ho = HIGH_ORDER
    conv_names = PAPER_INTEGRATORS + EXTRA_INTEGRATORS
    halvings = 3 if args.smoke else 8
    t_long = 10.0 if args.smoke else 100.0
    numbers = {}
    with Runner(serial=args.serial or args.smoke, scheduler=args.scheduler) as runner:
        conv = convergence_study("chain", conv_names, dt=0.1, halvings=halvings, t_end=1.0, runner=runner)
        for q, fig_no in (("position", 6), ("momentum", 7), ("temperature", 8)):
            convergence_figure(conv, q, os.path.join(args.out, f"fig{fig_no:02d}_convergence_{q}.png"))
        conv.to_csv(os.path.join(args.out, "convergence.csv"))
        conv.slopes_to_csv(os.path.join(args.out, "slopes.csv"))
        print(conv.summary())
        numbers["slopes"] = {f"{n}/{q}": fit.slope for (n, q), fit in conv.slopes.items()}

        cost_names = PAPER_INTEGRATORS + EXTRA_INTEGRATORS
        cost = cost_study("chain", cost_names, dt=0.1 if not args.smoke else 0.05, halvings=halvings,
                          t_end=1.0 if args.smoke else 10.0, repeats=1 if args.smoke else 5,
                          scipy={"DOP853": [1e-4, 1e-8]} if args.smoke else
                          {"DOP853": [10.0**-k for k in range(3, 13)], "RK45": [10.0**-k for k in range(3, 10)]},
                          runner=runner, one_at_a_time=True)
        cost_figure(cost, os.path.join(args.out, "fig09_cost.png"))
        cost.to_csv(os.path.join(args.out, "cost.csv"))
        summary = cost.summary()
        with open(os.path.join(args.out, "cost_summary.txt"), "w") as f:
            f.write(summary + "\n")
        print(summary)

        energy = energy_study("chain", ["co2", ho], h=0.01, t_end=t_long, runner=runner)
    energy.write(os.path.join(args.out, "energy"))
    for tag, fig in (("a_full", "fig15a"), ("b_zoom", "fig15b"), ("c_zoom", "fig15c")):
        os.replace(os.path.join(args.out, "energy", f"energy_{tag}.png"), os.path.join(args.out, f"{fig}_energy_{tag[2:]}.png"))
    print(energy.summary())
    numbers["energy"] = energy.statistics()
    numbers["initial_energy"] = energy.initial_energy

    co2_run = record_run("co2", 0.01, t_long)
    ho_run = record_run(ho, 0.01, t_long)
    trajectory_figures(co2_run, args.out)
    thermal_figures(co2_run, ho_run, ho, args.out)
    numbers["temperature_range"] = (float(co2_run["theta"].min()), float(co2_run["theta"].max()))
    numbers["entropy_total"] = float(co2_run["eta"][-1].sum())
    print(f"temperatures between {numbers['temperature_range'][0]:.0f} and {numbers['temperature_range'][1]:.0f}; "
          f"total entropy {numbers['entropy_total']:.6f}; PNGs in {args.out}")
    return numbers


if __name__ == "__main__":
    main()
