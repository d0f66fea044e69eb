"""The schedule of an explicit step: which sub-flow runs, with which coefficient, in which order.

An explicit integrator is a sequence of sub-flows with coefficients (fractions of h): the kicks
and drifts of a :class:`~thermonet.explicit.splitting.Splitting`, and any number of further
:class:`SubFlow` s (up to :data:`MAX_FLOWS` distinct ones) placed between them. :func:`stage_table`
turns that into the one table every target reads — the CPU kernel
(:mod:`thermonet.explicit.cpu`) and both CUDA launch modes (:mod:`thermonet.explicit.cuda`):

- a *stage* row ``(−1, k, d)``: a kick of k h fused with the drift of d h that follows it (one
  spring pass and one node pass);
- a *flow* row ``(j, c, τ)``: sub-flow j of the integrator over c h, at the time t + τ h of the
  positions it sees; a negative j other than −1 is a built-in heat-flow row (conduction swept
  forward or in reverse, thermal waves: :data:`CONDUCTION`, :data:`WAVES`).

The last kick of a step and the first of the next act at the same positions when no flow stands
between them: the table's ``carry`` is then that last kick, applied with the next step's first
stage (as two additions, so runs cut into chunks give the same bits) or by a call's closing kick.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import numpy as np

from ..errors import InputError
from ..heat.rows import CONDUCTION_FORWARD, CONDUCTION_REVERSE, THERMAL_WAVES

#: most distinct sub-flows one integrator may add to its kicks and drifts (the kernels dispatch
#: over a fixed number of slots, so that each stays a compile-time call)
MAX_FLOWS = 4

#: a stage row: a kick fused with the drift after it
STAGE = -1
#: the first sub-flow slot: a row whose code is at least this runs sub-flow slot ``code``
FIRST_FLOW_SLOT = 0
# built-in heat-flow rows (docs/theory.md §5–6): CONDUCTION_FORWARD, CONDUCTION_REVERSE (the second
# half of a symmetric cycle) and THERMAL_WAVES, codes named in thermonet.heat.rows


@dataclass(frozen=True)
class BuiltinFlow:
    """A heat-flow sub-flow every kernel knows (not a :class:`SubFlow` slot): its table code is
    one of the negative codes above."""

    name: str
    code: int

    def __repr__(self) -> str:
        return f"<built-in sub-flow {self.name}>"


#: the heat-flow sub-flows, for ``Splitting.flows``
CONDUCTION = (BuiltinFlow("conduction", CONDUCTION_FORWARD), BuiltinFlow("conduction (reverse sweep)",
                                                                          CONDUCTION_REVERSE))
WAVES = BuiltinFlow("thermal waves", THERMAL_WAVES)


@dataclass(frozen=True, eq=False)
class SubFlow:
    """A sub-flow of explicit steps beyond kick and drift, applied element by element.

    update: ``update(i, data, tau, t, x, p, phi, eta)``, a plain Python function (compiled with
    ``numba.njit`` for the CPU, as a device function for CUDA, run as Python under the CUDA
    simulator) that advances element i of the flow over a time tau at time t. x, p: (n, 3);
    phi, eta: (m,) (empty when thermal coupling is off); all in the internal numbering
    (``system.layout``). It may write only what belongs to element i (elements run in parallel).
    prepare: ``prepare(system) -> tuple of arrays``, the flow's own data (the record passed as
    ``data``); elements are ``range(len(data[0]))``.
    """

    name: str
    update: Callable
    prepare: Callable
    description: str = field(default="", compare=False)

    def __repr__(self) -> str:
        return f"<sub-flow {self.name}>"


class StageTable(NamedTuple):
    """The schedule of one step as arrays (see the module docstring).

    code: (R,) int64, −1 for a stage, ≤ −2 a built-in heat-flow row, else the flow's slot; kick: (R,) a stage's kick or a flow's
    coefficient; drift: (R,) a stage's drift or, for a flow, the time fraction τ of its
    positions; carry: the closing kick shared with the next step (0 when none).
    """

    code: np.ndarray
    kick: np.ndarray
    drift: np.ndarray
    carry: float


def flow_slots(flows) -> tuple[SubFlow, ...]:
    """The distinct sub-flows of ``flows`` ((position, SubFlow, coefficient), ...), in order of
    first appearance: slot j of the kernels runs ``slots[j]``."""
    slots: list[SubFlow] = []
    for _, flow, _ in flows:
        if isinstance(flow, BuiltinFlow):
            continue
        if flow not in slots:
            slots.append(flow)
    if len(slots) > MAX_FLOWS:
        raise InputError(f"an integrator may add at most {MAX_FLOWS} distinct sub-flows, not {len(slots)}")
    return tuple(slots)


def stage_table(kicks, drifts, flows=()) -> StageTable:
    """The table of ``K(k0) D(d0) … D(d_{S−1}) K(k_S)`` with ``flows`` ((position, SubFlow,
    coefficient), ...): position i ≤ S runs the flow before kick i, S + 1 after the last kick."""
    n_stages = len(drifts)
    slots = flow_slots(flows)
    at: dict[int, list] = {}
    for position, flow, coefficient in flows:
        if not 0 <= position <= n_stages + 1:
            raise InputError(f"sub-flow {flow.name}: position {position} outside 0..{n_stages + 1}")
        code = flow.code if isinstance(flow, BuiltinFlow) else slots.index(flow)
        at.setdefault(position, []).append((code, float(coefficient)))
    shared = not at.get(0) and not at.get(n_stages + 1)
    rows: list[tuple[int, float, float]] = []
    time = 0.0
    for i in range(n_stages + 1):
        rows.extend((slot, c, time) for slot, c in at.get(i, ()))
        if i < n_stages:
            rows.append((STAGE, float(kicks[i]), float(drifts[i])))
            time += float(drifts[i])
        elif not shared and kicks[i] != 0.0:
            rows.append((STAGE, float(kicks[i]), 0.0))
    rows.extend((slot, c, time) for slot, c in at.get(n_stages + 1, ()))
    code = np.array([r[0] for r in rows], dtype=np.int64)
    kick = np.array([r[1] for r in rows], dtype=np.float64)
    drift = np.array([r[2] for r in rows], dtype=np.float64)
    return StageTable(code, kick, drift, float(kicks[n_stages]) if shared else 0.0)


def flow_data(flows, system) -> tuple:
    """The kernels' ``effects`` record: one data tuple per flow slot (4), each flow's
    ``prepare(system)`` (as contiguous arrays), an unused slot a one-array placeholder."""
    data = [tuple(np.ascontiguousarray(a) for a in f.prepare(system)) for f in flows]
    return tuple(data + [(np.empty(0),)] * (MAX_FLOWS - len(data)))
