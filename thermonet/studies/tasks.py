"""The runs a study is made of, as module-level functions of picklable arguments.

Each builds its own simulation from the scene name, so it can execute in this process or on a
Dask worker. A run that fails (a non-physical state at too large a step) is reported, not raised:
its snapshot is NaN and ``status`` says why.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from ..errors import InputError, ThermonetError
from .ode import solve_hamilton
from .scenes import make_simulation
from .snapshot import Snapshot


def settle_numba_threads() -> None:
    """Make Numba read ``NUMBA_NUM_THREADS`` now, before a run launches its threads.

    A Dask worker gets the variable (1: one core per run) only after its process started, and
    Numba was imported before that (by the main module the worker re-imports): without this, the
    first run launches Numba's threads at the import-time count, and the first kernel compiled
    after that (a cold cache) re-reads the variable and Numba refuses the change with a
    RuntimeError. Harmless where nothing changed (serial runs)."""
    from numba.core import config

    config.reload_config()


def _nan_snapshot(scene: str) -> Snapshot:
    sim = make_simulation(scene, "co2", 1.0)
    k = int((~np.asarray(sim.net.anchored, dtype=bool)).sum())
    return Snapshot(np.full((k, 3), np.nan), np.full((k, 3), np.nan), np.full(sim.net.n_springs, np.nan))


def check_steps(t_end: float, h: float) -> int:
    """Steps of size h to t_end; t_end must be a whole multiple of h (errors at t_end compare
    states at the same time)."""
    n = round(t_end / h)
    if n < 1 or abs(n * h - t_end) > 1e-9 * t_end:
        raise InputError(f"t_end = {t_end:g} is not a whole number of steps h = {h:g}")
    return int(n)


def integrator_endpoint(scene: str, integrator: str, h: float, t_end: float) -> dict:
    """Run ``scene`` with ``integrator`` at step h to t_end: {snapshot, steps, status}."""
    settle_numba_threads()
    steps = check_steps(t_end, h)
    sim = make_simulation(scene, integrator, h, threads=1)
    try:
        sim.run(steps=steps, diagnostics_every=steps)
        snap, status = Snapshot.of(sim), "ok"
        if not all(np.isfinite(a).all() for a in snap.to_dict().values()):
            snap, status = _nan_snapshot(scene), "non-finite state"
    except (ThermonetError, FloatingPointError) as exc:
        snap, status = _nan_snapshot(scene), f"failed: {exc}"
    return {"snapshot": snap, "steps": steps, "status": status}


def ode_endpoint(scene: str, t_end: float, method: str = "DOP853", rtol: float = 1e-13, atol: float = 1e-13) -> dict:
    """Hamilton's equations of ``scene`` by ``solve_ivp``: {snapshot, nfev, wall_time, status}."""
    settle_numba_threads()
    res = solve_hamilton(make_simulation(scene, "co2", 1.0), t_end, method, rtol, atol)
    return {"snapshot": res.snapshot, "nfev": res.nfev, "wall_time": res.wall_time, "status": "ok"}


def timed_integrator_run(scene: str, integrator: str, h: float, t_end: float, repeats: int = 5) -> dict:
    """Wall-clock time of ``sim.run`` to t_end: one untimed warm-up run (JIT compilation, caches),
    then ``repeats`` timed runs from the initial state, each on a fresh simulation.

    Returns {snapshot, steps, status, times: (repeats,) seconds, time: their median}.
    Only ``run`` is timed (not building the simulation), with diagnostics at the ends only.
    """
    settle_numba_threads()
    steps = check_steps(t_end, h)
    times = []
    out = None
    for r in range(repeats + 1):
        sim = make_simulation(scene, integrator, h, threads=1)
        start = time.perf_counter()
        try:
            sim.run(steps=steps, diagnostics_every=steps)
        except (ThermonetError, FloatingPointError) as exc:
            return {"snapshot": _nan_snapshot(scene), "steps": steps, "status": f"failed: {exc}",
                    "times": [float("nan")], "time": float("nan")}
        elapsed = time.perf_counter() - start
        if r > 0:
            times.append(elapsed)
        out = sim
    snap = Snapshot.of(out)
    ok = all(np.isfinite(a).all() for a in snap.to_dict().values())
    return {"snapshot": snap if ok else _nan_snapshot(scene), "steps": steps,
            "status": "ok" if ok else "non-finite state", "times": times, "time": statistics.median(times)}


def timed_ode_run(scene: str, t_end: float, method: str, rtol: float, atol: float | None = None,
                  repeats: int = 3, compiled: bool = False) -> dict:
    """Wall-clock time of ``solve_ivp`` on Hamilton's equations: a short warm-up solve, then
    ``repeats`` timed solves; {snapshot, nfev, status, times, time (median)}. ``compiled``: with
    the Numba-compiled right-hand side (built-in models), else the NumPy one."""
    settle_numba_threads()
    atol = rtol if atol is None else atol
    solve_hamilton(make_simulation(scene, "co2", 1.0), min(t_end, 1e-2), method, rtol, atol, compiled=compiled)
    times, res = [], None
    for _ in range(repeats):
        try:
            res = solve_hamilton(make_simulation(scene, "co2", 1.0), t_end, method, rtol, atol, compiled=compiled)
        except ThermonetError as exc:
            return {"snapshot": _nan_snapshot(scene), "nfev": 0, "status": f"failed: {exc}",
                    "times": [float("nan")], "time": float("nan")}
        times.append(res.wall_time)
    return {"snapshot": res.snapshot, "nfev": res.nfev, "status": "ok", "times": times,
            "time": statistics.median(times)}


def history_run(scene: str, integrator: str, h: float, t_end: float, every: int = 1) -> dict:
    """A long run recording diagnostics every ``every`` steps: {columns: name -> (k,) array,
    status, wall_time}."""
    settle_numba_threads()
    steps = check_steps(t_end, h)
    sim = make_simulation(scene, integrator, h)
    status = "ok"
    try:
        sim.run(steps=steps, diagnostics_every=every)
    except (ThermonetError, FloatingPointError) as exc:
        status = f"failed: {exc}"
    d = sim.diagnostics
    names = [c for c in ("time", "energy", "entropy", "px", "py", "pz", "Lx", "Ly", "Lz") if c in d.columns]
    return {"columns": {c: d.column(c) for c in names}, "status": status, "wall_time": sim.wall_time,
            "anchored": bool(np.asarray(sim.net.anchored).any())}
