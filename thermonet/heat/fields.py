"""Output fields of heat flow, from the springs' temperatures (internal numbering).

- :func:`junction_temperature`: each node's temperature as a heat junction,
  ``Σ_e g_e θ_e / Σ_e g_e`` over its springs (the temperature that makes the junction's net heat
  zero; a bath node's is the bath's): a smooth point field for ParaView;
- :func:`heat_rate`: the net heat flowing into each spring per time from the junctions at its
  ends (``g_e (J_i − θ_e)`` at each junction end i, the same as ``Σ_f κ_ef (θ_f − θ_e)``), its
  bath ends and its sources.
"""

from __future__ import annotations

import numpy as np

from .exchange import BATH


def _bath_values(heat, t: float) -> np.ndarray:
    return np.array([f(t) for f in heat.functions], dtype=np.float64)


def junction_temperature(heat, layout, theta: np.ndarray, t: float, out: np.ndarray | None = None) -> np.ndarray:
    """(n,) junction temperatures at time t (θ: (m,) spring temperatures). Nodes whose springs
    all have g = 0 get the mean of their springs' temperatures."""
    n = layout.n_nodes
    spring = layout.inc_spring.astype(np.int64)
    node = np.repeat(np.arange(n), np.diff(layout.inc_ptr))
    g = heat.conductance[spring]
    weight = np.bincount(node, weights=g, minlength=n)
    weighted = np.bincount(node, weights=g * theta[spring], minlength=n)
    count = np.bincount(node, minlength=n)
    mean = np.bincount(node, weights=theta[spring], minlength=n) / np.maximum(count, 1)
    result = np.where(weight > 0.0, weighted / np.where(weight > 0.0, weight, 1.0), mean)
    baths = heat.bath_nodes >= 0
    if baths.any():
        result[baths] = _bath_values(heat, t)[heat.bath_nodes[baths]]
    if out is not None:
        out[:] = result
        return out
    return result


def heat_rate(heat, theta: np.ndarray, t: float) -> np.ndarray:
    """(m,) net heat per time flowing into each spring at time t (θ: (m,))."""
    m = len(theta)
    layout = heat.layout
    edges = np.asarray(layout.edges, dtype=np.int64)
    junction = junction_temperature(heat, layout, theta, t)
    rate = np.zeros(m)
    g = heat.conductance if heat.conduction else np.zeros(m)
    for end in (0, 1):
        node = edges[:, end]
        inner = heat.bath_nodes[node] < 0  # bath ends are entries (below)
        rate += np.where(inner, g * (junction[node] - theta), 0.0)
    if len(heat.entry_spring):
        values = _bath_values(heat, t)[heat.entry_fn]
        e = heat.entry_spring
        entry = np.where(heat.entry_kind == BATH, heat.entry_rate * heat.capacity[e] * (values - theta[e]), values)
        rate += np.bincount(e, weights=entry, minlength=m)
    return rate
