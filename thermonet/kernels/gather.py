"""Fields from the engine's internal numbering into the user's, written straight into
caller-owned output arrays (the views of an output frame's byte image), so that a frame costs one
pass per group of fields and no temporaries.

Every function takes ``order``: (k,) int64, internal item ``i`` is user item ``order[i]``
(:class:`thermonet.layout.Layout`'s ``node_order`` / ``spring_order``), and walks the internal
arrays in memory order, scattering into user positions: after a stretch of time steps has evicted
the state from cache, sequential reads and scattered writes cost about half of the reverse
(measured at 1e5 springs, five fields: 2.2 ms against 3.9 ms for gathering by rank).

Each pass exists serial and threaded (:func:`passes`), chosen like the stepping kernels by
``Simulation.parallel`` (net size): a threaded pass waits for its slowest thread, which on a
machine loaded by other processes can be a whole scheduler time slice (measured: 8 ms per call
with two threads while another process ran, 0.1 ms with one), so small nets stay serial.

Results equal the NumPy expressions named in each docstring bit for bit (the same IEEE operations
per element). Model-independent: compiled once and cached on disk.
"""

from __future__ import annotations

from types import SimpleNamespace

import numba as nb
import numpy as np

from .specialize import rebind

_OPTIONS = dict(cache=True, nogil=True, boundscheck=False)


def node_fields_to_user(points, displacement, velocity, momentum, positions, momenta, reference, masses, order):
    """One pass over the nodes, for user node u = order[i]: points[u] = x[i], displacement[u] =
    x[i] − X[u], velocity[u] = p[i] / m[u], momentum[u] = p[i]. Outputs: (n, 3), or (0, 3) for a
    field not wanted. positions, momenta: (n, 3) internal; reference: (n, 3) and masses: (n,)
    user numbering."""
    with_displacement = displacement.shape[0] > 0
    with_velocity = velocity.shape[0] > 0
    with_momentum = momentum.shape[0] > 0
    for i in nb.prange(order.shape[0]):
        u = order[i]
        for c in range(3):
            x = positions[i, c]
            points[u, c] = x
            if with_displacement:
                displacement[u, c] = x - reference[u, c]
        if with_velocity or with_momentum:
            d = masses[u]
            for c in range(3):
                p = momenta[i, c]
                if with_velocity:
                    velocity[u, c] = p / d
                if with_momentum:
                    momentum[u, c] = p


def node_means_to_user(out, spring_values, inc_ptr, inc_spring, order):
    """out[order[i]] = mean of spring_values over the springs meeting at internal node i (0 where
    none). spring_values: (m,) internal numbering; inc_ptr, inc_spring: the layout's incidence
    lists, whose neighbouring nodes' springs sit close in memory. The sum runs in incidence order,
    so it can differ from a sum in another order by round-off."""
    for i in nb.prange(order.shape[0]):
        start, stop = inc_ptr[i], inc_ptr[i + 1]
        total = 0.0
        for k in range(start, stop):
            total += spring_values[inc_spring[k]]
        out[order[i]] = total / max(stop - start, 1)


_PASSES = (node_fields_to_user, node_means_to_user)
_COMPILED: dict = {}


def passes(parallel: bool) -> SimpleNamespace:
    """The compiled passes, serial or threaded (the threaded ones write disjoint rows: ``order``
    is a permutation)."""
    key = bool(parallel)
    if key not in _COMPILED:
        tag = "par" if parallel else "ser"  # distinct names: distinct disk-cache entries
        _COMPILED[key] = SimpleNamespace(**{
            f.__name__: nb.njit(parallel=key, **_OPTIONS)(rebind(f, tag, {})) for f in _PASSES})
    return _COMPILED[key]


def as_index(order: np.ndarray) -> np.ndarray:
    """An order array in the index type the passes are compiled for (int64, contiguous)."""
    return np.ascontiguousarray(order, dtype=np.int64)
