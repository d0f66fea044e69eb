"""The thermo-elastic pendulum of Mata & Lew §3.1 (their Fig. 2): a mass on one spring whose
other end is fixed, moving in a plane, with the "quadratic" free energy (26); no gravity.

    python examples/pendulum.py [--out DIR] [--smoke]

The paper gives the equations, not numbers; this script fixes m = 1, r0 = 1, E = 100,
beta = 1, C0 = 5, theta0 = 300, eta0 = 0, r(0) = 1.2, θ(0) = 300, ṙ(0) = 0, r(0)ϕ̇(0) = 3.
thermonet integrates it as a two-node net in Cartesian coordinates; the yardstick is the
paper's own polar form (28)/(30) — r, ϕ, p_r, Φ with p_ϕ and η constant — integrated by SciPy's
DOP853 at rtol = atol = 1e-13, code that shares nothing with the net. The script reports the
largest differences in r, ϕ and θ along the run for each integrator and writes
pendulum_orbit.png, pendulum_r_theta.png and pendulum_error.png.
"""

from __future__ import annotations

import argparse
import os

import numpy as np
from scipy.integrate import solve_ivp

import thermonet as tn
from thermonet.studies.plots import pyplot

M, R0, E, BETA, C0, THETA0, ETA0 = 1.0, 1.0, 100.0, 1.0, 5.0, 300.0, 0.0
R_START, THETA_START, TANGENTIAL_SPEED = 1.2, 300.0, 3.0


def pendulum_simulation(integrator: str, h: float) -> tn.Simulation:
    net = tn.Net(positions=[[0.0, 0.0, 0.0], [R_START, 0.0, 0.0]], edges=[[0, 1]], masses=[1.0, M],
                 anchored=[True, False], rest_lengths=[R0], source="pendulum")
    return tn.Simulation(net, model="quadratic", parameters=dict(E=E, beta=BETA, C0=C0, theta0=THETA0, eta0=ETA0),
                         temperatures=[THETA_START], velocities=[[0, 0, 0], [0.0, TANGENTIAL_SPEED, 0.0]],
                         integrator=integrator, h=h)


def polar_solution(t_eval: np.ndarray) -> dict:
    """The paper's polar Hamiltonian equations (30) by DOP853: r, ϕ, θ at t_eval."""
    eta = C0 / THETA0 * (THETA_START - THETA0) + BETA * (R_START - R0) + ETA0   # (27b)
    p_phi = M * R_START * TANGENTIAL_SPEED

    def temperature(r):
        return THETA0 + THETA0 / C0 * (eta - ETA0 - BETA * (r - R0))            # (27c)

    def rhs(t, y):
        r, phi, p_r, Phi = y
        f_r = -E / R0 * (r - R0) + BETA * (temperature(r) - THETA0)           # (27a)
        return [p_r / M, p_phi / (M * r * r), p_phi**2 / (M * r**3) + f_r, temperature(r)]

    sol = solve_ivp(rhs, (0.0, t_eval[-1]), [R_START, 0.0, 0.0, 0.0], method="DOP853", rtol=1e-13, atol=1e-13,
                    t_eval=t_eval)
    r = sol.y[0]
    return {"r": r, "phi": sol.y[1], "theta": temperature(r)}


def net_history(integrator: str, h: float, t_end: float) -> dict:
    sim = pendulum_simulation(integrator, h)
    t, r, phi, theta = [], [], [], []

    def observe(s):
        x = s.state.positions[1]
        t.append(s.time)
        r.append(np.hypot(x[0], x[1]))
        phi.append(np.arctan2(x[1], x[0]))
        theta.append(s.temperatures()[0])

    sim.run(t_end=t_end, diagnostics_every=10, observers=[(1, observe)])
    return {"t": np.array(t), "r": np.array(r), "phi": np.unwrap(np.array(phi)), "theta": np.array(theta),
            "energy_range": float(np.ptp(sim.diagnostics.energy))}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join("examples-out", "pendulum"))
    ap.add_argument("--smoke", action="store_true", help="t = 1 instead of 10")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    t_end, h = (1.0 if args.smoke else 10.0), 0.01
    names = [n for n in ("co2", "gtr-1/2", "co4", "ho4") if n in tn.available_integrators()]

    runs = {n: net_history(n, h, t_end) for n in names}
    exact = polar_solution(runs[names[0]]["t"])
    numbers = {}
    for n, run in runs.items():
        numbers[n] = {q: float(np.max(np.abs(run[q] - exact[q]))) for q in ("r", "phi", "theta")}
        numbers[n]["energy_range"] = run["energy_range"]
        print(f"{n:>7} h={h:g}: max |Δr| {numbers[n]['r']:.2e}, max |Δϕ| {numbers[n]['phi']:.2e}, "
              f"max |Δθ| {numbers[n]['theta']:.2e}, energy range {run['energy_range']:.2e}")
    numbers["theta_range"] = (float(exact["theta"].min()), float(exact["theta"].max()))
    numbers["r_range"] = (float(exact["r"].min()), float(exact["r"].max()))
    print(f"polar DOP853 solution: r in [{numbers['r_range'][0]:.4f}, {numbers['r_range'][1]:.4f}], "
          f"θ in [{numbers['theta_range'][0]:.3f}, {numbers['theta_range'][1]:.3f}]")

    plt = pyplot()
    co2 = runs["co2"]
    fig, ax = plt.subplots(figsize=(4.6, 4.6), dpi=100)
    ax.plot(exact["r"] * np.cos(exact["phi"]), exact["r"] * np.sin(exact["phi"]), lw=2.5, color="0.8", label="polar ODE")
    ax.plot(co2["r"] * np.cos(co2["phi"]), co2["r"] * np.sin(co2["phi"]), lw=0.6, label="thermonet CO2")
    ax.plot([0], [0], "k+")
    ax.set_aspect("equal")
    ax.set_title("thermo-elastic pendulum: orbit of the mass", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "pendulum_orbit.png"))
    plt.close(fig)

    fig, axes = plt.subplots(2, 1, figsize=(6.0, 4.4), dpi=100, sharex=True)
    axes[0].plot(co2["t"], exact["r"], lw=2.5, color="0.8", label="polar ODE")
    axes[0].plot(co2["t"], co2["r"], lw=0.7, label="thermonet CO2")
    axes[0].set_ylabel("r")
    axes[0].legend(fontsize=7)
    axes[1].plot(co2["t"], exact["theta"], lw=2.5, color="0.8")
    axes[1].plot(co2["t"], co2["theta"], lw=0.7, color="C3")
    axes[1].set_ylabel("temperature θ")
    axes[1].set_xlabel("time")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "pendulum_r_theta.png"))
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6.0, 3.4), dpi=100)
    for n, run in runs.items():
        ax.semilogy(run["t"][1:], np.abs(run["r"] - exact["r"])[1:] + 1e-17, lw=0.7, label=n.upper())
    ax.set_xlabel("time")
    ax.set_ylabel("|r − r_ODE|")
    ax.set_title(f"difference from the polar ODE solution, h = {h:g}", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "pendulum_error.png"))
    plt.close(fig)
    return numbers


if __name__ == "__main__":
    main()
