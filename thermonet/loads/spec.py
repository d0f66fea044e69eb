"""Loads as the user gives them: driven node groups (:class:`Drive`) and forces on node groups
(:class:`Force`), each a vector of :class:`~thermonet.timefunctions.TimeFunction` s, checked with
errors that name the load and its key.

A component is given per axis (``{"x": f, "z": g}`` or ``[f, None, g]``) or as a direction times
one function (``direction=[1, 0, 0], value=f``). Every component takes the forms of
:func:`thermonet.timefunctions.time_function` (a number, a mapping, a TimeFunction).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import InputError
from ..timefunctions import TimeFunction, time_function

AXES = ("x", "y", "z")


@dataclass(frozen=True, eq=False)
class Drive:
    """Prescribed motion of a node group: x_i(t) = X_i + u(t) − u(0) in the driven axes.

    group: a node group name of the net, or node indices (user numbering).
    displacement: u, per axis (a mapping of "x", "y", "z" or a 3-sequence; None: not driven)
        or one function along ``direction``; ``velocity``: a constant velocity per axis
        instead (u = v t; an axis of velocity 0 is not set, so ``free`` decides it).
    free: what the axes u does not set do: False (default) held at their initial positions,
        True free (moved by the net like any free node; a roller support).
    name: the load's name in diagnostics columns and errors.
    """

    group: object
    displacement: object = None
    direction: object = None
    velocity: object = None
    free: bool = False
    name: str = ""

    kind = "drive"

    def components(self, where: str) -> tuple:
        """The 3 components (TimeFunction or None) and the (3,) free-axis mask (1.0 free)."""
        if (self.displacement is None) == (self.velocity is None):
            raise InputError(f"{where}: give exactly one of displacement or velocity")
        if self.velocity is not None:
            v = _vector(self.velocity, f"{where}.velocity")
            comps = tuple(None if c == 0.0 else TimeFunction.linear(float(c)) for c in v)  # 0: not set
        else:
            comps = _components(self.displacement, self.direction, f"{where}.displacement")
        free = np.array([1.0 if (c is None and self.free) else 0.0 for c in comps])
        if not isinstance(self.free, (bool, np.bool_)):
            raise InputError(f"{where}.free: must be true or false, got {self.free!r}")
        return comps, free


@dataclass(frozen=True, eq=False)
class Force:
    """A force on every node of a group: f(t) per node, or with ``total`` a total force spread
    over the group's nodes in proportion to their masses (the group's centre of mass then
    accelerates as a free particle would). Components as in :class:`Drive`."""

    group: object
    force: object = None
    direction: object = None
    total: bool = False
    name: str = ""

    kind = "force"

    def components(self, where: str) -> tuple:
        if self.force is None:
            raise InputError(f"{where}.force: missing (a vector of time functions, or a direction and a value)")
        if not isinstance(self.total, (bool, np.bool_)):
            raise InputError(f"{where}.total: must be true or false, got {self.total!r}")
        return _components(self.force, self.direction, f"{where}.force"), np.ones(3)


def _vector(v, where: str) -> np.ndarray:
    try:
        a = np.asarray(v, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"{where}: expected 3 numbers, got {v!r}") from None
    if a.shape != (3,) or not np.isfinite(a).all():
        raise InputError(f"{where}: expected 3 finite numbers, got {v!r}")
    return a


def _components(value, direction, where: str) -> tuple:
    """Three TimeFunctions (None where not given) from a per-axis value or direction × value."""
    if direction is not None:
        d = _vector(direction, where.rsplit(".", 1)[0] + ".direction")
        norm = float(np.linalg.norm(d))
        if norm == 0.0:
            raise InputError(f"{where.rsplit('.', 1)[0]}.direction: must not be zero")
        f = time_function(value, where)
        return tuple(None if c == 0.0 else _scaled(f, c / norm) for c in d)
    if isinstance(value, Mapping) and set(value) <= set(AXES) and value:
        return tuple(None if value.get(a) is None else time_function(value[a], f"{where}.{a}") for a in AXES)
    if isinstance(value, (list, tuple, np.ndarray)) and len(value) == 3:
        return tuple(None if c is None else time_function(c, f"{where}[{i}]") for i, c in enumerate(value))
    raise InputError(f"{where}: expected one time function per axis ({{x = ..., y = ..., z = ...}} or 3 items) "
                     f"or a direction and a value, got {value!r}")


def _scaled(f: TimeFunction, c: float) -> TimeFunction:
    """c f as a TimeFunction of the same kind."""
    if c == 1.0:
        return f
    if f.kind == "table":
        return TimeFunction("table", (), f.times, f.values * c)
    p = list(f.params)
    if f.kind == "sine":
        p[0] *= c
        p[3] *= c
    else:  # constant, linear, ramp: every parameter but the ramp's duration scales
        p = [v * c for v in p]
        if f.kind == "ramp":
            p[2] = f.params[2]
    return TimeFunction(f.kind, tuple(p))
