"""The three convergence checks of continuum materials (docs/continuum.md), on gmsh bars at three
refinements: free thermal expansion, the longitudinal wave speed, the decay of a Fourier
temperature mode; and total mass and heat capacity.

    python -m thermonet.materials.checks        # prints the table of docs/continuum.md

Needs gmsh (the test extra) to mesh the bars.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np

from ..builders import read_mesh
from ..simulation import Simulation
from .report import spring_rest_values
from .rigidity import stiffness

#: the bar (length, width, height) and the material the checks use (consistent units; any
#: unit system works: the rule is linear in every property)
BAR = (1.0, 0.25, 0.25)
MATERIAL = {"youngs_modulus": 2.0, "density": 1.5, "heat_capacity": 2.0, "conductivity": 0.5,
            "thermal_expansion": 1e-3}
THETA0 = 300.0
#: mesh sizes of the three refinements
SIZES = (0.125, 0.0625, 0.04)


def bar_mesh(path: str, size: float, lengths=BAR, seed: int = 1) -> str:
    """Write a gmsh tetrahedral mesh of a box ``lengths`` at mesh size ``size`` to ``path``."""
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.model.add("bar")
        gmsh.model.occ.addBox(0, 0, 0, *lengths)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMin", size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.option.setNumber("Mesh.RandomSeed", seed)
        gmsh.model.addPhysicalGroup(3, [1], name="bar")
        gmsh.model.mesh.generate(3)
        gmsh.write(path)
    finally:
        gmsh.finalize()
    return path


def bar_net(size: float, folder: str | None = None):
    """The spring net of the bar at mesh size ``size`` (its mesh written to ``folder``)."""
    folder = folder or tempfile.mkdtemp(prefix="thermonet-bar-")
    path = bar_mesh(os.path.join(folder, f"bar_{size:g}.msh"), size)
    return read_mesh(path)


def parameters(**changes) -> dict:
    return {**MATERIAL, "theta0": THETA0, **changes}


def free_expansion(net, dtheta: float = 50.0) -> dict:
    """Heat the free block by Δθ and scale it by exp(α Δθ) (hencky: a logarithmic strain α Δθ in
    every direction): the largest spring tension there relative to the thermal stress scale
    c α Δθ / l (0: the scaled block is the heated block's equilibrium), and the block's strain
    per axis over α Δθ."""
    import dataclasses

    alpha = MATERIAL["thermal_expansion"]
    heated = dataclasses.replace(net, positions=net.positions * np.exp(alpha * dtheta), rest_lengths=net.rest_lengths)
    sim = Simulation(heated, parameters=parameters(), temperatures=THETA0 + dtheta, integrator="co2", h=1e-3)
    c = 6.0 * MATERIAL["youngs_modulus"] * sim.continuum.volume
    scale = c * alpha * dtheta / sim.lengths()
    strain = np.log(np.ptp(heated.positions, axis=0) / np.ptp(net.positions, axis=0)) / (alpha * dtheta)
    return {"residual": float(np.max(np.abs(sim.tensions())) / np.max(scale)), "strain": strain}


def wave_speed(net) -> float:
    """The bar's lowest longitudinal mode ω (free ends; the net's isothermal stiffness at rest,
    d²F/dl² of its springs from the model; its lumped masses): ω L / π over √(E/ρ)."""
    from scipy.sparse import diags
    from scipy.sparse.linalg import eigsh

    sim = Simulation(net, parameters=parameters(), integrator="co2", h=1e-3)
    P = sim.layout.springs_to_user(sim.system.parameters.T).T
    k, _ = spring_rest_values(sim.model, P, sim.net.rest_lengths)
    x = sim.net.positions
    K = stiffness(x, sim.net.edges, k, np.eye(3))
    masses = np.repeat(sim.net.masses, 3)
    L = np.ptp(x[:, 0])
    count = min(30, K.shape[0] - 2)
    w2, modes = eigsh(K, k=count, M=diags(masses), sigma=-1e-6 * K.diagonal().mean() / masses.mean(), which="LM")
    shape = np.zeros_like(x)
    shape[:, 0] = np.cos(np.pi * (x[:, 0] - x[:, 0].min()) / L)
    ref = shape.ravel()
    overlap = (modes.T @ (masses * ref)) ** 2 / np.einsum("ij,ij->j", modes, masses[:, None] * modes)
    omega = np.sqrt(max(w2[int(np.argmax(overlap))], 0.0))
    return float(omega * L / np.pi / np.sqrt(MATERIAL["youngs_modulus"] / MATERIAL["density"]))


def fourier_decay(net, t_end: float = 0.25, h: float = 6.25e-4, amplitude: float = 1.0) -> float:
    """A temperature mode cos(π x / L) in the insulated bar (β = 0), run with conduction: its
    measured decay rate (from the spring temperatures projected on the mode, between t_end/5 and
    t_end) over k q² / c_v."""
    middle = 0.5 * (net.positions[net.edges[:, 0]] + net.positions[net.edges[:, 1]])
    x0, L = net.positions[:, 0].min(), np.ptp(net.positions[:, 0])
    q = np.pi / L
    mode = np.cos(q * (middle[:, 0] - x0))
    sim = Simulation(net, parameters=parameters(thermal_expansion=0.0), temperatures=THETA0 + amplitude * mode,
                     conduction=True, integrator="co2", h=h)
    C = sim.continuum.volume * MATERIAL["heat_capacity"]

    def projection():
        theta = sim.temperatures()
        return float(np.sum(C * (theta - THETA0) * mode) / np.sum(C * mode * mode))

    steps = int(round(t_end / h))
    first = max(1, steps // 5)
    sim.run(steps=first)
    a1, t1 = projection(), sim.state.time
    sim.run(steps=steps - first)
    a2, t2 = projection(), sim.state.time
    rate = np.log(a1 / a2) / (t2 - t1)
    return float(rate / (MATERIAL["conductivity"] * q * q / MATERIAL["heat_capacity"]))


def totals(net) -> dict:
    """Total mass and heat capacity over ρ V and c_v V (V: the mesh's volume)."""
    sim = Simulation(net, parameters=parameters(), integrator="co2", h=1e-3)
    V = float(np.prod(BAR))
    return {"mass": float(sim.net.masses.sum() / (MATERIAL["density"] * V)),
            "heat_capacity": float(sim.continuum.volume.sum() * MATERIAL["heat_capacity"] / (MATERIAL["heat_capacity"] * V))}


def table(sizes=SIZES, folder: str | None = None) -> list[dict]:
    """Every figure at each mesh size."""
    rows = []
    for size in sizes:
        net = bar_net(size, folder)
        rows.append({"size": size, "nodes": net.n_nodes, "springs": net.n_springs,
                     "expansion": free_expansion(net), "wave": wave_speed(net),
                     "fourier": fourier_decay(net), "totals": totals(net)})
    return rows


def main() -> None:  # pragma: no cover - the docs' command
    print(f"bar {BAR[0]:g} x {BAR[1]:g} x {BAR[2]:g}, gmsh tetrahedra; figures are measured / continuum")
    print("| mesh size | nodes | springs | expansion x, y, z | equilibrium residual | wave speed | Fourier decay "
          "| mass | heat capacity |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in table():
        e = r["expansion"]
        print(f"| {r['size']:g} | {r['nodes']} | {r['springs']} | {', '.join(f'{v:.6f}' for v in e['strain'])} | "
              f"{e['residual']:.1e} | {r['wave']:.4f} | {r['fourier']:.4f} | {r['totals']['mass']:.12f} | "
              f"{r['totals']['heat_capacity']:.12f} |")


if __name__ == "__main__":  # pragma: no cover
    main()
