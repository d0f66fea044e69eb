"""The heat-flow logs the kernels keep in the state (:func:`heat_logs`, :func:`cycle_position`)
and the heat-flow columns of a diagnostics row computed from them.

- ``entropy_produced``: Σ of every exchange's entropy production (junctions and bath ends), since
  the run's logs started;
- ``heat_<name>``: heat given to the net by each bath and source; ``heat_in``: their sum;
- ``entropy_in``: entropy brought in (Q/θ_b by baths, C ln(θ'/θ) by sources);
- ``wave_energy`` (thermal waves): W(Φ), included in ``energy``;
- ``energy_balance``: ``H − H(0) − (heat_in − heat_in(0))``, zero but for the integrator's
  error (bounded and O(h²) with an explicit splitting, the Newton tolerance with EM2);
- ``entropy_balance``: ``S − S(0) − Δentropy_in − Δentropy_produced``, zero to round-off.

(0) is the first row of the series.
"""

from __future__ import annotations

import numpy as np

#: heat-flow logs with one value per spring (stored in the user's numbering outside the engine)
PER_SPRING_LOGS = ("produced", "theta", "length", "pending_eta", "pending_produced", "pending_theta")


def heat_columns(heat, state) -> dict:
    """The logged columns of ``state`` (see the module docstring; the balances are added by
    :func:`balances`)."""
    logs = state.extra["heat"]
    # (bincount adds the entries in order from 0, as np.add.at would, at a fraction of its cost)
    per_name = np.bincount(heat.entry_fn, weights=logs["entry_heat"], minlength=len(heat.names))
    flux = float(np.sum(logs["entry_flux"]))
    row = {"entropy_produced": float(np.sum(logs["produced"]))}
    for name, q in zip(heat.names, per_name):
        row[f"heat_{name}"] = float(q)
    row["heat_in"] = float(np.sum(per_name))
    row["entropy_in"] = flux
    return row


def wave_energy(heat, phi: np.ndarray) -> float:
    """The Green–Naghdi gradient energy W(Φ) = Σ_pairs k*/2 (Φ_e − Φ_f)² (part of H with thermal
    waves)."""
    g = heat.graph
    d = phi[g.first] - phi[g.second]
    return float(0.5 * np.sum(g.kappa[:, 1] * d * d))


def balances(row: dict, first: dict) -> dict:
    """energy_balance and entropy_balance of ``row`` against the series' first row."""
    return {
        "energy_balance": (row["energy"] - first["energy"]) - (row["heat_in"] - first["heat_in"]),
        "entropy_balance": ((row["entropy"] - first["entropy"]) - (row["entropy_in"] - first["entropy_in"])
                            - (row["entropy_produced"] - first["entropy_produced"])),
    }


def heat_logs(state, heat) -> dict:
    """The heat-flow logs kept in ``state.extra["heat"]`` (created zeroed the first time)."""
    logs = state.extra.get("heat")
    if logs is None:
        logs = state.extra["heat"] = heat.new_logs()
    if "cycle" not in logs:  # a state saved before multirate conduction: every step, from its step
        for key, value in heat.new_logs().items():
            logs.setdefault(key, value)
        logs["cycle"][1] = float(state.step)
    return logs


def cycle_position(state, heat) -> tuple[int, int]:
    """(k, steps of its conduction cycle ``state`` has made): the cycle's length k and
    ``(step − origin) % k`` from the state's heat logs (see
    :meth:`~thermonet.heat.setup.HeatSetup.new_logs`)."""
    cycle = heat_logs(state, heat)["cycle"]
    every = int(cycle[0])
    return every, int((state.step - int(cycle[1])) % every)
