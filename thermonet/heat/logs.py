"""The heat-flow columns of a diagnostics row, from the logs the kernels keep in the state.

- ``entropy_produced``: Σ of every exchange's entropy production (pairs and bath ends), since
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


def heat_columns(heat, state) -> dict:
    """The logged columns of ``state`` (see the module docstring; the balances are added by
    :func:`balances`)."""
    logs = state.extra["heat"]
    per_name = np.zeros(len(heat.names))
    np.add.at(per_name, heat.entry_fn, logs["entry_heat"])
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
