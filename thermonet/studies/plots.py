"""Figures of the studies (matplotlib, Agg backend, imported only when a figure is drawn)."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError

LABELS = {"position": "error in position", "momentum": "error in momentum", "temperature": "error in temperature"}
MARKERS = "osD^v<>phx*"


def pyplot():
    """matplotlib.pyplot on the Agg backend (no display needed)."""
    try:
        import matplotlib
    except ImportError:
        raise InputError("figures need matplotlib: pip install 'thermonet[vis]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def display_name(name: str) -> str:
    return name.upper()


def convergence_figure(study, quantity: str, path) -> None:
    """Error at t_end against h, log-log, one curve per integrator; the fitted slope written at
    the fitted range and the range drawn as a dashed line."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.0, 4.6), dpi=100)
    floor = study.reference.floor(quantity)
    for i, name in enumerate(study.integrators):
        h, e = study.errors(name, quantity)
        ok = np.isfinite(e) & (e > 0)
        line, = ax.loglog(h[ok], e[ok], marker=MARKERS[i % len(MARKERS)], ms=4, lw=1.2, label=display_name(name))
        fit = study.slopes[(name, quantity)]
        if math.isfinite(fit.slope):
            hh = np.array([fit.h_min, fit.h_max])
            ax.loglog(hh, fit.constant * hh**fit.slope, ls="--", lw=2.5, color=line.get_color(), alpha=0.35)
            hm = math.sqrt(fit.h_min * fit.h_max)
            ax.annotate(f"{fit.slope:.2f}", (hm, fit.constant * hm**fit.slope), textcoords="offset points",
                        xytext=(6, -10), color=line.get_color(), fontsize=9, fontweight="bold")
    if floor > 0:
        ax.axhline(floor, color="0.6", lw=0.8, ls=":")
        ax.annotate("reference floor", (ax.get_xlim()[0], floor), textcoords="offset points", xytext=(4, 3),
                    color="0.5", fontsize=7)
    ax.set_xlabel("time step h")
    ax.set_ylabel(f"{LABELS[quantity]} at t = {study.t_end:g}")
    ax.set_title(f"{study.scene}: convergence ({quantity})", fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def cost_figure(study, path, quantity: str = "position") -> None:
    """Error at t_end against median wall-clock time, one curve per integrator and per SciPy
    method (the paper's Fig. 9, axes swapped to the usual work-precision layout)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.8), dpi=100)
    for i, (label, rows) in enumerate(study.curves()):
        t = np.array([r["time"] for r in rows])
        e = np.array([r[quantity] for r in rows])
        ok = np.isfinite(t) & np.isfinite(e) & (e > 0)
        scipy = label.startswith("scipy")
        ax.loglog(t[ok], e[ok], marker=MARKERS[i % len(MARKERS)], ms=4, lw=1.2, ls="--" if scipy else "-",
                  label=label)
    ax.set_xlabel("wall-clock time of the run [s] (median of repeats)")
    ax.set_ylabel(f"{LABELS[quantity]} at t = {study.t_end:g}")
    ax.set_title(f"{study.scene}: what accuracy costs in time", fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def energy_figures(study, out_dir, prefix: str = "energy") -> list[str]:
    """Energy against time at full scale (a), zoomed on a window with every integrator (b) and
    zoomed for the highest-order integrator alone (c) (the paper's Fig. 15); plus entropy and
    momenta. Returns the paths."""
    import os

    plt = pyplot()
    paths = []
    window = study.window

    def draw(names, t_range, tag, title, ylim=None):
        fig, ax = plt.subplots(figsize=(6.0, 3.6), dpi=100)
        for name in names:
            c = study.histories[name]
            t, e = c["time"], c["energy"]
            sel = np.ones_like(t, dtype=bool) if t_range is None else (t >= t_range[0]) & (t <= t_range[1])
            ax.plot(t[sel], e[sel], lw=0.8, label=display_name(name))
        ax.ticklabel_format(axis="y", useOffset=False, style="plain")
        if ylim is not None:
            ax.set_ylim(*ylim)
        ax.set_xlabel("time")
        ax.set_ylabel("total energy")
        ax.set_title(title, fontsize=10)
        ax.legend(fontsize=8)
        ax.grid(True, alpha=0.3)
        fig.tight_layout()
        path = os.path.join(out_dir, f"{prefix}_{tag}.png")
        fig.savefig(path)
        plt.close(fig)
        paths.append(path)

    names = study.integrators
    e0 = study.initial_energy
    fig_a_title = f"(a) full scale (initial energy {e0:.3f})"
    # full scale: an axis as wide as the paper's Fig. 15(a) (7000-8500 around 7983), so that
    # only a change of the energy's own size would show
    draw(names, None, "a_full", fig_a_title, ylim=(0.875 * e0, 1.0625 * e0) if e0 > 0 else None)
    draw(names, window, "b_zoom", f"(b) t in [{window[0]:g}, {window[1]:g}]")
    best = study.highest_order()
    draw([best], window, "c_zoom", f"(c) {display_name(best)} alone, t in [{window[0]:g}, {window[1]:g}]")

    fig, axes = plt.subplots(1, 3, figsize=(11.0, 3.2), dpi=90)
    for name in names:
        c = study.histories[name]
        if "entropy" in c:
            axes[0].plot(c["time"], c["entropy"] - c["entropy"][0], lw=0.8, label=display_name(name))
        if not study.anchored:
            axes[1].plot(c["time"], np.linalg.norm(np.column_stack([c["px"], c["py"], c["pz"]]) -
                                                   np.array([c["px"][0], c["py"][0], c["pz"][0]]), axis=1), lw=0.8)
        axes[2].plot(c["time"], np.linalg.norm(np.column_stack([c["Lx"], c["Ly"], c["Lz"]]) -
                                               np.array([c["Lx"][0], c["Ly"][0], c["Lz"][0]]), axis=1), lw=0.8,
                     label=display_name(name))
    p_title = "linear momentum: not conserved (anchored)" if study.anchored else "|linear momentum − initial|"
    thermal = any("entropy" in study.histories[name] for name in names)
    s_title = "total entropy − initial" if thermal else "entropy: none (no thermal coupling)"
    for ax, title in zip(axes, (s_title, p_title, "|angular momentum − initial|")):
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("time")
        ax.grid(True, alpha=0.3)
    (axes[0] if thermal else axes[2]).legend(fontsize=7)
    fig.tight_layout()
    path = os.path.join(out_dir, f"{prefix}_invariants.png")
    fig.savefig(path)
    plt.close(fig)
    paths.append(path)
    return paths
