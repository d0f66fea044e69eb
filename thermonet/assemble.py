"""Assembling a run's stepper, in one place: the integrator (with the heat rows in an explicit
splitting's schedule), its stepper, and the wrappers for what an implicit stepper does not do
itself, each added here and nowhere else:

- conduction around each implicit step (:class:`~thermonet.heat.stepper.ConductionAround`:
  ``K(h/2) ∘ A(h) ∘ K(h/2)``, docs/theory.md §5.4);
- loads around each implicit step (:class:`~thermonet.loads.implicit.ImplicitLoads`, by Strang
  splitting, docs/theory.md §7.3);

then the stepper's loads are pointed at the Simulation's clock (``time_origin``). A new effect
that wraps steppers is added to :func:`assemble`.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

from .heat.stepper import ConductionAround, integrator_with_heat
from .loads.implicit import ImplicitLoads


class Assembly(NamedTuple):
    """What :func:`assemble` makes: the integrator the run reports (an explicit splitting with
    its heat rows) and the stepper that advances the state."""

    integrator: object
    stepper: object


def assemble(integrator, system, *, parallel: bool, backend: str, options: dict,
             time_origin: Callable[[], tuple]) -> Assembly:
    """The integrator and stepper of a run of ``system`` (heat and loads as ``system`` holds
    them). options: the stepper's options (solver settings; ``backend`` is added for a device);
    time_origin: the Simulation's clock, ``() -> (step, time)`` where the run's time starts."""
    heat, loads = system.heat, system.loads
    if heat is not None:
        integrator = integrator_with_heat(integrator, heat, backend)
    options = dict(options)
    if backend != "cpu":
        options["backend"] = backend
    stepper = integrator.make_stepper(system, parallel=parallel, **options)
    if not integrator.explicit:
        if heat is not None:
            stepper = ConductionAround(stepper, system, parallel)
        if loads is not None:
            stepper = ImplicitLoads(stepper, system, loads)
    if loads is not None:
        clock = getattr(stepper, "loads", None)  # the stepper's loads read their time from the run's clock
        if clock is not None:
            clock.time_origin = time_origin
    return Assembly(integrator, stepper)
