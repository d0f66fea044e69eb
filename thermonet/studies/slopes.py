"""Convergence slopes fitted over the asymptotic range of an error-versus-step curve.

How the range is chosen (no knowledge of the expected order is used):

1. Points are dropped that are not finite, that lie below the *floor* (errors there measure the
   reference solution or round-off, not the integrator: the caller passes e.g. 100× the
   reference's estimated error), or whose error is at least ``max_relative`` (10 %) of the
   quantity's size (no longer a small perturbation of the solution; not applied to a quantity
   of size 0).
2. Of what remains, the contiguous run of time steps that contains the smallest kept step is
   taken.
3. Starting from each point of that run in turn (smallest step first), points towards larger
   steps are added while the local slope (log-log slope between a point and its smaller
   neighbour) stays within ``tolerance`` (0.25) of the median of the local slopes already
   accepted; the first coarse point that bends the curve away ends the range (the
   pre-asymptotic regime). The longest such range wins, the one at smaller steps on ties. Starting
   anywhere, not only at the smallest step, lets the range skip a finest point that has reached
   the integrator's own round-off or solver-tolerance floor (seen with HO4's temperatures: the
   error stops falling at ~1e-13 of θ after thousands of steps), which no reference floor catches.
4. The slope is the least-squares fit of log(error) on log(h) over the range (at least two points).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SlopeFit:
    """slope: fitted order (nan without two usable points); constant: error ≈ constant·h^slope;
    h_min, h_max: the range fitted; n_points: how many points it holds."""

    slope: float
    constant: float
    h_min: float
    h_max: float
    n_points: int


def asymptotic_slope(h, error, floor: float = 0.0, scale: float = np.inf, max_relative: float = 0.1,
                     tolerance: float = 0.25) -> SlopeFit:
    """Fit error ≈ C h^p over the asymptotic range (see the module docstring).

    h, error: (n,) time steps and errors (any order); floor: errors at or below it are not
    used; scale: the size of the quantity (errors ≥ max_relative·scale are not used).
    """
    h = np.asarray(h, dtype=np.float64)
    error = np.asarray(error, dtype=np.float64)
    order = np.argsort(h)
    h, error = h[order], error[order]
    # a quantity of size 0 (e.g. momenta at rest) has no relative criterion: only the floor applies
    usable = (np.isfinite(error) & (error > floor) & (error > 0)
              & ((error < max_relative * scale) | (not scale > 0)))
    if usable.sum() < 2:
        return SlopeFit(float("nan"), float("nan"), float("nan"), float("nan"), int(usable.sum()))
    first = int(np.flatnonzero(usable)[0])
    last = first
    while last + 1 < len(h) and usable[last + 1]:
        last += 1
    logh, loge = np.log(h[first:last + 1]), np.log(error[first:last + 1])
    local = np.diff(loge) / np.diff(logh)
    best_start, best_n = 0, 0
    for start in range(len(local)):
        accepted = [local[start]]
        for s in local[start + 1:]:
            if abs(s - np.median(accepted)) > tolerance:
                break
            accepted.append(s)
        if len(accepted) + 1 > best_n:
            best_start, best_n = start, len(accepted) + 1
    i, n = best_start, best_n
    p, logc = np.polyfit(logh[i:i + n], loge[i:i + n], 1)
    return SlopeFit(float(p), float(np.exp(logc)), float(h[first + i]), float(h[first + i + n - 1]), n)
