"""The step-limit policy: is a run's time step safely below its integrator's stability limit?

At the state a run starts from, :func:`check_step` estimates ``h_max = c / ω_max``
(:func:`thermonet.stability.stable_step`) and classifies ``h``:

- ``h ≤ SAFETY · h_max`` — ok;
- ``SAFETY · h_max < h ≤ REFUSE · h_max`` — a :class:`StepWarning` (the estimate is of the
  linearized net at one state; a run this close to the limit may still blow up later);
- ``h > REFUSE · h_max`` — refused with :class:`UnstableStepError` (a one-line message saying
  which h to use), unless ``allow_unstable=True`` (``thermonet run --allow-unstable-step``, scene
  key ``integrator.check_step = false``), which turns the refusal into a warning.

An unconditionally stable integrator (``unconditionally_stable``: EM2) has no limit: verdict
``"ok"`` without an estimate. Integrators without a known interval (a user's) are never refused
(verdict ``"unknown"``). A refusal or warning recommends a smaller h and, for steps above the
limit, EM2 (``blowup.UNLIMITED``), not another integrator with a limit of its own. The
policy looks at the initial state only: a net that stiffens on its way (a spring driven towards
collapse) is caught while running, by the simulation's blow-up detection.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

from .blowup import UNLIMITED
from .errors import InputError
from .stability import stable_step

#: warn above this fraction of h_max
SAFETY = 0.9
#: refuse above this multiple of h_max
REFUSE = 1.5


class UnstableStepError(InputError):
    """A time step far above the integrator's stability limit (refused before running)."""


class StepWarning(UserWarning):
    """A time step above the safety fraction of the stability limit."""


@dataclass
class StepCheck:
    """The verdict on one run's step.

    verdict: "ok", "warn", "refuse" (raised unless allowed), "allowed" (a refusal overridden),
    or "unknown" (no stability interval for this integrator). ratio: h / h_max.
    message: one line for the user ("" when ok).
    """

    h: float
    h_max: float
    ratio: float
    verdict: str
    message: str
    estimate: dict


def check_step(sim, *, allow_unstable: bool = False, warn: bool = True) -> StepCheck:
    """Apply the policy to ``sim`` (a :class:`~thermonet.simulation.Simulation`) at its current
    state. Raises :class:`UnstableStepError` for a refused step unless ``allow_unstable``; emits a
    :class:`StepWarning` for "warn" and "allowed" verdicts when ``warn``."""
    if getattr(sim.integrator, "unconditionally_stable", False):
        return StepCheck(float(sim.h), math.inf, 0.0, "ok", "",
                         {"integrator": sim.integrator.name, "h_max": math.inf, "interval": math.inf})
    est = stable_step(sim)
    h, h_max = float(sim.h), float(est["h_max"])
    if not math.isfinite(est["interval"]):
        return StepCheck(h, h_max, 0.0, "unknown", "", est)
    if not math.isfinite(est["omega_max"]):
        msg = (f"no stability limit at step {sim.step}: {est['method']} (a parameter or the state is out of "
               f"the range of model {sim.model.name!r}); pass --allow-unstable-step "
               f"(scene: integrator.check_step = false) to run anyway")
        if not allow_unstable:
            raise UnstableStepError(msg)
        if warn:
            warnings.warn(msg, StepWarning, stacklevel=2)
        return StepCheck(h, h_max, math.inf, "allowed", msg, est)
    ratio = h / h_max if h_max > 0 else math.inf
    where = (f"stability limit h_max ≈ {h_max:.4g} of {est['integrator']} at step {sim.step} "
             f"(ω_max ≈ {est['omega_max']:.4g}, h_max = {est['interval']:.4g}/ω_max)")
    safe = SAFETY * h_max
    if ratio <= SAFETY:
        return StepCheck(h, h_max, ratio, "ok", "", est)
    if ratio <= REFUSE:
        msg = (f"h = {h:.4g} is {ratio:.2f}× the {where}, above the safety fraction {SAFETY:g}; "
               f"the run may blow up: consider h ≤ {safe:.3g} (or the integrator {UNLIMITED}, which has no "
               f"stability limit)")
        verdict = "warn"
    else:
        msg = (f"h = {h:.4g} is {ratio:.3g}× the {where}: the run would blow up; use h ≤ {safe:.3g}, "
               f"or the integrator {UNLIMITED}, which has no stability limit (energy exact at any step; fast "
               f"modes lose accuracy, not stability), or pass --allow-unstable-step (scene: "
               f"integrator.check_step = false) to run anyway")
        if not allow_unstable:
            raise UnstableStepError(msg)
        verdict = "allowed"
    if warn:
        warnings.warn(msg, StepWarning, stacklevel=2)
    return StepCheck(h, h_max, ratio, verdict, msg, est)


#: how far t_end may be from a whole number of steps, relative to that number (rounding of t/h)
WHOLE_STEPS_TOLERANCE = 1e-9


def whole_steps(t_end: float, h: float, start: float = 0.0, what: str = "t_end") -> int:
    """The number of steps of size ``h`` from time ``start`` to ``t_end``, which must be a whole
    number (within :data:`WHOLE_STEPS_TOLERANCE`): the one rule of the API (``Simulation.run``),
    scenes (``integrator.t_end``) and the studies. Otherwise an :class:`InputError` says which
    t_end or step count would do."""
    n = (t_end - start) / h
    k = round(n)
    if abs(n - k) <= WHOLE_STEPS_TOLERANCE * max(1.0, abs(n)) and k >= 0:
        return int(k)
    if n < 0:
        raise InputError(f"{what} = {t_end:g} is before the current time t = {start:g}")
    lo, hi = math.floor(n), math.ceil(n)
    options = " or ".join(f"{start + k * h:.10g}" for k in (lo, hi) if k >= 1)
    raise InputError(f"{what} = {t_end:g} is not a whole number of steps of h = {h:g} from t = {start:g} "
                     f"({n:.6g} steps); give {what} = {options}, or a number of steps")
