"""Multirate conduction: conduction every k steps, ``K(kh/2) ∘ A(h)^k ∘ K(kh/2)``.

Heat usually moves far slower than elastic waves (an element of steel at 1 mm diffuses its heat
over ~10⁵ explicit steps), so one conduction sweep per step is mostly wasted work. A conduction
cycle of k steps keeps energy exact and entropy non-decreasing for any k (every sweep does) and
is second order in k·h; outputs are second order when they fall on cycle boundaries, so k must
divide every output cadence and the run's length (a state inside a cycle has had only part of
its conduction).

``conduction_every = "auto"`` picks k with ``λ k h ≤ AUTO_TOLERANCE``, λ the conduction's
fastest rate (:meth:`thermonet.heat.setup.HeatSetup.fastest_rate`): the largest number of the
series 1, 2, 5, 10, 20, 50, … below that limit (so that the usual output cadences are
multiples of it and k does not depend on them), or its largest divisor that divides the
cadences where they are not. The fastest mode's decay per half sweep stays resolved; the error
grows as (k h)²: on the thermal-shock scene (a bath 600 K above the bar) about 0.01 (λ k h)² of
the temperature range, ≤ 1e-3 at the limit (docs/heat.md). An integer sets k.
"""

from __future__ import annotations

import math
from functools import reduce

import numpy as np

from ..errors import InputError

#: "auto": k with λ k h ≤ this (on the thermal-shock scene: errors ≤ 1e-3 of the temperature range)
AUTO_TOLERANCE = 0.3


def check_conduction_every(value, where: str = "conduction_every"):
    """"auto" or an integer ≥ 1, else an InputError naming ``where``."""
    if isinstance(value, str):
        if value == "auto":
            return value
        raise InputError(f"{where}: expected \"auto\" or a whole number of steps ≥ 1, got {value!r}")
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or int(value) < 1:
        raise InputError(f"{where}: expected \"auto\" or a whole number of steps ≥ 1, got {value!r}")
    return int(value)


def auto_limit(rate: float, h: float) -> int:
    """The largest k with ``rate · k · h ≤ AUTO_TOLERANCE`` (at least 1)."""
    if rate <= 0.0:
        return 1 << 30
    return max(1, int(math.floor(AUTO_TOLERANCE / (rate * h) * (1 + 1e-12))))


def choose_cycle(requested, rate: float, h: float, cadences, where: str = "conduction_every") -> tuple[int, str]:
    """(k, why): the conduction cycle for a run whose outputs fall every ``cadences`` steps
    (the output cadences, the run's length and the step it starts from; zeros ignored).

    requested: "auto" (the largest divisor of every cadence with λ k h ≤ AUTO_TOLERANCE) or k
    (which must divide every cadence: an InputError names the first that it does not).
    """
    cadences = [int(c) for c in cadences if int(c) > 0]
    common = reduce(math.gcd, cadences, 0)
    if requested != "auto":
        k = int(requested)
        if common and common % k:
            bad = next(c for c in cadences if c % k)
            raise InputError(f"{where} = {k} does not divide the run's output cadences and length "
                             f"({', '.join(str(c) for c in cadences)}; {bad} is not a multiple of {k}): an "
                             "output inside a conduction cycle is only first order; give a divisor or \"auto\"")
        return k, f"set to {k}" + (f" (λ k h = {rate * k * h:.3g})" if rate > 0 else "")
    if rate <= 0.0:
        k = common or 1
        return k, "auto: no conductance, the sweeps exchange nothing"
    limit = auto_limit(rate, h)
    series = round_below(limit)
    k = math.gcd(common, series) if common else series
    if rate * h > AUTO_TOLERANCE:  # (k = 1 cannot meet the tolerance: say so rather than claim it)
        return k, (f"auto: fastest conduction rate λ = {rate:.4g}/time, λ h = {rate * h:.3g} > {AUTO_TOLERANCE:g}: "
                   "conduction every step")
    why = (f"auto: fastest conduction rate λ = {rate:.4g}/time, λ k h = {rate * k * h:.3g} ≤ {AUTO_TOLERANCE:g}"
           + (f" (k divides the output cadences and the run's length, {common})" if k < series else ""))
    return k, why


def round_below(limit: int) -> int:
    """The largest number of the series 1, 2, 5, 10, 20, 50, … that is ≤ limit (≥ 1)."""
    best = 1
    scale = 1
    while scale <= limit:
        for m in (1, 2, 5):
            if m * scale <= limit:
                best = m * scale
        scale *= 10
    return best
