"""The heat-flow logs the kernels keep in the state (:func:`heat_logs`, :func:`cycle_of`) and the
heat-flow columns of a diagnostics row computed from them.

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

from ..kernels import exact

#: heat-flow logs with one value per spring (stored in the user's numbering outside the engine)
PER_SPRING_LOGS = ("produced", "theta", "length", "pending_eta", "pending_produced", "pending_theta")
#: heat-flow logs with one value per bath or source entry (the same in every numbering)
ENTRY_LOGS = ("entry_heat", "entry_flux")


def heat_columns(heat, state) -> dict:
    """The logged columns of ``state`` (see the module docstring; the balances are added by
    :func:`balances`), each sum correctly rounded (:func:`heat_sums`)."""
    logs = state.extra["heat"]
    return heat_columns_of(heat, heat_sums(logs["produced"], logs["entry_heat"], logs["entry_flux"],
                                           heat.entry_fn, len(heat.names)))


def heat_sums(produced: np.ndarray, entry_heat: np.ndarray, entry_flux: np.ndarray, entry_fn: np.ndarray,
              n_names: int) -> np.ndarray:
    """(3 + n_names, WIDTH) int64 exact accumulators (:mod:`thermonet.kernels.exact`) of the
    heat-flow sums of a row: Σ produced (k,), Σ entry_flux, Σ entry_heat (E,), then Σ entry_heat
    of the entries of each bath or source (``entry_fn`` (E,): their numbers). Exact: the
    accumulators of parts of the logs (a process's springs and entries) add up to the whole's.
    One compiled call (a row of a small net is otherwise mostly calls)."""
    acc = np.zeros((3 + n_names, exact.WIDTH), dtype=np.int64)
    _sums_kernel()(acc, np.ascontiguousarray(produced, dtype=np.float64),
                   np.ascontiguousarray(entry_heat, dtype=np.float64),
                   np.ascontiguousarray(entry_flux, dtype=np.float64), np.ascontiguousarray(entry_fn, dtype=np.int64))
    return acc


def _heat_sums(acc, produced, entry_heat, entry_flux, entry_fn):
    """:func:`heat_sums` into the zeroed acc (3 + names, WIDTH)."""
    rest = np.empty(exact.BLOCK)
    for row, values in ((0, produced), (1, entry_flux), (2, entry_heat)):
        k = values.shape[0]
        for lo in range(0, k, exact.BLOCK):
            exact.add_terms(acc[row], values[lo:], min(exact.BLOCK, k - lo), rest)
    bits = entry_heat.view(np.uint64)
    for j in range(entry_heat.shape[0]):  # (each to its bath's or source's accumulator)
        exact.add_bits(acc[3 + entry_fn[j]], bits[j])
    for row in range(acc.shape[0]):
        exact.normalize(acc[row])


_SUMS = []


def _sums_kernel():
    """:func:`_heat_sums` compiled, its cache name carrying the exact sums' digest
    (:func:`thermonet.kernels.reductions.rows_digest`: it inlines them, and Numba's disk cache
    watches this file only)."""
    if not _SUMS:
        from ..kernels.reductions import rows_digest
        from ..kernels.specialize import specialize

        _SUMS.append(specialize(_heat_sums, f"x{rows_digest()}", {"exact": exact, "np": np}, cache=True,
                                error_model="numpy", boundscheck=False))
    return _SUMS[0]


def heat_columns_of(heat, acc: np.ndarray) -> dict:
    """The logged columns from the accumulators of :func:`heat_sums` (of the whole net: added
    over the processes' shares where there are several)."""
    v = exact.values(acc).tolist()
    row = {"entropy_produced": v[0]}
    for i, name in enumerate(heat.names):
        row[f"heat_{name}"] = v[3 + i]
    row["heat_in"] = v[2]
    row["entropy_in"] = v[1]
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


def cycle_of(state, heat) -> tuple[int, int, int]:
    """(k, steps of its conduction cycle ``state`` has made, j) from the state's heat logs (see
    :meth:`~thermonet.heat.setup.HeatSetup.new_logs`): the cycle's length k, ``(step − origin) %
    k``, and the half sweeps j of each half of its boundaries (sub-sweeps:
    :mod:`thermonet.heat.multirate`)."""
    k, origin, sweeps = heat_logs(state, heat)["cycle"].tolist()
    k = int(k)
    return k, int((state.step - int(origin)) % k), int(sweeps)
