"""A thermal shock: the scene scenes/thermal_shock.toml, its ParaView series, and its temperature
profiles against the exact solution of the net's own linear heat equations.

    python examples/thermal_shock.py [--out DIR] [--smoke]

The bar (meshes/thermal_bar.msh, 673 springs) starts at 300 K; from t = 0 its end face x = 0 is
a heat bath at 900 K, its far end is insulated. With thermal coupling beta = 0 the springs'
temperatures obey exactly the linear lattice equations of docs/heat.md with a bath,

    C dθ/dt = −(L + D_b) (θ − θ_b),

L the Laplacian of the pair conductances κ_ef = Σ_i g_e g_f / G_i (the junction rule, from
``thermonet.heat.graph.pair_graph`` on the user's numbering, the bath nodes not eliminated),
D_b the diagonal of g_e over the springs' bath ends, C the heat capacities. Their solution
θ_b + exp(−C⁻¹(L + D_b) t)(θ(0) − θ_b) (``scipy.sparse.linalg.expm_multiply``) is the
yardstick: the integrator (CO2 with conduction sweeps of node-star exchanges around it)
differs from it by its O(h²) error only, which the example measures at h and h/2 with
conduction every step, and at the scene's h with conduction every k steps as "auto" picks k and its sub-sweeps.
The scene's small beta = 0.002 lets the hot end expand (a 1.2 % thermal strain at 900 K);
the mechanical work this takes and gives back changes temperatures by a few thousandths of a
kelvin (reported as the "coupling" difference to the beta = 0 run at the same h: a change of
the physics, not an error, so it does not shrink with h).

Writes, in OUT (default thermonet-out/thermal_shock_example): the scene's run in OUT/run
(thermal_shock.pvd with its frames, diagnostics.csv, summary.json) and thermal_shock_profiles.png (temperature
against x at four times, the run's springs averaged in slices of the bar, the lattice solution
as lines), and prints the errors. ``--smoke``: the profiles to t = 2 only, no ParaView run.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import expm_multiply

from thermonet.heat.graph import bath_ends, pair_graph
from thermonet.layout import build_layout
from thermonet.scenes import load_scene

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "thermal_shock.toml"
TIMES = (1.0, 5.0, 10.0, 20.0)
SMOKE_TIMES = (0.5, 1.0, 2.0)


def heat_operator(net, g: np.ndarray, capacity: np.ndarray, bath_nodes) -> sp.csr_matrix:
    """(m, m) sparse M = C⁻¹ (L + D_b), so that dθ/dt = −M (θ − θ_b) for one bath at θ_b.

    g, capacity: (m,) conductances and heat capacities (user numbering); bath_nodes: node indices
    held at the bath temperature. L: pair conductances of the junctions (every other node), as a
    graph Laplacian; D_b: Σ g_e over the bath ends of each spring."""
    layout = build_layout(net, renumber=False)   # user numbering: springs and nodes as given
    m = net.n_springs
    bath_of_node = np.full(net.n_nodes, -1, dtype=np.int64)
    bath_of_node[np.asarray(bath_nodes)] = 0
    graph = pair_graph(layout, np.asarray(g, dtype=np.float64)[None, :], junction=bath_of_node < 0)
    kappa = graph.kappa[:, 0]
    e, f = graph.first, graph.second
    laplacian = sp.coo_matrix((np.r_[-kappa, -kappa], (np.r_[e, f], np.r_[f, e])), shape=(m, m)).tocsr()
    diagonal = np.bincount(np.r_[e, f], weights=np.r_[kappa, kappa], minlength=m)
    springs, _ = bath_ends(layout, bath_of_node)
    diagonal += np.bincount(springs, weights=np.asarray(g)[springs], minlength=m)
    return sp.diags(1.0 / np.asarray(capacity)) @ (laplacian + sp.diags(diagonal))


def lattice_solution(M, theta0: np.ndarray, theta_b: float, times) -> np.ndarray:
    """(len(times), m) θ(t) = θ_b + exp(−M t)(θ(0) − θ_b) at each time."""
    start = np.asarray(theta0, dtype=np.float64) - theta_b
    return np.array([theta_b + expm_multiply(-M * t, start) for t in times])


def scene_run(h: float, times, beta: float | None = None, overrides=(), every="auto"):
    """(simulation, (len(times), m) spring temperatures at each time) of the scene run with step
    h (and thermal coupling beta, default the scene's), conduction every ``every`` steps."""
    every = f'"{every}"' if every == "auto" else every
    sets = [f"integrator.h={h!r}", f"integrator.t_end={max(times)!r}", f"effects.conduction_every={every}",
            *overrides]
    if beta is not None:
        sets.append(f"materials.bar.beta={beta!r}")
    sim = load_scene(SCENE, sets).build().simulation
    out = []
    for t in times:
        sim.run(steps=int(round((t - sim.time) / h)), diagnostics_every=int(round(0.5 / h)))
        out.append(sim.temperatures())
    return sim, np.array(out)


def comparison(h: float, times, beta: float = 0.0) -> dict:
    """The scene at steps h and h/2 (thermal coupling beta; conduction every step), and at h
    with conduction "auto", against the lattice solution: errors max over springs at each time,
    relative to the shock θ_b − θ(0); the ratio of the first two."""
    sim, coarse = scene_run(h, times, beta, every=1)
    _, fine = scene_run(h / 2, times, beta, every=1)
    auto_sim, auto = scene_run(h, times, beta)
    heat = sim.system.heat
    net = sim.net
    g = sim.layout.springs_to_user(heat.conductance)
    capacity = sim.layout.springs_to_user(heat.capacity)
    theta_b = float(heat.functions[0].params[0])
    theta0 = np.full(net.n_springs, 300.0)
    exact = lattice_solution(heat_operator(net, g, capacity, net.node_groups["hot_end"]), theta0, theta_b, times)
    scale = theta_b - 300.0
    err_h = np.abs(coarse - exact).max(axis=1) / scale
    err_h2 = np.abs(fine - exact).max(axis=1) / scale
    return {"h": h, "times": list(times), "error_h": err_h, "error_h2": err_h2, "ratio": err_h / err_h2,
            "error_auto": np.abs(auto - exact).max(axis=1) / scale, "k_auto": auto_sim.conduction_cycle.k,
            "sweeps_auto": auto_sim.conduction_cycle.sweeps,
            "exact": exact, "run": coarse, "sim": sim}


def profile_plot(net, times, exact, run, coupled, path: str) -> None:
    from thermonet.studies.plots import pyplot

    plt = pyplot()
    mid = 0.5 * (net.positions[net.edges[:, 0], 0] + net.positions[net.edges[:, 1], 0])
    edges = np.linspace(0.0, mid.max() + 1e-9, 17)
    slot = np.digitize(mid, edges) - 1
    centre = 0.5 * (edges[1:] + edges[:-1])

    def sliced(theta):
        return np.bincount(slot, weights=theta, minlength=16) / np.bincount(slot, minlength=16)

    fig, ax = plt.subplots(figsize=(7, 4.2))
    for i, t in enumerate(times):
        colour = f"C{i}"
        ax.plot(centre, sliced(exact[i]), "-", color=colour, label=f"t = {t:g}: lattice solution")
        ax.plot(centre, sliced(run[i]), "o", color=colour, mfc="none", label="run, beta = 0" if i == 0 else None)
        ax.plot(centre, sliced(coupled[i]), "x", color=colour, label="run, beta = 0.002" if i == 0 else None)
    ax.set_xlabel("x (spring midpoints, mean over slices of 0.5)")
    ax.set_ylabel("spring temperature θ (K)")
    ax.set_title("thermal shock: bath at 900 K on x = 0, far end insulated")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="thermonet-out/thermal_shock_example")
    ap.add_argument("--smoke", action="store_true", help="profiles to t = 2 only, no ParaView run")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    times = SMOKE_TIMES if args.smoke else TIMES
    if not args.smoke:
        from thermonet.cli.main import main as thermonet

        code = thermonet(["run", str(SCENE), "--out", os.path.join(args.out, "run"), "--overwrite", "--quiet"])
        if code != 0:
            raise SystemExit(f"thermonet run {SCENE} failed with exit code {code}")
    h = 0.01
    linear = comparison(h, times)
    _, coupled = scene_run(h, times, every=1)    # the scene's beta
    coupling = np.abs(coupled - linear["run"]).max(axis=1)   # what beta changes, at the same h
    sim = linear["sim"]
    profile_plot(sim.net, times, linear["exact"], linear["run"], coupled,
                 os.path.join(args.out, "thermal_shock_profiles.png"))
    k, j = linear["k_auto"], linear["sweeps_auto"]
    print(f"thermal shock, {sim.net.n_springs} springs; conduction every step, and \"auto\" (every {k} steps, "
          f"{j} sub-sweep{'s' if j != 1 else ''})")
    print("   t    max|θ − θ_lattice| / 600 K                    ratio   beta 0.002 vs 0: max|Δθ| (K)")
    print(f"        h = {h:g}      h = {h / 2:g}     h = {h:g}, k = {k}, j = {j}")
    for i, t in enumerate(times):
        print(f"{t:5g}   {linear['error_h'][i]:.3e}   {linear['error_h2'][i]:.3e}   {linear['error_auto'][i]:.3e}"
              f"   {linear['ratio'][i]:6.3f}   {coupling[i]:.3e}")
    return {"times": list(times), "error_h": linear["error_h"].tolist(), "error_h2": linear["error_h2"].tolist(),
            "error_auto": linear["error_auto"].tolist(), "k_auto": k, "sweeps_auto": j,
            "ratio": linear["ratio"].tolist(), "coupling": coupling.tolist(), "n_springs": sim.net.n_springs,
            "exact": linear["exact"]}


if __name__ == "__main__":
    main()
