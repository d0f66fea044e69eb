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
from ..stability import stability_interval, stable_step
from ..step_policy import SAFETY
from .reference import DEFAULT_CHECK, DEFAULT_RTOL, ReferenceSolution, assemble_reference, reference_tasks
from .runner import Runner
from .scenes import BUILTIN, check_scene, make_simulation, scene_effects, scene_time
from .slopes import asymptotic_slope
from .snapshot import QUANTITIES
from .tasks import check_steps, integrator_endpoint

#: errors below this multiple of the reference's agreement are not used for slopes
FLOOR_FACTOR = 100.0
#: errors at or above this fraction of a quantity's size are not used for slopes (as in slopes.py)
MAX_RELATIVE = 0.1
#: the paper's coarsest step, the default of the built-in scenes
PAPER_DT = 0.1


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
    #: what the scene does beyond Hamilton's equations (its reference is then a fine-step run)
    effects: list = field(default_factory=list)

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
        if "conduction" in self.effects:
            lines.append("  (conduction is never composed: every integrator is second order with it, whatever its "
                         "own order; docs/heat.md)")
        ok = [r for r in self.rows if r["status"] == "ok"]
        exact = [q for q in QUANTITIES if ok and all(r[q] == 0.0 for r in ok)]
        for q in exact:
            lines.append(f"  no {q} slopes: every run's {q} equals the reference's exactly"
                         + (" (a scene without thermal coupling keeps every spring at its reference temperature)"
                            if q == "temperature" else ""))
        for (name, q), reason in self.unfitted().items():
            if q not in exact:
                lines.append(f"  no {q} slope for {name}: {reason}")
        failed = [r for r in self.rows if r["status"] != "ok"]
        for r in failed:  # one line each, whatever the error's text
            lines.append(f"  {r['integrator']} h={r['h']:g}: {' '.join(str(r['status']).split())}")
        return "\n".join(lines)

    def unfitted(self) -> dict:
        """(integrator, quantity) -> why no slope could be fitted, for every slope that is nan."""
        out = {}
        for (name, q), fit in self.slopes.items():
            if math.isfinite(fit.slope):
                continue
            h, e = self.errors(name, q)
            out[(name, q)] = unfitted_reason(h, e, self.reference.floor(q, FLOOR_FACTOR), self.reference.scales[q])
        return out

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


def unfitted_reason(h, error, floor: float, scale: float, max_relative: float = MAX_RELATIVE) -> str:
    """Why the errors (n,) at steps h (n,) give no slope: what each point was dropped for (the
    criteria of :func:`thermonet.studies.slopes.asymptotic_slope`)."""
    error = np.asarray(error, dtype=np.float64)
    finite = np.isfinite(error)
    failed = int((~finite).sum())
    low = finite & ((error <= floor) | (error <= 0))
    below = int(low.sum())
    large = int((finite & ~low & (error >= max_relative * scale) & (scale > 0)).sum())  # each point once
    usable = len(error) - failed - below - large
    parts = [f"{usable} usable point{'s' if usable != 1 else ''} of {len(error)} (2 needed)"]
    if failed:
        parts.append(f"{failed} failed or non-finite run{'s' if failed != 1 else ''} (see below; the steps may be "
                     "above the stability limit: a smaller --dt)")
    if below:
        parts.append(f"{below} at or below the reference's floor {floor:.2g} (100× its agreement with the check "
                     "solution: a larger --dt, or a tighter check)")
    if large:
        parts.append(f"{large} with errors ≥ {max_relative:g} of the quantity's size {scale:.3g} (a smaller --dt)")
    return "; ".join(parts)


def default_time_step(scene: str, integrators, t_end: float) -> float:
    """The coarsest step of a study when none is given: the paper's 0.1 for the built-in scenes,
    else the scene's own h; at most ``SAFETY`` (0.9) × the smallest stability limit of the
    integrators at the initial state, and a whole fraction of ``t_end``."""
    h = PAPER_DT if scene in BUILTIN else scene_time(scene)[0]
    for name in integrators:
        sim = make_simulation(scene, name, h)
        if math.isfinite(stability_interval(sim.integrator)):
            h = min(h, SAFETY * stable_step(sim)["h_max"])
    return fraction_of(t_end, h)


#: the reference of a scene with effects beyond Hamilton's equations: this integrator at the
#: study's finest step divided by FINE_REFERENCE_DIVISOR (checked against twice that step)
FINE_REFERENCE = "co4"
FINE_REFERENCE_DIVISOR = 16


def default_check(scene: str, t_end: float, finest: float | None = None, effects=None) -> tuple[str, float]:
    """The check of the reference when none is given: CO6 at h = 5e-4, or at half its stability
    limit at the initial state where that is smaller, a whole fraction of ``t_end``.

    For a scene with effects beyond Hamilton's equations (``effects``; found when None) the
    reference itself: CO4 at ``finest`` (the study's finest step) / 16, or half its stability
    limit where that is smaller, a whole fraction of ``t_end`` by an even number of steps (its
    check runs at twice the step)."""
    if effects is None:
        effects = scene_effects(scene)
    if effects:
        name = FINE_REFERENCE
        h = (finest if finest is not None else DEFAULT_CHECK[1]) / FINE_REFERENCE_DIVISOR
        h_max = stable_step(make_simulation(scene, name, h))["h_max"]
        k = math.ceil(t_end / min(h, 0.5 * h_max) * (1 - 1e-12))
        return name, t_end / (k + k % 2)
    name, h = DEFAULT_CHECK
    h_max = stable_step(make_simulation(scene, name, h))["h_max"]
    return name, fraction_of(t_end, min(h, 0.5 * h_max))


def fraction_of(t_end: float, h: float) -> float:
    """The largest t_end / k (k a whole number) not above h."""
    return t_end / math.ceil(t_end / h * (1 - 1e-12))


def time_steps(dt: float, halvings: int) -> list[float]:
    """dt · 2⁻ⁱ, i = 0 … halvings."""
    return [dt / 2**i for i in range(int(halvings) + 1)]


def convergence_study(scene: str, integrators, dt: float = 0.1, halvings: int = 8, t_end: float = 1.0,
                      runner: Runner | None = None, rtol: float = DEFAULT_RTOL, check=DEFAULT_CHECK,
                      progress=None) -> ConvergenceStudy:
    """Run every (integrator, h) and the reference (with its check) on ``runner``; fit slopes.
    For a scene with effects beyond Hamilton's equations the reference is an integrator at a fine
    step (:func:`~thermonet.studies.reference.reference_tasks`; default :func:`default_check`)."""
    check_scene(scene)
    integrators = [get_integrator(name).name for name in integrators]
    hs = time_steps(dt, halvings)
    for h in hs:
        check_steps(t_end, h)
    effects = scene_effects(scene)
    if effects and check is DEFAULT_CHECK:
        check = default_check(scene, t_end, hs[-1], effects)
    ref, chk = reference_tasks(scene, t_end, rtol, check, effects)
    calls = [ref] + ([chk] if chk else [])
    calls += [(integrator_endpoint, dict(scene=scene, integrator=name, h=h, t_end=t_end))
              for name in integrators for h in hs]
    results = (runner or Runner(serial=True)).run(calls, progress=progress)
    n_ref = 2 if chk else 1
    reference = assemble_reference(results[0], results[1] if chk else None, t_end, rtol, check, effects)
    study = ConvergenceStudy(scene, t_end, integrators, hs, reference, effects=list(effects))
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
