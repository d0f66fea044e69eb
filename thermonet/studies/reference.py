"""The reference solution every study measures errors against, and how far it can be trusted.

Choice: SciPy's DOP853 (8th-order Dormand–Prince) on Hamilton's equations (Mata & Lew 2011, (18)) at
rtol = atol = 1e-13, with the NumPy right-hand side of :mod:`thermonet.reference` (independent
of the engine's kernels). It is *checked* against a second, unrelated solution: the explicit
6th-order composition CO6 at a small step (default h = 5e-4), or HO4 (the paper's own choice,
h = 1e-4) when asked. The distance between the two, per quantity, is reported as the reference's
``agreement`` and sets the floor under which errors are not used for slopes.
"""

from __future__ import annotations

from dataclasses import dataclass

from .runner import Runner
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


def reference_tasks(scene: str, t_end: float, rtol: float = DEFAULT_RTOL, check=DEFAULT_CHECK):
    """The (function, kwargs) of the reference run and of its check (None if check is None)."""
    ref = (ode_endpoint, dict(scene=scene, t_end=t_end, method="DOP853", rtol=rtol, atol=rtol))
    chk = None if check is None else (integrator_endpoint, dict(scene=scene, integrator=check[0], h=check[1], t_end=t_end))
    return ref, chk


def assemble_reference(ref_result: dict, check_result: dict | None, t_end: float, rtol: float = DEFAULT_RTOL,
                       check=DEFAULT_CHECK) -> ReferenceSolution:
    snap = ref_result["snapshot"]
    desc = f"DOP853 rtol=atol={rtol:g} ({ref_result['nfev']} RHS evaluations)"
    if check_result is None:
        return ReferenceSolution(snap, None, {q: 0.0 for q in QUANTITIES}, snap.scales(), desc, t_end)
    agreement = check_result["snapshot"].errors(snap)
    desc += f", checked against {check[0]} h={check[1]:g}: " + ", ".join(f"{q} {agreement[q]:.1e}" for q in QUANTITIES)
    return ReferenceSolution(snap, check_result["snapshot"], agreement, snap.scales(), desc, t_end)


def reference_solution(scene: str, t_end: float, rtol: float = DEFAULT_RTOL, check=DEFAULT_CHECK,
                       runner: Runner | None = None) -> ReferenceSolution:
    """Compute the reference (and its check, in parallel on ``runner``)."""
    runner = runner or Runner(serial=True)
    ref, chk = reference_tasks(scene, t_end, rtol, check)
    results = runner.run([ref] + ([chk] if chk else []))
    return assemble_reference(results[0], results[1] if chk else None, t_end, rtol, check)
