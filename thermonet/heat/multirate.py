"""Multirate conduction: conduction every k steps, ``K(kh/2) ∘ A(h)^k ∘ K(kh/2)``.

Heat usually moves far slower than elastic waves (an element of steel at 1 mm diffuses its heat
over ~10⁵ explicit steps), so one conduction sweep per step is mostly wasted work. A conduction
cycle of k steps keeps energy exact and entropy non-decreasing for any k (every sweep does) and
is second order in k·h; outputs are second order when they fall on cycle boundaries, so k must
divide every output cadence and the run's length (a state inside a cycle has had only part of
its conduction).

*Sub-sweeps.* A cycle boundary may also sweep j times (j ≥ 1): its conduction over k h is then
2j half sweeps over k h / (2 j), alternately reverse and forward, the first j ending one cycle
(the last of them a reverse one) and the last j starting the next (the first a forward one):
each half is the other's adjoint, so the cycle stays symmetric, and its outputs fall between a
reverse and a forward half sweep as with one sweep.
The sweep error is that of a cycle of k / j steps, at the cost of one boundary (one entropy
update, one refresh of the forces) with j sweep pairs, instead of j boundaries.

``conduction_every = "auto"`` picks k with ``λ k h ≤ AUTO_TOLERANCE``, λ the conduction's
fastest rate (:meth:`thermonet.heat.setup.HeatSetup.fastest_rate`): the largest number of the
series 1, 2, 5, 10, 20, 50, … below that limit (so that the usual output cadences are
multiples of it and k does not depend on them), or its largest divisor that divides the
cadences where they are not. Where a longer cycle with sub-sweeps (``λ k h / j ≤
AUTO_TOLERANCE``, the cycle itself within ``λ k h ≤ AUTO_CYCLE``) costs at least
``AUTO_SAVING`` adiabatic steps per step less by :func:`boundary_cost`, it takes the cheapest
such cycle instead. The fastest mode's decay per pair of half sweeps stays resolved; the error
grows as (k h / j)²: on the thermal-shock scene (a bath 600 K above the bar) about
0.01 (λ k h / j)² of the temperature range, ≤ 1e-3 at the limit (docs/heat.md). An integer sets
k, with ``conduction_sweeps`` j (default 1).
"""

from __future__ import annotations

import math
from functools import reduce
from typing import NamedTuple

import numpy as np

from ..errors import InputError


class ConductionCycle(NamedTuple):
    """The conduction cycle a run took: k steps, why (a sentence), and its sub-sweeps j (the
    half sweeps of each half of a cycle boundary)."""

    k: int
    why: str
    sweeps: int = 1

    def describe(self) -> str:
        """"conduction every k steps[, j sub-sweeps] (why)": the run summary's and ``info``'s line."""
        return (f"conduction every {self.k} step{'s' if self.k != 1 else ''}"
                + (f", {self.sweeps} sub-sweeps" if self.sweeps > 1 else "") + f" ({self.why})")


#: why a j given with conduction_every = "auto" is refused (the API and scenes)
SWEEPS_WITH_AUTO = 'set it with a whole conduction_every (k); "auto" chooses the sub-sweeps itself'

#: "auto": k with λ k h / j ≤ this (on the thermal-shock scene: errors ≤ 1e-3 of the temperature range)
AUTO_TOLERANCE = 0.3
#: "auto" with sub-sweeps: a cycle's λ k h at most this (the fastest mode decays by at most e⁻¹
#: over the k steps whose mechanics sees the temperatures of the cycle's start)
AUTO_CYCLE = 1.0
#: "auto" takes sub-sweeps where they save at least this many adiabatic steps per step
AUTO_SAVING = 0.05
#: a cycle boundary's cost in adiabatic CO2 steps: a fixed part (the entropy update, the refresh
#: of the forces after the sweeps, the deferred kick's second force sum) and a part per pair of
#: half sweeps (measured with benchmarks/heat_cost.py on lattices and tetrahedra, one thread)
BOUNDARY_FIXED, BOUNDARY_PER_SWEEP = 0.5, 0.8


def check_conduction_every(value, where: str = "conduction_every"):
    """"auto" or an integer ≥ 1, else an InputError naming ``where``."""
    if isinstance(value, str):
        if value == "auto":
            return value
        raise InputError(f"{where}: expected \"auto\" or a whole number of steps ≥ 1, got {value!r}")
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or int(value) < 1:
        raise InputError(f"{where}: expected \"auto\" or a whole number of steps ≥ 1, got {value!r}")
    return int(value)


def check_conduction_sweeps(value, every, where: str = "conduction_sweeps"):
    """None (chosen by "auto", else 1) or an integer ≥ 1 given with an integer ``every``; else
    an InputError naming ``where``."""
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or int(value) < 1:
        raise InputError(f"{where}: expected a whole number of sub-sweeps ≥ 1, got {value!r}")
    if every == "auto":
        raise InputError(f"{where}: {SWEEPS_WITH_AUTO}")
    return int(value)


def auto_limit(rate: float, h: float) -> int:
    """The largest k with ``rate · k · h ≤ AUTO_TOLERANCE`` (at least 1)."""
    if rate <= 0.0:
        return 1 << 30
    return max(1, int(math.floor(AUTO_TOLERANCE / (rate * h) * (1 + 1e-12))))


def boundary_cost(k: int, sweeps: int) -> float:
    """The estimated conduction cost per step of a cycle of k steps with ``sweeps`` sub-sweeps,
    in adiabatic CO2 steps (:data:`BOUNDARY_FIXED`, :data:`BOUNDARY_PER_SWEEP`)."""
    return (BOUNDARY_FIXED + BOUNDARY_PER_SWEEP * sweeps) / k


def choose_cycle(requested, rate: float, h: float, cadences, where: str = "conduction_every",
                 sweeps: int | None = None) -> tuple[int, int, str]:
    """(k, j, why): the conduction cycle of k steps, each boundary swept j times (sub-sweeps,
    see the module docstring), for a run whose outputs fall every ``cadences`` steps (the output
    cadences, the run's length and the step it starts from; zeros ignored).

    requested: "auto" (see the module docstring) or k (which must divide every cadence: an
    InputError names the first that it does not), with j = ``sweeps`` (default 1).
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
        j = sweeps or 1
        if j == 1:
            return k, 1, f"set to {k}" + (f" (λ k h = {rate * k * h:.3g})" if rate > 0 else "")
        return k, j, f"set to {k}, {j} sub-sweeps" + (f" (λ k h / {j} = {rate * k * h / j:.3g})" if rate > 0 else "")
    if rate <= 0.0:
        k = common or 1
        return k, 1, "auto: no conductance, the sweeps exchange nothing"
    k, series = one_sweep_cycle(rate, h, cadences), round_below(auto_limit(rate, h))
    if rate * h > AUTO_TOLERANCE:  # (k = 1 cannot meet the tolerance: say so rather than claim it)
        return k, 1, (f"auto: fastest conduction rate λ = {rate:.4g}/time, λ h = {rate * h:.3g} > "
                      f"{AUTO_TOLERANCE:g}: conduction every step")
    why = (f"auto: fastest conduction rate λ = {rate:.4g}/time, λ k h = {rate * k * h:.3g} ≤ {AUTO_TOLERANCE:g}"
           + (f" (k divides the output cadences and the run's length, {common})" if k < series else ""))
    best = (boundary_cost(k, 1) - AUTO_SAVING, k, 1, k)
    scale = 1
    while scale * rate * h <= AUTO_CYCLE:  # longer cycles with sub-sweeps
        for m in (1, 2, 5):
            longer = math.gcd(common, m * scale) if common else m * scale
            j = math.ceil(rate * longer * h / AUTO_TOLERANCE * (1 - 1e-12))
            if m * scale * rate * h <= AUTO_CYCLE and j > 1 and boundary_cost(longer, j) < best[0]:
                best = (boundary_cost(longer, j), longer, j, m * scale)
        scale *= 10
    if best[2] == 1:
        return k, 1, why
    _, longer, j, wanted = best
    return longer, j, (
        f"auto: fastest conduction rate λ = {rate:.4g}/time, {j} sub-sweeps per cycle boundary: "
        f"λ k h / {j} = {rate * longer * h / j:.3g} ≤ {AUTO_TOLERANCE:g}, λ k h = {rate * longer * h:.3g} "
        f"≤ {AUTO_CYCLE:g}; about {boundary_cost(longer, j):.2g} adiabatic steps of conduction per step "
        f"against {boundary_cost(k, 1):.2g} with k = {k} and one sweep"
        + (f" (k divides the output cadences and the run's length, {common})" if longer < wanted else ""))


def one_sweep_cycle(rate: float, h: float, cadences) -> int:
    """The cycle "auto" takes with one sweep per boundary: the largest k of the series with
    λ k h ≤ AUTO_TOLERANCE, or its largest divisor that divides the ``cadences`` (rate > 0)."""
    common = reduce(math.gcd, [int(c) for c in cadences if int(c) > 0], 0)
    series = round_below(auto_limit(rate, h))
    return math.gcd(common, series) if common else series


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
