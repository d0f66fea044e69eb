"""Long-run energy study: energy, entropy and momenta over a long run for chosen integrators,
at full scale and zoomed (the paper's Fig. 15 a–c: chain, h = 0.01, t = 100, zoom on t ∈ [42, 45]).
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass, field

import numpy as np

from ..integrators import get_integrator
from .runner import Runner
from .scenes import check_scene
from .tasks import check_steps, history_run


@dataclass
class EnergyStudy:
    """histories: integrator -> column name -> (k,) array (time, energy, entropy, px … Lz);
    window: (t0, t1) of the zoomed plots."""

    scene: str
    h: float
    t_end: float
    integrators: list[str]
    window: tuple[float, float]
    histories: dict = field(default_factory=dict)
    status: dict = field(default_factory=dict)
    anchored: bool = False

    @property
    def initial_energy(self) -> float:
        return float(self.histories[self.integrators[0]]["energy"][0])

    def highest_order(self) -> str:
        return max(self.integrators, key=lambda n: get_integrator(n).order)

    def statistics(self) -> dict[str, dict[str, float]]:
        """Per integrator: energy oscillation (max − min) over the run and over the window,
        the drift (mean over the last tenth − mean over the first tenth), and the largest change
        of the total entropy and of |linear| and |angular momentum|."""
        out = {}
        for name in self.integrators:
            c = self.histories[name]
            t, e = c["time"], c["energy"]
            win = (t >= self.window[0]) & (t <= self.window[1])
            tenth = max(1, len(e) // 10)
            P = np.column_stack([c["px"], c["py"], c["pz"]])
            L = np.column_stack([c["Lx"], c["Ly"], c["Lz"]])
            out[name] = {
                "energy_range": float(e.max() - e.min()),
                "energy_range_window": float(e[win].max() - e[win].min()) if win.any() else float("nan"),
                "energy_drift": float(e[-tenth:].mean() - e[:tenth].mean()),
                "entropy_change": float(np.max(np.abs(c["entropy"] - c["entropy"][0]))) if "entropy" in c else float("nan"),
                # with anchors the total linear momentum is not a conserved quantity
                "linear_momentum_change": float("nan") if self.anchored else float(np.max(np.linalg.norm(P - P[0], axis=1))),
                "angular_momentum_change": float(np.max(np.linalg.norm(L - L[0], axis=1))),
            }
        return out

    def summary(self) -> str:
        stats = self.statistics()
        lines = [f"energy study: {self.scene}, h = {self.h:g}, t = 0 … {self.t_end:g}, initial energy {self.initial_energy:.6f}",
                 f"  {'integrator':<10} {'range':>10} {'range in [%g, %g]' % self.window:>18} {'drift':>10} "
                 f"{'Δentropy':>10} {'Δ|P|':>10} {'Δ|L|':>10}"]
        for name, s in stats.items():
            entropy = f"{s['entropy_change']:>10.1e}" if np.isfinite(s["entropy_change"]) else f"{'—':>10}"  # (mechanical)
            lines.append(f"  {name:<10} {s['energy_range']:>10.3e} {s['energy_range_window']:>18.3e} {s['energy_drift']:>10.2e} "
                         f"{entropy} {s['linear_momentum_change']:>10.1e} {s['angular_momentum_change']:>10.1e}")
        for name, st in self.status.items():
            if st != "ok":
                lines.append(f"  {name}: {st}")
        return "\n".join(lines)

    def write(self, out_dir) -> list[str]:
        from .plots import energy_figures

        os.makedirs(out_dir, exist_ok=True)
        files = []
        for name in self.integrators:
            path = os.path.join(out_dir, f"history_{name.replace('/', '_')}.csv")
            cols = self.histories[name]
            with open(path, "w", newline="") as f:
                w = csv.writer(f)
                w.writerow(list(cols))
                w.writerows(zip(*(map(repr, v.tolist()) for v in cols.values())))
            files.append(path)
        path = os.path.join(out_dir, "energy_summary.txt")
        with open(path, "w") as f:
            f.write(self.summary() + "\n")
        return files + [path] + energy_figures(self, out_dir)


def energy_study(scene: str, integrators, h: float = 0.01, t_end: float = 100.0, every: int = 1,
                 window=None, runner: Runner | None = None) -> EnergyStudy:
    """One long run per integrator (in parallel on ``runner``), diagnostics every ``every`` steps.

    window: (t0, t1) for the zoomed plots; default the paper's [0.42, 0.45]·t_end.
    """
    check_scene(scene)
    check_steps(t_end, h)
    integrators = [get_integrator(n).name for n in integrators]
    window = tuple(window) if window else (0.42 * t_end, 0.45 * t_end)
    results = (runner or Runner(serial=True)).map(
        history_run, [dict(scene=scene, integrator=n, h=h, t_end=t_end, every=every) for n in integrators])
    study = EnergyStudy(scene, h, t_end, integrators, window)
    for name, res in zip(integrators, results):
        study.histories[name] = res["columns"]
        study.status[name] = res["status"]
        study.anchored = res["anchored"]
    return study
