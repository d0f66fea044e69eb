"""``thermonet plot OUTDIR``: PNG plots of a run's diagnostics (matplotlib): energy and its
balance, entropy, momenta, load–displacement per loaded group, and the probes' series."""

from __future__ import annotations

import csv
import os

import numpy as np

from ..errors import InputError

HELP = "plot a run's diagnostics.csv and probe CSVs as PNGs (energy, balance, entropy, momenta, loads, probes)"


def add_args(p) -> None:
    p.add_argument("outdir", metavar="OUTDIR", help="the output folder of `thermonet run`")
    p.add_argument("--to", default=None, metavar="FOLDER", help="where the PNGs go (default OUTDIR/plots)")


def handle(args) -> int:
    files = plot_run(args.outdir, args.to)
    print(f"thermonet: wrote {len(files)} plots to {os.path.dirname(files[0]) if files else args.to}: "
          + ", ".join(os.path.basename(f) for f in files))
    return 0


def read_columns(path: str) -> dict[str, np.ndarray]:
    """The columns of a CSV file with a header row, as float arrays (blank cells NaN)."""
    with open(path) as f:
        rows = list(csv.reader(f))
    if not rows:
        return {}
    header, body = rows[0], rows[1:]
    return {c: np.array([float(r[i]) if i < len(r) and r[i] != "" else np.nan for r in body]) for i, c in enumerate(header)}


def _units(outdir: str) -> str:
    """The run's units from its summary.json (``SI`` with continuum materials), else model units."""
    import json

    try:
        with open(os.path.join(outdir, "summary.json")) as f:
            return json.load(f).get("units", "model units")
    except (OSError, ValueError):
        return "model units"


def plot_run(outdir: str, to: str | None = None) -> list[str]:
    """The PNGs of the run in ``outdir`` (written to ``to``, default OUTDIR/plots); their paths."""
    diagnostics = os.path.join(outdir, "diagnostics.csv")
    if not os.path.isfile(diagnostics):
        raise InputError(f"{outdir}: no diagnostics.csv here; give the output folder of `thermonet run`")
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise InputError("thermonet plot needs matplotlib (pip install matplotlib)") from None
    d = read_columns(diagnostics)
    si = _units(outdir) == "SI"
    time_label = "time (s)" if si else "time (model units)"
    energy_unit = " (J)" if si else " (model units)"
    to = to or os.path.join(outdir, "plots")
    os.makedirs(to, exist_ok=True)
    t = d["time"]
    written = []

    def save(fig, name):
        path = os.path.join(to, name)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)

    fig, axes = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for c in ("energy", "kinetic", "internal", "potential"):
        if c in d:
            axes[0].plot(t, d[c], label=c)
    # what flowed in from outside, beside the energy it changed: heat from baths and sources, the loads' work
    for c, label in (("heat_in", "heat in (baths, sources)"), ("work", "work of the loads")):
        if c in d:
            axes[0].plot(t, d[c], label=label, linestyle="--")
    axes[0].set_ylabel("energy" + energy_unit)
    axes[0].legend()
    if "energy_balance" in d:
        axes[1].plot(t, d["energy_balance"], color="k")
        axes[1].set_ylabel(("H − H(0) − W − ΣQ" if "heat_in" in d and "work" in d else
                            "H − H(0) − W" if "work" in d else "H − H(0) − ΣQ") + energy_unit)
    else:
        axes[1].plot(t, d["energy"] - d["energy"][0], color="k")
        axes[1].set_ylabel("H − H(0)" + energy_unit)
    axes[1].set_xlabel(time_label)
    save(fig, "energy.png")
    if "entropy" in d:
        fig, ax = plt.subplots(figsize=(7, 3.5))
        ax.plot(t, d["entropy"] - d["entropy"][0])
        ax.set_xlabel(time_label)
        ax.set_ylabel("S − S(0)" + (" (J/K)" if si else " (model units)"))
        save(fig, "entropy.png")
    fig, axes = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for c in ("px", "py", "pz"):
        axes[0].plot(t, d[c], label=c)
    for c in ("Lx", "Ly", "Lz"):
        axes[1].plot(t, d[c], label=c)
    axes[0].set_ylabel("linear momentum" + (" (kg m/s)" if si else " (model units)"))
    axes[1].set_ylabel("angular momentum" + (" (kg m²/s)" if si else " (model units)"))
    axes[1].set_xlabel(time_label)
    axes[0].legend()
    axes[1].legend()
    save(fig, "momenta.png")
    for load in sorted({c[:-5] for c in d if c.endswith("_work") and c != "work"}):
        force = "R" if f"{load}_Rx" in d else "F"
        fig, ax = plt.subplots(figsize=(6, 4.5))
        for a in "xyz":
            u, f = d[f"{load}_u{a}"], d[f"{load}_{force}{a}"]
            if np.any(u != 0) or np.any(f != 0):
                sign = -1.0 if force == "R" else 1.0  # a grip pulls the net with −R
                ax.plot(u, sign * f, label=f"{a}")
        ax.set_xlabel(f"{load}: mean displacement of the group" + (" (m)" if si else " (model units)"))
        ax.set_ylabel(("force on the net (−reaction)" if force == "R" else "applied force")
                      + (" (N)" if si else " (model units)"))
        ax.set_title(f"load–displacement: {load}")
        ax.legend()
        save(fig, f"load_{load}.png")
    for name in sorted(f for f in os.listdir(outdir) if f.startswith("probe_") and f.endswith(".csv")):
        p = read_columns(os.path.join(outdir, name))
        fig, ax = plt.subplots(figsize=(7, 3.5))
        ax.fill_between(p["time"], p["min"], p["max"], alpha=0.3, label="min–max")
        ax.plot(p["time"], p["mean"], label="mean")
        ax.set_xlabel(time_label)
        ax.set_title(name[len("probe_"):-4])
        ax.legend()
        save(fig, name[:-4] + ".png")
    return written
