"""Work-precision study: the error at t_end against wall-clock time for every (integrator, h),
with SciPy's ``solve_ivp`` (DOP853 and RK45 over a range of tolerances, on Hamilton's equations)
as the curve a Python user would otherwise pick (the paper's Fig. 9). SciPy drives a
Numba-compiled right-hand side (:mod:`thermonet.studies.compiled_rhs`, for the built-in models),
what a performance-aware user would write; ``scipy_rhs="numpy"`` times the NumPy one instead
and ``"both"`` both (the NumPy runs labelled ``scipy-<method>-numpy``). The reference solution
always uses the NumPy right-hand side (independent of the compiled one and of the engine).

How the timings are kept honest:

- each run is timed on its own: one untimed warm-up run first (Numba dispatch and compilation,
  caches), then ``repeats`` timed runs from the initial state; the **median** is reported (and the
  min and max, in the CSV). Only the time stepping is timed, with diagnostics at the ends only.
- on a Dask cluster every worker is a single-threaded process (one per core; Numba and BLAS
  threads pinned to 1), so no two runs share a core; with ``one_at_a_time`` the runs are
  submitted one after another and never overlap at all (use it on a machine shared with other
  jobs, or when the net is large enough to compete for memory bandwidth).
- medians, because a shared machine adds occasional long outliers; the spread is in the CSV.
The errors do not depend on any of this: they are the same serially and on Dask.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..integrators import get_integrator
from .convergence import default_check, time_steps
from .reference import DEFAULT_CHECK, DEFAULT_RTOL, ReferenceSolution, assemble_reference, reference_tasks
from .runner import Runner
from .scenes import check_scene, scene_effects
from .snapshot import QUANTITIES
from .tasks import check_steps, timed_integrator_run, timed_ode_run

DEFAULT_SCIPY = {"DOP853": [10.0**-k for k in range(3, 13)], "RK45": [10.0**-k for k in range(3, 10)]}


@dataclass
class CostStudy:
    """rows: one dict per run with keys solver (integrator name or "scipy-<method>"), h (nan for
    SciPy), rtol (nan for thermonet), work (steps or RHS evaluations), time (median seconds),
    time_min, time_max, repeats, status and one error per quantity."""

    scene: str
    t_end: float
    reference: ReferenceSolution
    rows: list[dict] = field(default_factory=list)
    repeats: int = 5
    runner: str = ""
    scipy_rhs: str = "compiled"
    #: what the scene does beyond Hamilton's equations (then no SciPy baseline)
    effects: list = field(default_factory=list)

    def curves(self) -> list[tuple[str, list[dict]]]:
        """(label, rows) per integrator or SciPy method, from the coarsest step or loosest
        tolerance to the finest."""
        labels: list[str] = []
        for r in self.rows:
            if r["solver"] not in labels:
                labels.append(r["solver"])
        def coarse_first(r):
            return -(r["rtol"] if r["solver"].startswith("scipy") else r["h"])

        return [(label, sorted((r for r in self.rows if r["solver"] == label), key=coarse_first)) for label in labels]

    def to_csv(self, path) -> None:
        cols = ["solver", "h", "rtol", "work", "time_median_s", "time_min_s", "time_max_s", "repeats"]
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(cols + [f"error_{q}" for q in QUANTITIES] + ["status"])
            for r in self.rows:
                w.writerow([r["solver"], repr(r["h"]), repr(r["rtol"]), r["work"], repr(r["time"]),
                            repr(r["time_min"]), repr(r["time_max"]), r["repeats"]]
                           + [repr(r[q]) for q in QUANTITIES] + [r["status"]])

    def cheapest(self, accuracy: float, quantity: str = "position", scipy: bool | None = None) -> dict | None:
        """The run with the smallest median time whose error ≤ accuracy (None if none);
        ``scipy``: True/False to restrict to SciPy's or thermonet's runs."""
        ok = [r for r in self.rows if math.isfinite(r["time"]) and r[quantity] <= accuracy
              and (scipy is None or r["solver"].startswith("scipy") == scipy)]
        return min(ok, key=lambda r: r["time"]) if ok else None

    def accuracies(self, quantity: str = "position") -> list[float]:
        """Decades from the largest to the smallest error reached (above the reference floor)."""
        e = np.array([r[quantity] for r in self.rows], dtype=float)
        e = e[np.isfinite(e) & (e > self.reference.floor(quantity))]
        if e.size == 0:
            return []
        hi, lo = math.floor(math.log10(e.max())), math.ceil(math.log10(e.min()))
        return [10.0**k for k in range(min(hi, 0), lo - 1, -1)]

    def summary(self, quantity: str = "position", accuracies=None) -> str:
        lines = [f"cost study: {self.scene}, error in {quantity} at t = {self.t_end:g} against wall-clock time",
                 f"reference: {self.reference.description}",
                 f"timings: median of {self.repeats} repeats after a warm-up run, {self.runner}",
                 ("no SciPy baseline: it solves Hamilton's equations, which leave out the scene's "
                  + ", ".join(self.effects)) if self.effects else
                 "SciPy's right-hand side: " + {"compiled": "Numba-compiled", "numpy": "NumPy (labels -numpy)",
                                                "both": "Numba-compiled, and NumPy (labels -numpy)"}[self.scipy_rhs]]
        for acc in accuracies or self.accuracies(quantity):
            best = self.cheapest(acc, quantity)
            if best is None:
                lines.append(f"for accuracy {acc:.0e} no run is accurate enough")
                continue
            sp = self.cheapest(acc, quantity, scipy=True)
            tn = self.cheapest(acc, quantity, scipy=False)
            line = f"for accuracy {acc:.0e} the cheapest is {_describe(best)}"
            if best is tn:
                line += (f"; SciPy's cheapest, {_describe(sp)}, {_slower(sp['time'] / best['time'])}"
                         if sp is not None else "; no SciPy run reached it" if not self.effects else "")
            else:
                line += f"; thermonet's cheapest is {_describe(tn)}" if tn is not None else "; no thermonet run reached it"
            lines.append(line)
        for r in self.rows:
            if r["status"] != "ok":
                lines.append(f"  {r['solver']} h={r['h']:g}: {r['status']}")
        return "\n".join(lines)

    def write(self, out_dir, quantity: str = "position", accuracies=None) -> list[str]:
        from .plots import cost_figure

        os.makedirs(out_dir, exist_ok=True)
        files = [os.path.join(out_dir, n) for n in ("cost.csv", "cost_summary.txt", f"cost_{quantity}.png")]
        self.to_csv(files[0])
        with open(files[1], "w") as f:
            f.write(self.summary(quantity, accuracies) + "\n")
        cost_figure(self, files[2], quantity)
        return files


def _slower(ratio: float) -> str:
    """``is 3.2 times slower``, or ``takes about as long`` within 5 %."""
    if ratio < 1.05:
        return "takes about as long"
    return f"is {ratio:.2g} times slower"


def _describe(r: dict) -> str:
    t = r["time"]
    when = f"{t * 1e3:.3g} ms" if t < 1 else f"{t:.3g} s"
    if r["solver"].startswith("scipy"):
        return f"{r['solver']} at rtol={r['rtol']:.0e} ({when})"
    return f"{r['solver'].upper()} at h={r['h']:g} ({when})"


def cost_study(scene: str, integrators, dt: float = 0.1, halvings: int = 8, t_end: float = 1.0,
               repeats: int = 5, scipy=None, runner: Runner | None = None, one_at_a_time: bool = False,
               rtol: float = DEFAULT_RTOL, check=DEFAULT_CHECK, progress=None,
               scipy_rhs: str = "compiled") -> CostStudy:
    """Time every (integrator, h = dt·2⁻ⁱ) and every SciPy (method, tolerance) run to t_end.

    scipy: method -> list of tolerances (rtol = atol); default :data:`DEFAULT_SCIPY`; {} for none
    (and none for a scene with effects beyond Hamilton's equations, whose reference is then an
    integrator at a fine step: :func:`~thermonet.studies.reference.reference_tasks`).
    scipy_rhs: "compiled" (Numba right-hand side, labels ``scipy-<method>``), "numpy" (labels
    ``scipy-<method>-numpy``) or "both".
    """
    if scipy_rhs not in ("compiled", "numpy", "both"):
        raise InputError(f"scipy_rhs must be 'compiled', 'numpy' or 'both', got {scipy_rhs!r}")
    variants = {"compiled": [(True, "")], "numpy": [(False, "-numpy")],
                "both": [(True, ""), (False, "-numpy")]}[scipy_rhs]
    check_scene(scene)
    runner = runner or Runner(serial=True)
    integrators = [get_integrator(name).name for name in integrators]
    scipy = DEFAULT_SCIPY if scipy is None else scipy
    hs = time_steps(dt, halvings)
    for h in hs:
        check_steps(t_end, h)
    effects = scene_effects(scene)
    if effects:  # SciPy's baselines solve Hamilton's equations, which leave these out: no baseline
        scipy = {}
        if check is DEFAULT_CHECK:
            check = default_check(scene, t_end, hs[-1], effects)
    ref, chk = reference_tasks(scene, t_end, rtol, check, effects)
    ref_results = runner.run([ref] + ([chk] if chk else []))
    reference = assemble_reference(ref_results[0], ref_results[1] if chk else None, t_end, rtol, check, effects)
    timed = [(timed_integrator_run, dict(scene=scene, integrator=n, h=h, t_end=t_end, repeats=repeats))
             for n in integrators for h in hs]
    labels = [(n, h, float("nan")) for n in integrators for h in hs]
    for method, tolerances in scipy.items():
        for compiled, tag in variants:
            timed += [(timed_ode_run, dict(scene=scene, t_end=t_end, method=method, rtol=tol, repeats=repeats,
                                           compiled=compiled)) for tol in tolerances]
            labels += [(f"scipy-{method}{tag}", float("nan"), tol) for tol in tolerances]
    results = runner.run(timed, one_at_a_time=one_at_a_time, progress=progress)
    study = CostStudy(scene, t_end, reference, repeats=repeats,
                      runner=runner.description + (", one run at a time" if one_at_a_time else ""),
                      scipy_rhs=scipy_rhs, effects=list(effects))
    for (solver, h, tol), res in zip(labels, results):
        times = np.asarray(res["times"], dtype=float)
        study.rows.append({
            "solver": solver, "h": h, "rtol": tol, "work": res.get("steps", res.get("nfev")),
            "time": res["time"], "time_min": float(np.min(times)), "time_max": float(np.max(times)),
            "repeats": len(times), "status": res["status"], **res["snapshot"].errors(reference.snapshot)})
    return study
