"""Convergence study: the error at t_end of every (integrator, h) against the reference, and
the fitted order of each integrator in positions, momenta and temperatures (the paper's
Figs. 6–8).

Time steps are ``dt · 2⁻ⁱ`` for i = 0 … halvings (the paper: dt = 0.1, 8 halvings, t_end = 1).
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, field

import numpy as np

from ..integrators import get_integrator
from .reference import DEFAULT_CHECK, DEFAULT_RTOL, ReferenceSolution, assemble_reference, reference_tasks
from .runner import Runner
from .scenes import check_scene
from .slopes import asymptotic_slope
from .snapshot import QUANTITIES
from .tasks import check_steps, integrator_endpoint

#: errors below this multiple of the reference's agreement are not used for slopes
FLOOR_FACTOR = 100.0


@dataclass
class ConvergenceStudy:
    """rows: one dict per (integrator, h) with keys integrator, h, steps, status and one error
    per quantity; slopes: (integrator, quantity) -> :class:`SlopeFit`."""

    scene: str
    t_end: float
    integrators: list[str]
    steps: list[float]
    reference: ReferenceSolution
    rows: list[dict] = field(default_factory=list)
    slopes: dict = field(default_factory=dict)

    def errors(self, integrator: str, quantity: str) -> tuple[np.ndarray, np.ndarray]:
        """(h, error) arrays of one integrator, coarse to fine."""
        rows = [r for r in self.rows if r["integrator"] == integrator]
        return np.array([r["h"] for r in rows]), np.array([r[quantity] for r in rows])

    def error_table(self) -> list[tuple]:
        """The errors alone, as comparable tuples (integrator, h, e_x, e_p, e_θ)."""
        return [(r["integrator"], r["h"]) + tuple(r[q] for q in QUANTITIES) for r in self.rows]

    def to_csv(self, path) -> None:
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["integrator", "h", "steps"] + [f"error_{q}" for q in QUANTITIES] + ["status"])
            for r in self.rows:
                w.writerow([r["integrator"], repr(r["h"]), r["steps"]] + [repr(r[q]) for q in QUANTITIES] + [r["status"]])

    def slopes_to_csv(self, path) -> None:
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["integrator", "order", "quantity", "slope", "h_min", "h_max", "points"])
            for (name, q), fit in self.slopes.items():
                w.writerow([name, get_integrator(name).order, q, f"{fit.slope:.4f}", repr(fit.h_min), repr(fit.h_max), fit.n_points])

    def summary(self) -> str:
        lines = [f"convergence study: {self.scene}, errors at t = {self.t_end:g}",
                 f"reference: {self.reference.description}",
                 "slopes fitted over the asymptotic range (thermonet.studies.slopes):",
                 f"  {'integrator':<10} {'order':>5}  " + "  ".join(f"{q:>11}" for q in QUANTITIES)]
        for name in self.integrators:
            fits = [self.slopes[(name, q)] for q in QUANTITIES]
            lines.append(f"  {name:<10} {get_integrator(name).order:>5}  " + "  ".join(
                f"{f.slope:>6.2f} ({f.n_points})" if math.isfinite(f.slope) else f"{'—':>11}" for f in fits))
        failed = [r for r in self.rows if r["status"] != "ok"]
        for r in failed:
            lines.append(f"  {r['integrator']} h={r['h']:g}: {r['status']}")
        return "\n".join(lines)

    def plot(self, out_dir, prefix: str = "convergence") -> list[str]:
        """One log-log PNG per quantity, slopes annotated; returns the paths."""
        from .plots import convergence_figure

        os.makedirs(out_dir, exist_ok=True)
        paths = []
        for q in QUANTITIES:
            path = os.path.join(out_dir, f"{prefix}_{q}.png")
            convergence_figure(self, q, path)
            paths.append(path)
        return paths

    def write(self, out_dir) -> list[str]:
        """CSV tables, PNGs and summary.txt into ``out_dir``; returns the files written."""
        os.makedirs(out_dir, exist_ok=True)
        files = [os.path.join(out_dir, "convergence.csv"), os.path.join(out_dir, "slopes.csv"),
                 os.path.join(out_dir, "summary.txt")]
        self.to_csv(files[0])
        self.slopes_to_csv(files[1])
        with open(files[2], "w") as f:
            f.write(self.summary() + "\n")
        return files + self.plot(out_dir)


def time_steps(dt: float, halvings: int) -> list[float]:
    """dt · 2⁻ⁱ, i = 0 … halvings."""
    return [dt / 2**i for i in range(int(halvings) + 1)]


def convergence_study(scene: str, integrators, dt: float = 0.1, halvings: int = 8, t_end: float = 1.0,
                      runner: Runner | None = None, rtol: float = DEFAULT_RTOL, check=DEFAULT_CHECK,
                      progress=None) -> ConvergenceStudy:
    """Run every (integrator, h) and the reference (with its check) on ``runner``; fit slopes."""
    check_scene(scene)
    integrators = [get_integrator(name).name for name in integrators]
    hs = time_steps(dt, halvings)
    for h in hs:
        check_steps(t_end, h)
    ref, chk = reference_tasks(scene, t_end, rtol, check)
    calls = [ref] + ([chk] if chk else [])
    calls += [(integrator_endpoint, dict(scene=scene, integrator=name, h=h, t_end=t_end))
              for name in integrators for h in hs]
    results = (runner or Runner(serial=True)).run(calls, progress=progress)
    n_ref = 2 if chk else 1
    reference = assemble_reference(results[0], results[1] if chk else None, t_end, rtol, check)
    study = ConvergenceStudy(scene, t_end, integrators, hs, reference)
    runs = iter(results[n_ref:])
    for name in integrators:
        for h in hs:
            res = next(runs)
            errors = res["snapshot"].errors(reference.snapshot)
            study.rows.append({"integrator": name, "h": h, "steps": res["steps"], "status": res["status"], **errors})
    for name in integrators:
        for q in QUANTITIES:
            h_arr, e_arr = study.errors(name, q)
            study.slopes[(name, q)] = asymptotic_slope(
                h_arr, e_arr, floor=reference.floor(q, FLOOR_FACTOR), scale=reference.scales[q])
    return study
