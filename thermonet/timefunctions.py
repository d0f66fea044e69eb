"""Scalar functions of time for baths, sources and loads: constant, linear, ramp, sine, table.

A :class:`TimeFunction` is data (a kind and a few numbers, or a table of points), so that the
kernels can evaluate it: :func:`pack` lays a list of them out as arrays and :func:`evaluate` /
:func:`evaluate_rate` (``numba.njit``-compiled, also plain Python) read one of them at a time t.

Kinds (t in the run's time unit):

- ``constant``: v(t) = value
- ``linear``: v(t) = start + rate t (a constant velocity when v is a displacement)
- ``ramp``: from ``start`` to ``end`` linearly over [0, duration], then held at ``end``
- ``sine``: v(t) = offset + amplitude sin(2π frequency t + phase)
- ``table``: linear between points (t_i, v_i), t strictly increasing; held at the first value
  before the first point and at the last after the last
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
from numba import njit

from .errors import InputError

CONSTANT, LINEAR, RAMP, SINE, TABLE = 0, 1, 2, 3, 4
KINDS = {"constant": CONSTANT, "linear": LINEAR, "ramp": RAMP, "sine": SINE, "table": TABLE}

#: the forms a scene or the API may give (see :func:`time_function`)
FORMS = ("a number (constant)", "{start, rate} (linear)", "{start, end, duration} (ramp)",
         "{amplitude, frequency, phase, offset} (sine)", "{table = [[t0, v0], [t1, v1], ...]} (table)")


@dataclass(frozen=True, eq=False)
class TimeFunction:
    """One scalar function of time. kind: a key of :data:`KINDS`; params: up to 4 floats (their
    meaning per kind in the module docstring, in the order of :meth:`constant` … :meth:`sine`);
    times, values: (P,) the table's points (kind ``table`` only)."""

    kind: str
    params: tuple = ()
    times: np.ndarray = field(default_factory=lambda: np.empty(0))
    values: np.ndarray = field(default_factory=lambda: np.empty(0))

    @classmethod
    def constant(cls, value: float) -> "TimeFunction":
        return cls("constant", (float(value),))

    @classmethod
    def linear(cls, rate: float, start: float = 0.0) -> "TimeFunction":
        return cls("linear", (float(start), float(rate)))

    @classmethod
    def ramp(cls, end: float, duration: float, start: float = 0.0) -> "TimeFunction":
        return cls("ramp", (float(start), float(end), float(duration)))

    @classmethod
    def sine(cls, amplitude: float, frequency: float, phase: float = 0.0, offset: float = 0.0) -> "TimeFunction":
        return cls("sine", (float(amplitude), float(frequency), float(phase), float(offset)))

    @classmethod
    def table(cls, points) -> "TimeFunction":
        pts = np.asarray(points, dtype=np.float64)
        return cls("table", (), np.ascontiguousarray(pts[:, 0]), np.ascontiguousarray(pts[:, 1]))

    def __call__(self, t: float) -> float:
        """v(t)."""
        f = pack([self])
        return float(evaluate(f.kind, f.params, f.ptr, f.times, f.values, 0, float(t)))

    def rate(self, t: float) -> float:
        """dv/dt at t (right derivative at a table point or at the end of a ramp)."""
        f = pack([self])
        return float(evaluate_rate(f.kind, f.params, f.ptr, f.times, f.values, 0, float(t)))

    def describe(self) -> str:
        """The function in words and numbers, for messages and ``thermonet info``: ``900``,
        ``300 + 2·t``, ``300 → 900 over t ∈ [0, 5]``, ``1 + 2·sin(2π·0.5·t + 0)``, ``table of 3
        points, t ∈ [0, 2]``."""
        p = self.params
        if self.kind == "constant":
            return f"{p[0]:g}"
        if self.kind == "linear":
            return f"{p[0]:g} {'−' if p[1] < 0 else '+'} {abs(p[1]):g}·t"
        if self.kind == "ramp":
            return f"{p[0]:g} → {p[1]:g} over t ∈ [0, {p[2]:g}]"
        if self.kind == "sine":
            return f"{p[3]:g} + {p[0]:g}·sin(2π·{p[1]:g}·t + {p[2]:g})"
        if self.kind == "table" and len(self.times):
            return f"table of {len(self.times)} points, t ∈ [{self.times[0]:g}, {self.times[-1]:g}]"
        return f"{self.kind} {p}"

    def __repr__(self) -> str:
        return f"<TimeFunction {self.describe()}>"

    def first_at_or_below(self, level: float = 0.0) -> float | None:
        """The first time t ≥ 0 at which v(t) ≤ level (None if never)."""
        p = self.params
        if self.kind == "constant":
            return 0.0 if p[0] <= level else None
        if self.kind == "linear":
            if p[0] <= level:
                return 0.0
            return (level - p[0]) / p[1] if p[1] < 0 else None
        if self.kind == "ramp":
            if p[0] <= level:
                return 0.0
            return p[2] * (p[0] - level) / (p[0] - p[1]) if p[1] <= level else None
        if self.kind == "sine":
            amplitude, frequency, phase, offset = p
            if offset - abs(amplitude) > level:
                return None
            if frequency == 0.0:
                return 0.0 if offset + amplitude * math.sin(phase) <= level else None
            t = np.linspace(0.0, 1.0 / frequency, 100_001)
            below = np.flatnonzero(offset + amplitude * np.sin(2 * math.pi * frequency * t + phase) <= level)
            return float(t[below[0]]) if below.size else None
        times, values = np.asarray(self.times), np.asarray(self.values)
        if values[0] <= level:
            return 0.0  # held before the first point
        for i in range(1, len(values)):
            if values[i] <= level:
                a, b = values[i - 1], values[i]
                return float(times[i - 1] + (times[i] - times[i - 1]) * (a - level) / (a - b))
        return None


class PackedFunctions(tuple):
    """A list of :class:`TimeFunction` s as arrays: kind (F,) int64, params (F, 4), ptr (F+1,)
    int64 (function f's points are times[ptr[f]:ptr[f+1]]), times, values (P,)."""

    __slots__ = ()

    def __new__(cls, kind, params, ptr, times, values):
        return super().__new__(cls, (kind, params, ptr, times, values))

    def __getnewargs__(self):  # (pickled as its five arrays: a distributed run sends it)
        return tuple(self)

    kind = property(lambda self: self[0])
    params = property(lambda self: self[1])
    ptr = property(lambda self: self[2])
    times = property(lambda self: self[3])
    values = property(lambda self: self[4])


def pack(functions) -> PackedFunctions:
    """The arrays the kernels read for ``functions`` (a sequence of :class:`TimeFunction`)."""
    functions = list(functions)
    kind = np.array([KINDS[f.kind] for f in functions], dtype=np.int64)
    params = np.zeros((len(functions), 4))
    counts = [len(f.times) for f in functions]
    for i, f in enumerate(functions):
        params[i, :len(f.params)] = f.params
    ptr = np.zeros(len(functions) + 1, dtype=np.int64)
    ptr[1:] = np.cumsum(counts)
    times = np.concatenate([f.times for f in functions]) if functions else np.empty(0)
    values = np.concatenate([f.values for f in functions]) if functions else np.empty(0)
    return PackedFunctions(kind, params, ptr, np.ascontiguousarray(times, dtype=np.float64),
                           np.ascontiguousarray(values, dtype=np.float64))


def evaluate_py(kind, params, ptr, times, values, f, t):
    """Function f of the packed arrays at time t (plain Python; :func:`evaluate` is it compiled)."""
    k = kind[f]
    if k == CONSTANT:
        return params[f, 0]
    if k == LINEAR:
        return params[f, 0] + params[f, 1] * t
    if k == RAMP:
        duration = params[f, 2]
        if t >= duration:
            return params[f, 1]
        if t <= 0.0:
            return params[f, 0]
        return params[f, 0] + (params[f, 1] - params[f, 0]) * (t / duration)
    if k == SINE:
        return params[f, 3] + params[f, 0] * math.sin(2.0 * math.pi * params[f, 1] * t + params[f, 2])
    lo = ptr[f]
    hi = ptr[f + 1] - 1
    if t <= times[lo]:
        return values[lo]
    if t >= times[hi]:
        return values[hi]
    while hi - lo > 1:  # bisection: times[lo] < t < times[hi]
        mid = (lo + hi) // 2
        if times[mid] <= t:
            lo = mid
        else:
            hi = mid
    w = (t - times[lo]) / (times[hi] - times[lo])
    return values[lo] + w * (values[hi] - values[lo])


def evaluate_rate_py(kind, params, ptr, times, values, f, t):
    """d/dt of function f at time t (right derivative at kinks); plain Python."""
    k = kind[f]
    if k == CONSTANT:
        return 0.0
    if k == LINEAR:
        return params[f, 1]
    if k == RAMP:
        duration = params[f, 2]
        if t >= duration or t < 0.0:
            return 0.0
        return (params[f, 1] - params[f, 0]) / duration
    if k == SINE:
        w = 2.0 * math.pi * params[f, 1]
        return params[f, 0] * w * math.cos(w * t + params[f, 2])
    lo = ptr[f]
    hi = ptr[f + 1] - 1
    if t < times[lo] or t >= times[hi]:
        return 0.0
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if times[mid] <= t:
            lo = mid
        else:
            hi = mid
    return (values[hi] - values[lo]) / (times[hi] - times[lo])


evaluate = njit(inline="always", error_model="numpy", boundscheck=False)(evaluate_py)
evaluate_rate = njit(inline="always", error_model="numpy", boundscheck=False)(evaluate_rate_py)


def time_function(value, where: str) -> TimeFunction:
    """A :class:`TimeFunction` from what a scene or the API gives (see :data:`FORMS`): a number,
    a TimeFunction, or a mapping of one form's keys. ``where`` names the key in errors (with
    file:line from a scene)."""
    if isinstance(value, TimeFunction):
        f = value
    elif isinstance(value, bool):
        raise InputError(f"{where}: expected a number or a time function, got {value!r}")
    elif isinstance(value, (int, float, np.floating, np.integer)):
        f = TimeFunction.constant(float(value))
    elif isinstance(value, Mapping):
        f = _from_mapping(dict(value), where)
    else:
        raise InputError(f"{where}: expected a number or a time function ({'; '.join(FORMS)}), got {value!r}")
    _check(f, where)
    return f


def _from_mapping(d: dict, where: str) -> TimeFunction:
    keys = set(d)
    forms = {
        "table": ({"table"}, set()),
        "sine": ({"amplitude", "frequency"}, {"phase", "offset"}),
        "ramp": ({"end", "duration"}, {"start"}),
        "linear": ({"rate"}, {"start"}),
    }
    for kind, (needed, optional) in forms.items():
        if needed <= keys:
            extra = keys - needed - optional
            if extra:
                raise InputError(f"{where}: unknown key(s) {sorted(extra)} for a {kind} time function "
                                 f"(keys: {sorted(needed | optional)})")
            for k in keys - {"table"}:
                if isinstance(d[k], bool) or not isinstance(d[k], (int, float)):
                    raise InputError(f"{where}.{k}: expected a number, got {d[k]!r}")
            if kind == "table":
                return _table(d["table"], where)
            if kind == "sine":
                return TimeFunction.sine(d["amplitude"], d["frequency"], d.get("phase", 0.0), d.get("offset", 0.0))
            if kind == "ramp":
                return TimeFunction.ramp(d["end"], d["duration"], d.get("start", 0.0))
            return TimeFunction.linear(d["rate"], d.get("start", 0.0))
    raise InputError(f"{where}: {sorted(keys)} is not a time function; give one of: {'; '.join(FORMS)}")


def _table(points, where: str) -> TimeFunction:
    try:
        pts = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{where}.table: expected [[t0, v0], [t1, v1], ...] of numbers, got {points!r}") from None
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 1:
        raise InputError(f"{where}.table: expected [[t0, v0], [t1, v1], ...] (pairs), got shape {pts.shape}")
    return TimeFunction.table(pts)


def _check(f: TimeFunction, where: str) -> None:
    values = np.concatenate([np.asarray(f.params, dtype=np.float64), f.times, f.values])
    if not np.all(np.isfinite(values)):
        if f.kind == "constant":
            raise InputError(f"{where}: must be finite, got {f.params[0]:g}")
        raise InputError(f"{where}: a non-finite number in the time function {f.describe()}")
    if f.kind == "ramp" and not f.params[2] > 0.0:
        raise InputError(f"{where}.duration: must be > 0, got {f.params[2]}")
    if f.kind == "sine" and not f.params[1] >= 0.0:
        raise InputError(f"{where}.frequency: must be ≥ 0, got {f.params[1]}")
    if f.kind == "table":
        steps = np.diff(f.times)
        if np.any(steps <= 0.0):
            i = int(np.flatnonzero(steps <= 0.0)[0])
            raise InputError(f"{where}.table: times must increase strictly; point {i + 1} "
                             f"(t = {f.times[i + 1]}) does not come after point {i} (t = {f.times[i]})")


def bounds(f: TimeFunction, t_end: float) -> tuple[float, float]:
    """(min, max) of f over [0, t_end] (exact for every kind: extremes at ends, table points or,
    for a sine, its amplitude when a full period fits)."""
    ts = [0.0, float(t_end)]
    if f.kind == "table":
        ts += [t for t in f.times if 0.0 <= t <= t_end]
    if f.kind == "ramp":
        ts.append(min(f.params[2], t_end))
    vals = [f(t) for t in ts]
    if f.kind == "sine":
        amplitude, frequency, _, offset = f.params
        if frequency * t_end >= 1.0:
            vals += [offset - abs(amplitude), offset + abs(amplitude)]
        else:
            vals += [f(t) for t in np.linspace(0.0, t_end, 257)]
    return float(min(vals)), float(max(vals))
