"""Hamilton's equations (Mata & Lew 2011, (18)) of any simulation's net, for SciPy's ``solve_ivp``.

The state is y = [x_free (3k), p_free (3k), Φ (m)] (see :class:`thermonet.reference.HamiltonRHS`),
η constant. For the built-in models the right-hand side uses the NumPy laws of
:mod:`thermonet.reference` (code independent of the engine's kernels, so a reference solution
built on it checks the engine rather than repeating it); any other model goes through its own
scalar functions mapped over the springs (:func:`thermonet.kernels.springs.map_springs`).
With ``compiled=True`` the built-in models get a Numba-compiled right-hand side instead
(:mod:`thermonet.studies.compiled_rhs`): what the cost study times SciPy with.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import SimulationError
from ..kernels.springs import map_springs
from ..models import get_model
from ..reference import LAWS, HamiltonRHS, ReferenceNet
from .snapshot import Snapshot


class _MappedLaw:
    """A model's compiled scalar functions behind the NumPy-law interface of the reference
    (``temperature(l, η, l0, P)``, ``tension(l, θ, l0, P)``; P is the (k, m) parameter array)."""

    def __init__(self, model):
        self._temperature = map_springs(model, "temperature")
        self._tension = map_springs(model, "tension")

    def temperature(self, l, eta, l0, P):
        out = np.empty_like(l)
        self._temperature(l, eta, l0, P, out)
        return out

    def tension(self, l, theta, l0, P):
        out = np.empty_like(l)
        self._tension(l, theta, l0, P, out)
        return out


class _HeldAtReference:
    """A law whose springs stay at their reference temperature whatever their length: what a
    mechanical run (thermal coupling off) integrates. ``reference``: the key of θ_ref in the
    parameters (a name, or a row of the (k, m) array of a mapped law)."""

    def __init__(self, law, reference):
        self.law, self.reference = law, reference

    def temperature(self, l, eta, l0, P):
        return np.broadcast_to(np.asarray(P[self.reference], dtype=np.float64), np.shape(l)).copy()

    def tension(self, l, theta, l0, P):
        return self.law.tension(l, theta, l0, P)


class _GravityRHS(HamiltonRHS):
    """Hamilton's equations with a uniform acceleration g: ṗ = f_η(x) + m g on free nodes."""

    def __init__(self, net, x_anchor, eta, gravity):
        super().__init__(net, x_anchor, eta)
        self.weight = (net.masses[self.free][:, None] * np.asarray(gravity)[None, :]).ravel()

    def __call__(self, t, y):
        dy = super().__call__(t, y)
        dy[3 * self.k:6 * self.k] += self.weight
        return dy


def hamilton_rhs(sim, compiled: bool = False) -> tuple[HamiltonRHS, np.ndarray]:
    """The right-hand side for ``sim``'s net and model, and y(0) from its *initial* state.

    ``sim`` must not have been run (its state is the initial data). ``compiled``: for the
    built-in models, the Numba-compiled right-hand side
    (:class:`~thermonet.studies.compiled_rhs.CompiledHamiltonRHS`) instead of the NumPy one;
    other models always use their own compiled scalar functions mapped over the springs.
    """
    net, system = sim.net, sim.system
    state = sim.state
    # a mechanical run has no thermal arrays (its springs stay at θ_ref, below): η is unused and
    # Φ, which nothing reads, is integrated from zero
    zeros = np.zeros(net.n_springs)
    entropy = zeros if state.entropy is None else state.entropy
    phi = zeros if state.thermal_displacement is None else state.thermal_displacement
    # parameters back in the user's spring numbering: (k, m)
    P_user = sim.layout.springs_to_user(system.parameters.T).T
    builtin = sim.model.name in LAWS and get_model(sim.model.name) is sim.model
    if builtin:
        law = LAWS[sim.model.name]
        parameters = {name: P_user[i].copy() for i, name in enumerate(sim.model.parameters)}
    else:
        law, parameters = _MappedLaw(sim.model), np.ascontiguousarray(P_user)
    if not system.thermal:
        reference = sim.model.reference_temperature
        law = _HeldAtReference(law, reference if builtin else sim.model.parameter_index(reference))
    ref_net = ReferenceNet(np.asarray(net.edges), np.asarray(net.rest_lengths, dtype=np.float64),
                           np.asarray(net.masses, dtype=np.float64), np.asarray(net.anchored, dtype=bool),
                           law, parameters)
    if compiled and builtin:
        from .compiled_rhs import CompiledHamiltonRHS

        rhs = CompiledHamiltonRHS(ref_net, state.positions, entropy, sim.model.name, system.gravity,
                                  thermal=system.thermal)
    elif system.gravity is not None:
        rhs = _GravityRHS(ref_net, state.positions, entropy, system.gravity)
    else:
        rhs = HamiltonRHS(ref_net, state.positions, entropy)
    return rhs, rhs.pack(state.positions, state.momenta, phi)


@dataclass
class ODEResult:
    """The end state of one ``solve_ivp`` run and what it cost.

    snapshot: the state at t_end; wall_time: seconds for ``solve_ivp`` alone; nfev: right-hand
    side evaluations; t: (k,) output times and y: (len(y0), k) states when dense output was asked.
    """

    snapshot: Snapshot
    wall_time: float
    nfev: int
    t: np.ndarray | None = None
    y: np.ndarray | None = None


def solve_hamilton(sim, t_end: float, method: str = "DOP853", rtol: float = 1e-13, atol: float = 1e-13,
                   t_eval=None, compiled: bool = False) -> ODEResult:
    """Integrate Hamilton's equations of ``sim`` (not yet run) from 0 to ``t_end``; ``compiled``:
    see :func:`hamilton_rhs`."""
    from scipy.integrate import solve_ivp

    rhs, y0 = hamilton_rhs(sim, compiled)
    start = time.perf_counter()
    sol = solve_ivp(rhs, (0.0, float(t_end)), y0, method=method, rtol=rtol, atol=atol, t_eval=t_eval)
    wall = time.perf_counter() - start
    if not sol.success:
        raise SimulationError(f"solve_ivp {method} (rtol={rtol:g}) failed: {sol.message}")
    x, p, _phi = rhs.unpack(sol.y[:, -1])
    free = rhs.free
    theta = rhs.net.temperatures(x, rhs.eta)
    snap = Snapshot(positions=x[free], momenta=p[free], temperatures=theta)
    return ODEResult(snap, wall, int(sol.nfev), sol.t if t_eval is not None else None,
                     sol.y if t_eval is not None else None)
