"""A large 3D net: a gmsh tetrahedral bar of ≥ 1e5 springs, clamped at one end and set
twisting, with thermo-elastic heating and cooling of its springs.

    python examples/large_net.py [--out DIR] [--smoke]

The bar [0, 4] × [0, 1] × [0, 1] is meshed by the gmsh Python API (mesh size 0.06 gives about
1.2e5 springs: the unique edges of the tetrahedra); its face x = 0 is anchored. Every spring is
"hencky" (c = 100, beta = 0.2, C0 = 5, theta0 = 300), masses are lumped from density 1, and the
initial velocity is a twist about the bar's axis growing linearly along it. CO2 runs with a
step of 0.4× the estimated stability limit (thermonet.stability) to t = 0.4 (the tip's
surface starts at speed 20; --t-end changes it).

Why t = 0.4: on the 0.06 mesh the linearized net's lowest modes (shift-invert Lanczos on the
mass-weighted adiabatic stiffness of thermonet.stability.stiffness_matrix, free dofs) are two
bending modes at ω = 45.7, 46.3 (period 0.137) and the first torsional mode at ω = 168.6
(period 0.0373), which holds 98.6 % of the initial twist's kinetic energy. t = 0.4 is about
10.7 periods of that torsional mode and 2.9 of the lowest bending mode: 45,476 steps, 49 s of
stepping on this project's 2-core machine, both cores free (docs/large-net.md).
With anchors at several points neither linear nor angular momentum is conserved; energy and
every spring's entropy are. Writes large_net_temperature.png (spring temperatures on the bar's
mid-plane at the end) and large_net_conservation.png, and prints the conservation summary.
``--smoke``: mesh size 0.3 and 200 steps.
"""

from __future__ import annotations

import argparse
import os

import numpy as np

import thermonet as tn
from thermonet.studies.plots import pyplot

LENGTH, PARAMETERS, TWIST_RATE = 4.0, dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0), 40.0
T_END = 0.4   # ≈ 10.7 periods of the first torsional mode (ω = 168.6) on the 0.06 mesh: see above


def gmsh_bar(mesh_size: float) -> tn.Net:
    """The tetrahedral bar as a net, built with gmsh and passed through meshio."""
    import gmsh
    import meshio

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("bar")
        gmsh.model.occ.addBox(0, 0, 0, LENGTH, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMin", mesh_size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", mesh_size)
        gmsh.model.mesh.generate(3)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        points = coords.reshape(-1, 3)
        index = {int(t): i for i, t in enumerate(tags)}
        types, _, nodes = gmsh.model.mesh.getElements(3)
        tets = np.asarray(nodes[list(types).index(4)], dtype=np.int64).reshape(-1, 4)
        tets = np.vectorize(index.__getitem__)(tets)
    finally:
        gmsh.finalize()
    mesh = meshio.Mesh(points, [("tetra", tets)])
    net = tn.from_meshio(mesh, density=1.0, source=f"gmsh bar, mesh size {mesh_size}")
    net.anchored[:] = net.positions[:, 0] < 1e-9
    return net


def twist_velocities(net: tn.Net) -> np.ndarray:
    """(n, 3) rotation about the axis y = z = 0.5 with angular speed growing along x."""
    x = net.positions
    omega = TWIST_RATE * x[:, 0] / LENGTH
    v = np.zeros_like(x)
    v[:, 1] = -omega * (x[:, 2] - 0.5)
    v[:, 2] = omega * (x[:, 1] - 0.5)
    v[net.anchored] = 0.0
    return v


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join("examples-out", "large_net"))
    ap.add_argument("--smoke", action="store_true", help="a coarse mesh and 200 steps")
    ap.add_argument("--t-end", type=float, default=T_END, help=f"final time (default {T_END})")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    from thermonet.stability import stable_step

    net = gmsh_bar(0.3 if args.smoke else 0.06)
    sim = tn.Simulation(net, model="hencky", parameters=PARAMETERS, velocities=twist_velocities(net),
                        integrator="co2", h=1.0)
    h = 0.4 * stable_step(sim)["h_max"]
    sim = tn.Simulation(net, model="hencky", parameters=PARAMETERS, velocities=twist_velocities(net),
                        integrator="co2", h=h)
    steps = 200 if args.smoke else int(round(args.t_end / h))
    print(f"{net.n_nodes} nodes, {net.n_springs} springs, {int(net.anchored.sum())} anchored; "
          f"CO2 h = {h:.3g}, {steps} steps to t = {steps * h:.3g}")
    diag = sim.run(steps=steps, diagnostics_every=max(1, steps // 200))
    summary = sim.conservation_summary()
    for name, s in summary.items():
        if name == "_run":
            continue
        print(f"  {name:<8} initial {s['initial']:>14.6g}  max deviation {s['max_deviation']:.3e}  (relative {s['relative']:.1e})")
    run = summary["_run"]
    print(f"  {run['steps']} steps in {run['wall_time_s']:.2f} s: {run['spring_steps_per_s']:.3g} spring-steps/s")
    print(f"  spring temperatures over the run in [{diag.theta_min.min():.3f}, {diag.theta_max.max():.3f}]")

    plt = pyplot()
    theta = sim.temperatures()
    x = sim.state.positions
    mid = 0.5 * (x[net.edges[:, 0]] + x[net.edges[:, 1]])
    x0 = net.positions
    slab = np.abs(0.5 * (x0[net.edges[:, 0], 2] + x0[net.edges[:, 1], 2]) - 0.5) < (0.12 if not args.smoke else 0.3)
    fig, ax = plt.subplots(figsize=(7.5, 2.8), dpi=100)
    sc = ax.scatter(mid[slab, 0], mid[slab, 1], c=theta[slab], s=3 if not args.smoke else 12, cmap="coolwarm",
                    vmin=np.percentile(theta, 1), vmax=np.percentile(theta, 99))
    fig.colorbar(sc, ax=ax, label="temperature")
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(f"spring temperatures near the mid-plane z = 0.5 at t = {sim.time:.3g} ({net.n_springs} springs)", fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "large_net_temperature.png"))
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(8.0, 3.0), dpi=100)
    axes[0].plot(diag.time, diag.energy - diag.energy[0], lw=0.8)
    axes[0].set_title("energy − initial", fontsize=9)
    L = diag.angular_momentum
    axes[1].plot(diag.time, diag.theta_min, lw=0.8, label="min θ")
    axes[1].plot(diag.time, diag.theta_max, lw=0.8, label="max θ")
    axes[1].set_title("spring temperature extremes", fontsize=9)
    axes[1].legend(fontsize=7)
    for ax in axes:
        ax.set_xlabel("time")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "large_net_conservation.png"))
    plt.close(fig)
    return {"n_springs": net.n_springs, "h": h, "steps": steps, "summary": summary,
            "theta_range": (float(theta.min()), float(theta.max()))}


if __name__ == "__main__":
    main()
