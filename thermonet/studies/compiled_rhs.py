"""Hamilton's equations (Mata & Lew 2011, (18)) compiled with Numba, for SciPy's ``solve_ivp``: the baseline a
performance-aware user would write, for the built-in models ("hencky", "quadratic").

Same state vector and interface as :class:`thermonet.reference.HamiltonRHS` (which it subclasses:
``pack``/``unpack`` are shared), y = [x_free (3k), p_free (3k), Φ (m)], η constant:

    ẋ_a = p_a / m_a,   ṗ_a = Σ_e ±T_e n_e (+ m_a g),   Φ̇_e = θ(l_e, η_e)

One compiled loop over the springs (tension and temperature from the model's closed forms, the
paper's (31) and (26), scatter into the free nodes' force) and one over the free nodes, writing into a
preallocated output; no NumPy temporaries per call. It shares no code with the engine's kernels
nor with the NumPy reference (a test checks it against the latter to round-off).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..reference import HamiltonRHS, ReferenceNet

#: model name -> the integer the compiled loop switches on, and its parameters in order
MODELS = {"hencky": (0, ("c", "beta", "C0", "theta0")), "quadratic": (1, ("E", "beta", "C0", "theta0", "eta0"))}


@njit(cache=True, fastmath=False)
def hamilton_derivative(y, dy, model, thermal, edges, l0, P, eta, slot, x_anchor, inv_mass, weight, k):
    """dy ← ẏ at y (both (6k + m,)).

    model: 0 hencky, 1 quadratic; thermal: False for a mechanical run (every spring at θ0, row 3
    of P, whatever its length); edges: (m, 2) node indices; l0, eta: (m,); P: (n_params, m)
    parameters in :data:`MODELS` order; slot: (n,) index of each node among the free ones, −1 if
    anchored; x_anchor: (n, 3) positions used for anchored nodes; inv_mass: (k,) of the free
    nodes; weight: (3k,) m g of the free nodes (zeros without gravity).
    """
    k3 = 3 * k
    m = edges.shape[0]
    for i in range(k3):
        dy[k3 + i] = weight[i]
    for e in range(m):
        a = edges[e, 0]
        b = edges[e, 1]
        sa = slot[a]
        sb = slot[b]
        d0 = (y[3 * sb] if sb >= 0 else x_anchor[b, 0]) - (y[3 * sa] if sa >= 0 else x_anchor[a, 0])
        d1 = (y[3 * sb + 1] if sb >= 0 else x_anchor[b, 1]) - (y[3 * sa + 1] if sa >= 0 else x_anchor[a, 1])
        d2 = (y[3 * sb + 2] if sb >= 0 else x_anchor[b, 2]) - (y[3 * sa + 2] if sa >= 0 else x_anchor[a, 2])
        l = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if model == 0:  # hencky: L = ln(l/l0), θ = θ0 exp((η − βL)/C0), T = (cL − β(θ − θ0))/l
            L = math.log(l / l0[e])
            theta = P[3, e] * math.exp((eta[e] - P[1, e] * L) / P[2, e]) if thermal else P[3, e]
            tension = (P[0, e] * L - P[1, e] * (theta - P[3, e])) / l
        else:  # quadratic: d = l − l0, θ = θ0 + θ0/C0 (η − η0 − βd), T = E/l0 d − β(θ − θ0)
            dl = l - l0[e]
            theta = P[3, e] + P[3, e] / P[2, e] * (eta[e] - P[4, e] - P[1, e] * dl) if thermal else P[3, e]
            tension = P[0, e] / l0[e] * dl - P[1, e] * (theta - P[3, e])
        dy[2 * k3 + e] = theta
        s = tension / l
        if sa >= 0:
            dy[k3 + 3 * sa] += s * d0
            dy[k3 + 3 * sa + 1] += s * d1
            dy[k3 + 3 * sa + 2] += s * d2
        if sb >= 0:
            dy[k3 + 3 * sb] -= s * d0
            dy[k3 + 3 * sb + 1] -= s * d1
            dy[k3 + 3 * sb + 2] -= s * d2
    for j in range(k):
        for c in range(3):
            dy[3 * j + c] = y[k3 + 3 * j + c] * inv_mass[j]


class CompiledHamiltonRHS(HamiltonRHS):
    """:class:`~thermonet.reference.HamiltonRHS` with its ``__call__`` compiled (see the module).

    net: a :class:`~thermonet.reference.ReferenceNet` whose law is one of the built-in models;
    x_anchor: (n, 3); eta: (m,); gravity: (3,) or None; thermal: False for a mechanical run.
    """

    def __init__(self, net: ReferenceNet, x_anchor, eta, model: str, gravity=None, thermal: bool = True):
        super().__init__(net, x_anchor, eta)
        self._thermal = bool(thermal)
        if model not in MODELS:
            raise ValueError(f"no compiled right-hand side for model {model!r} (built-in: {', '.join(MODELS)})")
        self._model, names = MODELS[model]
        self._P = np.ascontiguousarray(np.array([net.parameters[n] for n in names], dtype=np.float64))
        self._edges = np.ascontiguousarray(net.edges, dtype=np.int64)
        self._l0 = np.ascontiguousarray(net.rest_lengths, dtype=np.float64)
        slot = np.full(len(net.masses), -1, dtype=np.int64)
        slot[self.free] = np.arange(self.k)
        self._slot = slot
        g = np.zeros(3) if gravity is None else np.asarray(gravity, dtype=np.float64)
        self._weight = np.ascontiguousarray((net.masses[self.free][:, None] * g[None, :]).ravel())
        self._inv_mass = np.ascontiguousarray(self.inv_mass, dtype=np.float64)

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        dy = np.empty_like(y)
        hamilton_derivative(np.ascontiguousarray(y, dtype=np.float64), dy, self._model, self._thermal, self._edges,
                            self._l0, self._P, self.eta, self._slot, self.x_full, self._inv_mass, self._weight, self.k)
        return dy
