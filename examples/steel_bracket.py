"""A steel part heated over a second of physical time, with EM2 far above the explicit limit.

    python examples/steel_bracket.py [--out DIR] [--t-end SECONDS] [--smoke]

The L-bracket of meshes/bracket.msh (gmsh tetrahedra, about 5 mm, SI units) made of steel by
its continuum properties (docs/continuum.md: E = 200 GPa, α = 12e-6 /K, ρ = 7850 kg/m³,
ρ c_p = 3.6e6 J/(m³ K), k = 45 W/(m K)), bolted at its base (node group "clamp"), which is also
a heat bath: the machine it is bolted to warms from 293.15 K to 393.15 K over the first second
(a ramp) and stays there. Heat flows into the part by conduction; the part expands. CO2's
stable step here is about 4e-7 s, so a second takes it 2.6 million steps; EM2 runs at
h = 1 ms, about 2 500× that step (its "auto" path: SuperLU with kept factorizations; the run
summary says why), 1 000 steps per simulated second.

Writes, in OUT (default thermonet-out/steel_bracket_example): the scene it runs
(steel_bracket.toml), the run (OUT/run: steel_bracket.pvd with its frames for ParaView,
diagnostics.csv, summary.json) and steel_bracket.png (the part's coldest and hottest spring,
the heat the bath gave, and the energy balance against time). ``--smoke``: 20 steps.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import time
from pathlib import Path

MESH = Path(__file__).resolve().parents[1] / "meshes" / "bracket.msh"
H = 1e-3

SCENE = """# written by examples/steel_bracket.py
name = "steel_bracket"
description = "steel L-bracket (continuum material, SI units) heated through its bolted base, EM2"

[net]
mesh = "{mesh}"

[materials.bracket]
model = "hencky"
youngs_modulus = 200e9        # Pa
thermal_expansion = 12e-6     # 1/K
density = 7850.0              # kg/m³
heat_capacity = 3.6e6         # J/(m³ K)
conductivity = 45.0           # W/(m K)
theta0 = 293.15               # K

[initial.temperature]
uniform = 293.15

[effects]
thermal = true
conduction = true
anchors = ["clamp"]

[baths.machine]
group = "clamp"
temperature = {{ start = 293.15, end = 393.15, duration = 1.0 }}

[integrator]
name = "em2"
h = {h!r}
t_end = {t_end!r}

[output]
frames_every = {frames}
diagnostics_every = {diagnostics}
checkpoint_every = 0
"""


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = [float(r["time"]) for r in rows]
    fig, ax = plt.subplots(1, 3, figsize=(13, 3.6))
    ax[0].plot(t, [float(r["theta_max"]) for r in rows], label="hottest spring")
    ax[0].plot(t, [float(r["theta_min"]) for r in rows], label="coldest spring")
    ax[0].set_xlabel("t (s)")
    ax[0].set_ylabel("θ (K)")
    ax[0].legend()
    ax[1].plot(t, [float(r["heat_machine"]) for r in rows])
    ax[1].set_xlabel("t (s)")
    ax[1].set_ylabel("heat from the machine (J)")
    ax[2].semilogy(t, [max(abs(float(r["energy_balance"])), 1e-18) for r in rows])
    ax[2].set_xlabel("t (s)")
    ax[2].set_ylabel("|H − H(0) − Q| (J)")
    fig.suptitle("steel bracket heated through its base, EM2 at h = 1 ms (≈ 2 500× CO2's stable step)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="thermonet-out/steel_bracket_example")
    ap.add_argument("--t-end", type=float, default=2.0, help="simulated seconds (default 2)")
    ap.add_argument("--smoke", action="store_true", help="20 steps")
    args = ap.parse_args(argv)
    t_end = 20 * H if args.smoke else args.t_end
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    scene = out / "steel_bracket.toml"
    steps = int(round(t_end / H))
    scene.write_text(SCENE.format(mesh=MESH.as_posix(), h=H, t_end=steps * H, frames=max(1, steps // 40),
                                  diagnostics=max(1, steps // 200)))
    from thermonet.cli.main import main as thermonet

    t0 = time.perf_counter()
    code = thermonet(["run", str(scene), "--out", str(out / "run"), "--overwrite", "--quiet"])
    if code != 0:
        raise SystemExit(f"thermonet run {scene} failed with exit code {code}")
    wall = time.perf_counter() - t0
    rows = list(csv.DictReader(open(out / "run" / "diagnostics.csv")))
    summary = json.loads((out / "run" / "summary.json").read_text())
    newton = summary["newton"]
    plot(rows, out / "steel_bracket.png")
    last = rows[-1]
    balance = max(abs(float(r["energy_balance"])) for r in rows)
    heat = float(last["heat_machine"])
    print(f"steel bracket: {summary['springs']} springs, {steps} steps of {H:g} s to t = {float(last['time']):g} s "
          f"in {wall:.1f} s (compilation included)")
    print(f"  Newton: {newton['linear_solver']}, {newton['iterations_mean']:.2f} iterations/step, "
          f"{100 * newton['substep_fraction']:.0f} % substepped; {newton['path_reason']}")
    print(f"  hottest spring {float(last['theta_max']):.2f} K, coldest {float(last['theta_min']):.2f} K; "
          f"heat from the machine {heat:.4g} J; |energy balance| ≤ {balance:.3g} J")
    return {"steps": steps, "wall_s": wall, "theta_max": float(last["theta_max"]),
            "theta_min": float(last["theta_min"]), "heat": heat, "energy_balance": balance,
            "newton": newton, "springs": summary["springs"]}


if __name__ == "__main__":
    main()
