"""The transport parameters of springs: what heat flow needs besides the model's free energy.

``g``: each spring's conductance between its middle and each of its ends (power per kelvin,
docs/theory.md §5.1); ``g_star``: the Green–Naghdi type II constant (§6). Both are given like model
parameters (a scalar or one value per spring, in the API's ``parameters`` and in a scene's
material regions) and are ≥ 0.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..errors import InputError

#: parameter names that belong to heat flow, not to the model
TRANSPORT_PARAMETERS = ("g", "g_star")

DESCRIPTIONS = {
    "g": "conductance from a spring's middle to each end (Fourier conduction; power per kelvin)",
    "g_star": "Green–Naghdi type II constant from a spring's middle to each end (thermal waves)",
}


def split_parameters(parameters: Mapping | None) -> tuple[dict, dict]:
    """(model parameters, transport parameters) of a user's ``parameters`` mapping."""
    parameters = dict(parameters or {})
    transport = {k: parameters.pop(k) for k in TRANSPORT_PARAMETERS if k in parameters}
    return parameters, transport


def transport_array(name: str, value, n_springs: int) -> np.ndarray:
    """(m,) values of transport parameter ``name`` (user spring numbering), checked: finite and
    ≥ 0, errors naming the parameter and the first offending spring."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"parameter {name!r} is not a number: {value!r}") from None
    if arr.ndim == 0:
        arr = np.full(n_springs, float(arr))
    elif arr.shape != (n_springs,):
        raise InputError(f"parameter {name!r} must be a scalar or one value per spring ({n_springs}), "
                         f"got shape {arr.shape}")
    bad = ~np.isfinite(arr) | (arr < 0.0)
    if bad.any():
        e = int(np.flatnonzero(bad)[0])
        raise InputError(f"parameter {name!r} of spring {e} must be finite and ≥ 0, got {arr[e]}")
    return np.ascontiguousarray(arr)
