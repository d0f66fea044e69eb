"""The integrator interface and the name registry.

An :class:`Integrator` is a description (name, order, explicit or not); ``make_stepper(system)``
binds it to a :class:`~thermonet.system.System` and returns a :class:`Stepper` whose
``advance(state, n_steps, h)`` moves a :class:`~thermonet.system.State` forward in place.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

import numpy as np

from ..errors import SimulationError, UnknownNameError
from ..state import copy_extra


class Stepper(ABC):
    """An integrator bound to one system: what the :class:`~thermonet.simulation.Simulation`
    calls. Only :meth:`advance` is required; the rest have defaults for a stepper whose state is
    the host :class:`~thermonet.system.State` and that measures nothing itself."""

    #: whether ``advance(..., measure=True)`` can reduce the end state's diagnostics sums on the
    #: way (then :meth:`closing_sums` returns them)
    measures: bool = False

    @abstractmethod
    def advance(self, state, n_steps: int, h: float, measure: bool = False) -> dict[str, Any] | None:
        """Advance ``state`` in place by ``n_steps`` steps of size ``h``.

        Returns per-chunk statistics to record with the diagnostics (e.g. Newton iterations), or
        None. On failure raises :class:`StepFailure` with ``steps_done`` set, leaving ``state`` at
        the last completed step (or, with ``details["rewind"]``, asking the caller to restore and
        replay that many steps).
        """

    def closing_sums(self, state) -> dict | None:
        """The sums of a diagnostics row of ``state`` that the last ``advance(..., measure=True)``
        reduced at its end, if ``state`` is still that one (keys as
        :func:`thermonet.diagnostics.diagnostics_row`'s arguments); else None."""
        return None

    def diagnostics_row(self, system, state) -> dict | None:
        """A whole diagnostics row measured by the stepper (a state resident on a device is
        reduced there), or None: the caller measures the host state."""
        return None

    def sync(self, state) -> None:
        """Bring ``state``'s host arrays up to date (a device-resident stepper copies back)."""

    def backup_state(self, state, into=None, entropy: bool = True):
        """A copy of ``state`` to restore after a blow-up (:meth:`restore_state`), into ``into``
        (an earlier copy of this stepper's) where given; η copied only with ``entropy`` (heat
        flow changes it). The caller sets the copy's ``step`` and ``time``."""
        if into is None:
            return state.copy()
        _copy_state(state, into, entropy)
        return into

    def restore_state(self, backup, state, entropy: bool = True) -> None:
        """Put a :meth:`backup_state` copy back into ``state`` (in place)."""
        _copy_state(backup, state, entropy)

    def summary(self) -> dict | None:
        """Totals over the run to report (e.g. Newton iterations), or None."""
        return None


class Integrator(ABC):
    """A time integrator: name, order of accuracy, and how to build its stepper."""

    name: str
    order: int
    explicit: bool
    description: str = ""

    @abstractmethod
    def make_stepper(self, system, **options) -> Stepper: ...

    def __repr__(self) -> str:
        return f"<integrator {self.name}: order {self.order}, {'explicit' if self.explicit else 'implicit'}>"


class StepFailure(SimulationError):
    """A step could not be completed; ``steps_done`` steps of the chunk were (the state is there)."""

    def __init__(self, message: str, steps_done: int = 0, details: dict | None = None):
        super().__init__(message)
        self.steps_done = steps_done
        self.details = details or {}


_REGISTRY: dict[str, Any] = {}


def register_integrator(integrator_or_factory, name: str | None = None):
    """Register an :class:`Integrator` (or a factory ``f(**options) -> Integrator``) by name."""
    key = (name or integrator_or_factory.name).lower()
    _REGISTRY[key] = integrator_or_factory
    return integrator_or_factory


def get_integrator(name_or_integrator, **options) -> Integrator:
    """The integrator of that name (case-insensitive; options go to factories such as GTR-α)."""
    if isinstance(name_or_integrator, Integrator):
        return name_or_integrator
    key = str(name_or_integrator).lower().replace("_", "-")
    if key not in _REGISTRY:
        raise UnknownNameError("integrator", str(name_or_integrator), _REGISTRY)
    entry = _REGISTRY[key]
    if isinstance(entry, Integrator):
        if options:
            raise UnknownNameError("option for integrator " + key, ", ".join(options), ["(none)"])
        return entry
    return entry(**options)


def available_integrators() -> list[str]:
    return sorted(_REGISTRY)


def explicit_integrators() -> list[str]:
    """The registered names of explicit integrators (aliases included)."""
    return sorted(k for k, v in _REGISTRY.items() if isinstance(v, Integrator) and v.explicit)


def _copy_state(source, target, entropy: bool) -> None:
    """Copy ``source``'s stepping arrays into ``target``'s, in place: x, p, Φ, η (with
    ``entropy``) and the arrays of ``extra`` (the heat-flow logs, the loads' work)."""
    np.copyto(target.positions, source.positions)
    np.copyto(target.momenta, source.momenta)
    if source.thermal_displacement is not None:
        np.copyto(target.thermal_displacement, source.thermal_displacement)
    if entropy and source.entropy is not None:
        np.copyto(target.entropy, source.entropy)
    copy_extra(source.extra, target.extra)
