"""A Simulation's input, checked and built: every user argument checked with an error naming the
node, spring or key, and the internal :class:`~thermonet.system.System` and initial
:class:`~thermonet.state.State` built from it."""

from __future__ import annotations

import math

import numpy as np

from .errors import InputError
from .explicit.cuda import require_cuda
from .integrators import explicit_integrators
from .kernels.springs import map_springs
from .net import Net
from .run_guards import GUARD_MODES
from .state import State
from .system import System


def check_backend(backend, integrator) -> str:
    name = str(backend).lower()
    if name not in ("cpu", "cuda"):
        raise InputError(f"unknown backend {backend!r}; known: cpu, cuda")
    if name == "cuda":
        if not integrator.explicit:
            raise InputError(f"integrator {integrator.name!r} is implicit; backend 'cuda' runs only the explicit "
                             f"integrators ({', '.join(explicit_integrators())})")
        require_cuda()
    return name


def check_stretch_bounds(bounds) -> tuple[float, float]:
    try:
        lo, hi = (float(b) for b in bounds)
    except (TypeError, ValueError):
        raise InputError(f"stretch_bounds must be two numbers (lo, hi), got {bounds!r}") from None
    if not (0 <= lo < 1 < hi):
        raise InputError(f"stretch_bounds must satisfy 0 <= lo < 1 < hi, got ({lo}, {hi})")
    return lo, hi


def check_step(h) -> float:
    if isinstance(h, (str, bytes, bool)):  # float("0.01") would take it: a quoted number is a mistake
        raise InputError(f"time step h must be a number, got {type(h).__name__} {h!r}")
    try:
        h = float(h)
    except (TypeError, ValueError):
        raise InputError(f"time step h must be a number, got {h!r}") from None
    if not (math.isfinite(h) and h > 0):
        raise InputError(f"time step h must be finite and > 0, got {h}")
    return h


def build_system(net: Net, model, layout, P_user, gravity, thermal: bool, stretch_bounds, heat=None,
                 loads=None) -> System:
    """The :class:`System` of a net in the internal numbering of ``layout``: rest lengths,
    parameters (P_user: (k, m), user numbering), masses, anchors, the reference point of
    angular momentum, gravity (checked: a finite 3-vector or None), thermal coupling and the
    admissible stretches (checked), the heat flow (a checked HeatSetup or None) and the loads (a resolved
    :class:`~thermonet.loads.arrays.LoadSet` or None)."""
    gravity_vec = None
    if gravity is not None:
        gravity_vec = np.asarray(gravity, dtype=np.float64).reshape(-1)
        if gravity_vec.shape != (3,) or not np.isfinite(gravity_vec).all():
            raise InputError(f"gravity must be a finite 3-vector, got {gravity!r}")
    ref = net.anchor_point()
    masses = layout.nodes_to_internal(net.masses)
    anchored = layout.nodes_to_internal(net.anchored)
    if loads is not None:  # loads: nodes driven in every axis are not free
        anchored = anchored | layout.nodes_to_internal(loads.fully_driven)
    return System(
        model=model,
        layout=layout,
        rest_lengths=np.ascontiguousarray(layout.springs_to_internal(net.rest_lengths)),
        parameters=np.ascontiguousarray(P_user[:, layout.spring_order]),
        masses=np.ascontiguousarray(masses),
        inv_mass=np.where(anchored, 0.0, 1.0 / masses),
        anchored=np.ascontiguousarray(anchored),
        reference_point=np.zeros(3) if ref is None else ref,
        gravity=gravity_vec,
        thermal=bool(thermal),
        stretch_bounds=check_stretch_bounds(stretch_bounds),
        heat=heat,
        loads=loads,
    )


def initial_state(net: Net, model, layout, P_user, thermal: bool, temperatures, momenta, velocities) -> State:
    """The :class:`State` at step 0 in the internal numbering of ``layout``, from the user's
    initial temperatures and momenta or velocities (checked)."""
    m = net.n_springs
    x0 = layout.nodes_to_internal(net.positions).copy()
    p0 = initial_momenta(net, momenta, velocities)
    phi, eta = None, None
    if thermal:
        eta = np.ascontiguousarray(layout.springs_to_internal(initial_entropies(net, model, temperatures, P_user)))
        phi = np.zeros(m)
    elif temperatures is not None:
        raise InputError("initial temperatures given but thermal coupling is off (thermal=False)")
    return State(
        positions=np.ascontiguousarray(x0),
        momenta=np.ascontiguousarray(layout.nodes_to_internal(p0)),
        thermal_displacement=phi,
        entropy=eta,
    )


def angular_momentum_reference(net: Net) -> str:
    """What angular momentum is measured about, in words."""
    ref = net.anchor_point()
    if ref is not None and net.anchored.any():
        return "anchor point"
    return "origin" if ref is not None else "origin (anchors do not coincide: angular momentum is not conserved)"


def guard_mode(mode) -> str:
    """The stable-step guard's mode: "stop" (True), "warn" or "off" (False, None)."""
    if mode is True:
        return "stop"
    if mode is False or mode is None:
        return "off"
    if str(mode).lower() not in GUARD_MODES:
        raise InputError(f"stability_guard must be one of {', '.join(GUARD_MODES)} (or True/False), got {mode!r}")
    return str(mode).lower()


def check_energy_tolerance(energy_tolerance) -> float | None:
    if energy_tolerance is not None and not (float(energy_tolerance) > 0):
        raise InputError(f"energy_tolerance must be > 0 (relative), got {energy_tolerance}")
    return None if energy_tolerance is None else float(energy_tolerance)


def initial_momenta(net, momenta, velocities) -> np.ndarray:
    """(n, 3) initial momenta (user numbering) from momenta or velocities: (n, 3), (n, 2) or one
    (3,) vector for every free node; checked (finite, zero on anchors)."""
    n = net.n_nodes
    if momenta is not None and velocities is not None:
        raise InputError("give either momenta or velocities, not both")
    if momenta is None and velocities is None:
        return np.zeros((n, 3))
    given = momenta if momenta is not None else velocities
    what = "momenta" if momenta is not None else "velocities"
    arr = np.asarray(given, dtype=np.float64)
    if arr.shape == (3,):
        arr = np.broadcast_to(arr, (n, 3)).copy()
        arr[net.anchored] = 0.0
    if arr.shape == (n, 2):
        arr = np.column_stack([arr, np.zeros(n)])
    if arr.shape != (n, 3):
        raise InputError(f"initial {what} must have shape ({n}, 3), got {arr.shape}")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        a = int(np.flatnonzero(bad)[0])
        raise InputError(f"node {a}: initial {what[:-1] if what == 'momenta' else 'velocity'} is not finite: {arr[a].tolist()}")
    moving = net.anchored & (np.abs(arr).sum(axis=1) > 0)
    if moving.any():
        a = int(np.flatnonzero(moving)[0])
        raise InputError(f"node {a} is anchored but has initial {what} {arr[a].tolist()}")
    if velocities is not None:
        with np.errstate(over="ignore"):
            momenta = arr * net.masses[:, None]
        bad = ~np.isfinite(momenta).all(axis=1)
        if bad.any():
            a = int(np.flatnonzero(bad)[0])
            raise InputError(f"node {a}: initial momentum m v overflows (velocity {arr[a].tolist()}, mass "
                             f"{net.masses[a]:g})")
        arr = momenta
    return arr


def initial_temperatures(net, model, temperatures, P_user) -> np.ndarray:
    """(m,) initial θ per spring (user numbering): a scalar, one per spring, or None (each
    spring's reference temperature); checked finite and > 0."""
    m = net.n_springs
    if temperatures is None:
        return P_user[model.parameter_index(model.reference_temperature)].copy()
    theta = np.asarray(temperatures, dtype=np.float64)
    if theta.ndim == 0:
        theta = np.full(m, float(theta))
    if theta.shape != (m,):
        raise InputError(f"initial temperatures must be a scalar or one per spring ({m}), got shape {theta.shape}")
    bad = ~(np.isfinite(theta) & (theta > 0))
    if bad.any():
        e = int(np.flatnonzero(bad)[0])
        raise InputError(f"spring {e}: initial temperature must be finite and > 0, got {theta[e]}")
    return theta


def initial_entropies(net, model, temperatures, P_user) -> np.ndarray:
    """(m,) η = Γ(l(0), θ(0)) per spring (user numbering); P_user: (k, m) parameters."""
    theta0 = initial_temperatures(net, model, temperatures, P_user)
    lengths = net.lengths()
    eta = np.empty(net.n_springs)
    map_springs(model, "entropy")(lengths, theta0, net.rest_lengths, P_user, eta)
    bad = ~np.isfinite(eta)
    if bad.any():
        e = int(np.flatnonzero(bad)[0])
        raise InputError(f"spring {e}: initial entropy is not finite (θ = {theta0[e]}, l = {lengths[e]})")
    return eta
