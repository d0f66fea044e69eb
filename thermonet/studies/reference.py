"""The reference solution every study measures errors against, and how far it can be trusted.

Choice: SciPy's DOP853 (8th-order Dormand–Prince) on Hamilton's equations (Mata & Lew 2011, (18)) at
rtol = atol = 1e-13, with the NumPy right-hand side of :mod:`thermonet.reference` (independent
of the engine's kernels). It is *checked* against a second, unrelated solution: the explicit
6th-order composition CO6 at a small step (default h = 5e-4), or HO4 (the paper's own choice,
h = 1e-4) when asked. The distance between the two, per quantity, is reported as the reference's
``agreement`` and sets the floor under which errors are not used for slopes.

A scene whose heat flows (conduction, thermal waves, baths, sources) or that carries loads is
not Hamilton's equations of its net: its reference is an integrator of thermonet at a fine step
(which includes every effect), checked against the same integrator at twice that step.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import InputError, SimulationError
from .runner import Runner
from .scenes import scene_effects
from .snapshot import QUANTITIES, Snapshot
from .tasks import integrator_endpoint, ode_endpoint

DEFAULT_RTOL = 1e-13
DEFAULT_CHECK = ("co6", 5e-4)


@dataclass
class ReferenceSolution:
    """snapshot: the reference state at t_end; check: the checking solution's state;
    agreement: quantity -> |reference − check| (the paper's norm); scales: quantity -> size;
    description: one line saying what was computed."""

    snapshot: Snapshot
    check: Snapshot | None
    agreement: dict[str, float]
    scales: dict[str, float]
    description: str
    t_end: float

    def floor(self, quantity: str, factor: float = 100.0) -> float:
        """Errors below ``factor`` × the reference's agreement are the reference's, not the run's."""
        return factor * self.agreement.get(quantity, 0.0)


def reference_tasks(scene: str, t_end: float, rtol: float = DEFAULT_RTOL, check=DEFAULT_CHECK, effects=()):
    """The (function, kwargs) of the reference run and of its check (None if check is None).

    effects: what the scene does beyond Hamilton's equations (:func:`~thermonet.studies.scenes.
    effects_beyond_hamilton`). With any, DOP853 would solve another problem: the reference is
    then the run of ``check`` = (integrator, h) itself, and its check the same integrator at 2h
    (their distance bounds the reference's error for any converging integrator)."""
    if effects:
        if check is None:
            raise InputError(f"the scene has {', '.join(effects)}, which Hamilton's equations leave out: the "
                             "reference is an integrator at a fine step (--check INTEGRATOR:H), not 'none'")
        name, h = check
        ref = (integrator_endpoint, dict(scene=scene, integrator=name, h=h, t_end=t_end))
        chk = (integrator_endpoint, dict(scene=scene, integrator=name, h=2 * h, t_end=t_end))
        return ref, chk
    ref = (ode_endpoint, dict(scene=scene, t_end=t_end, method="DOP853", rtol=rtol, atol=rtol))
    chk = None if check is None else (integrator_endpoint, dict(scene=scene, integrator=check[0], h=check[1], t_end=t_end))
    return ref, chk


def assemble_reference(ref_result: dict, check_result: dict | None, t_end: float, rtol: float = DEFAULT_RTOL,
                       check=DEFAULT_CHECK, effects=()) -> ReferenceSolution:
    snap = ref_result["snapshot"]
    if effects:
        name, h = check
        if ref_result["status"] != "ok":
            raise SimulationError(f"the reference run {name} h={h:g} failed: {' '.join(str(ref_result['status']).split())}")
        desc = (f"{name} h={h:g} ({', '.join(effects)}: not in Hamilton's equations, so no DOP853), "
                f"checked against {name} h={2 * h:g}")
        check = (name, 2 * h)
    else:
        desc = f"DOP853 rtol=atol={rtol:g} ({ref_result['nfev']} RHS evaluations)"
    if check_result is None:
        return ReferenceSolution(snap, None, {q: 0.0 for q in QUANTITIES}, snap.scales(), desc, t_end)
    agreement = check_result["snapshot"].errors(snap)
    if not effects:
        desc += f", checked against {check[0]} h={check[1]:g}"
    desc += ": " + ", ".join(f"{q} {agreement[q]:.1e}" for q in QUANTITIES)
    return ReferenceSolution(snap, check_result["snapshot"], agreement, snap.scales(), desc, t_end)


def reference_solution(scene: str, t_end: float, rtol: float = DEFAULT_RTOL, check=DEFAULT_CHECK,
                       runner: Runner | None = None) -> ReferenceSolution:
    """Compute the reference (and its check, in parallel on ``runner``); for a scene with effects
    beyond Hamilton's equations, see :func:`reference_tasks`."""
    runner = runner or Runner(serial=True)
    effects = scene_effects(scene)
    ref, chk = reference_tasks(scene, t_end, rtol, check, effects)
    results = runner.run([ref] + ([chk] if chk else []))
    return assemble_reference(results[0], results[1] if chk else None, t_end, rtol, check, effects)
