"""Guards a simulation applies while it runs, at the diagnostics cadence, and the verdict on a
finished run's conservation.

- :class:`StabilityGuard`: the explicit integrators' stable step ``h_max = c / ω_max``
  (:mod:`thermonet.stability`) re-estimated from the current adiabatic stiffnesses. A cheap
  rigorous bound first, one pass over the springs (:func:`frequency_bound`):

      ω_max² ≤ 2 max_a Σ_{e ∋ a} κ_e / m_a,   κ_e = max(dT/dl|η, T/l, 0)

  (κ_e the largest eigenvalue of spring e's 3×3 stiffness block; the Rayleigh quotient of
  Σ_e κ_e |u_b − u_a|² with |u_b − u_a|² ≤ 2(|u_a|² + |u_b|²)). Only when this bound, scaled by
  how pessimistic it was at the last accurate estimate, says h may be above ``SAFETY · h_max``
  is ω_max estimated accurately (:func:`thermonet.stability.max_frequency`: dense eigenvalues or
  Lanczos). Then the step policy's thresholds (:mod:`thermonet.step_policy`) apply: a
  :class:`~thermonet.step_policy.StepWarning` once above ``SAFETY``, and above ``REFUSE`` a stop
  (:class:`StabilityLimitExceeded`) unless the guard only warns. Stops are skipped where needed
  to keep the guard's time below :data:`GUARD_TIME_BUDGET` of the run's.
- :func:`energy_departure`: the energy guard, |H − H(0)| against ``tolerance · |H(0)|``.
- :func:`broken_conservation`: what a finished run failed to conserve beyond the tolerances
  (energy beyond the energy guard's default, entropy beyond :data:`ENTROPY_TOLERANCE`).
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np

from .compile_watch import CompileWatch
from .errors import SimulationError
from .kernels.specialize import model_fingerprint, model_namespace, specialize
from .stability import max_frequency, stability_interval, wave_frequency
from .step_policy import REFUSE, SAFETY, StepWarning

#: default energy guard: a run stops when |H − H(0)| exceeds this fraction of |H(0)|
DEFAULT_ENERGY_TOLERANCE = 0.1
#: relative entropy change a finished run may show (the integrators conserve it exactly, or to
#: their Newton tolerance)
ENTROPY_TOLERANCE = 1e-6

GUARD_MODES = ("stop", "warn", "off")
#: the stable-step guard skips diagnostics stops where needed so that its time stays below this
#: fraction of the time the simulation has spent running (a bound costs about two explicit steps
#: of a large net; on small nets, whose steps are cheap next to a stop's fixed costs, every stop
#: is checked). Running time, not time since its first check: a program that runs a simulation
#: in short calls between other work would otherwise give it a budget of that work's time too.
GUARD_TIME_BUDGET = 0.05
#: seconds the guard may spend beyond that budget (its first checks, an accurate estimate)
GUARD_TIME_ALLOWANCE = 0.1


class StabilityLimitExceeded(SimulationError):
    """The time step went far above the stability limit re-estimated while running."""


# ----------------------------------------------------------------------------------------------
# the cheap bound: one compiled pass over the springs, per model

temperature = tension = d2F_dl2 = d2F_dl_dtheta = d2F_dtheta2 = None  # bound per model
THERMAL = True
REFERENCE_TEMPERATURE = 0


def _node_stiffness_sums(x, eta, l0, P, edges, inv_mass, sums):
    """sums (n,) ← Σ_{e ∋ a} κ_e / m_a (0 at anchored nodes, inv_mass = 0 there); returns
    2 max_a sums[a], an upper bound on ω_max², or inf where a stiffness is not a number.
    x: (n, 3) positions; eta: (m,) entropies (unused without thermal coupling); l0: (m,);
    P: (k, m) parameters; edges: (m, 2)."""
    for a in range(sums.shape[0]):
        sums[a] = 0.0
    for e in range(edges.shape[0]):
        a, b = edges[e, 0], edges[e, 1]
        d0 = x[b, 0] - x[a, 0]
        d1 = x[b, 1] - x[a, 1]
        d2 = x[b, 2] - x[a, 2]
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if THERMAL:
            th = temperature(length, eta[e], l0[e], P, e)
        else:
            th = P[REFERENCE_TEMPERATURE, e]
        axial = d2F_dl2(length, th, l0[e], P, e)
        if THERMAL:
            f_lt = d2F_dl_dtheta(length, th, l0[e], P, e)
            axial -= f_lt * f_lt / d2F_dtheta2(length, th, l0[e], P, e)
        geometric = tension(length, th, l0[e], P, e) / length
        if not (math.isfinite(axial) and math.isfinite(geometric)):
            return math.inf
        kappa = max(axial, geometric, 0.0)
        sums[a] += kappa * inv_mass[a]
        sums[b] += kappa * inv_mass[b]
    top = 0.0
    for a in range(sums.shape[0]):
        top = max(top, sums[a])
    return 2.0 * top


_KERNELS: dict = {}


def _bound_kernel(model, thermal: bool):
    key = (model_fingerprint(model), bool(thermal))
    if key not in _KERNELS:
        ns = model_namespace(model)
        ns["THERMAL"] = bool(thermal)
        ns["REFERENCE_TEMPERATURE"] = model.parameter_index(model.reference_temperature)
        tag = f"{model.name}_{key[0]}_{'thermal' if thermal else 'mech'}"
        _KERNELS[key] = specialize(_node_stiffness_sums, tag, ns, cache=True, error_model="numpy")
    return _KERNELS[key]


def frequency_bound(system, positions: np.ndarray, entropy: np.ndarray | None) -> float:
    """An upper bound on ω_max of ``system`` linearized at ``positions`` (n, 3) and ``entropy``
    (m,) or None, internal numbering: sqrt(2 max_a Σ_{e∋a} κ_e / m_a) (module doc); inf where a
    stiffness is not finite. One pass over the springs."""
    kernel = _bound_kernel(system.model, system.thermal)
    sums = np.empty(system.n_nodes)
    eta = entropy if system.thermal else np.empty(0)
    with np.errstate(all="ignore"):
        lam = kernel(positions, eta, system.rest_lengths, system.parameters, system.edges, system.inv_mass, sums)
    return math.sqrt(lam) if lam >= 0 else math.inf


# ----------------------------------------------------------------------------------------------


class StabilityGuard:
    """The stable step re-estimated while a simulation runs (module doc).

    mode: "stop" (warn above ``SAFETY · h_max``, stop above ``REFUSE · h_max``), "warn" (only
    warn) or "off". Inactive for integrators without a known stability interval and on the GPU
    backend (its state lives on the device).
    """

    def __init__(self, sim, mode: str = "stop"):
        self.mode = mode
        self.interval = stability_interval(sim.integrator)
        self.active = mode != "off" and math.isfinite(self.interval) and sim.backend == "cpu"
        #: ω_max(accurate) / bound at the last accurate estimate (≤ 1): how pessimistic the bound is
        self.scale = 1.0
        self.warned = False
        #: the last verdict: (step, h / h_max) of the last accurate estimate, or None
        self.last = None
        #: stops checked and skipped (to keep within :data:`GUARD_TIME_BUDGET`); seconds spent
        self.checked = self.skipped = 0
        self.seconds = 0.0

    def check(self, sim) -> None:
        """Estimate the limit at ``sim``'s current state, unless this stop is skipped to keep
        the guard within :data:`GUARD_TIME_BUDGET` of the simulation's running time, plus
        :data:`GUARD_TIME_ALLOWANCE`; warn or raise :class:`StabilityLimitExceeded`."""
        if not self.active:
            return
        now = time.perf_counter()
        skip = self.seconds > GUARD_TIME_BUDGET * sim.runner.seconds_running() + GUARD_TIME_ALLOWANCE
        comm = getattr(sim, "comm", None)
        if comm is not None:  # over MPI processes: rank 0's clock decides for all (the check reads
            skip = comm.bcast(skip, root=0)  # the state, which the processes put together jointly)
        if skip:
            self.skipped += 1
            return
        self.checked += 1
        with CompileWatch() as compiling:  # a first run's compilation is not the guard's running cost
            try:
                sim.on_root(lambda: self._check(sim))  # (over MPI processes: by rank 0, on the whole state)
            finally:
                self.seconds += time.perf_counter() - now - compiling.seconds

    def _check(self, sim) -> None:
        state = sim.internal_state()
        h = sim.h
        waves = sim.system.heat is not None and sim.system.heat.waves
        bound = frequency_bound(sim.system, state.positions, state.entropy)
        wave_bound = wave_frequency(sim, bound_only=True) if waves else 0.0
        if math.isfinite(bound) and h * max(bound * self.scale, wave_bound) <= SAFETY * self.interval:
            return
        est = max_frequency(sim.system, state.positions, state.entropy)
        omega_w = wave_frequency(sim) if waves else 0.0
        omega = max(est.omega_max, omega_w)
        if math.isfinite(bound) and bound > 0 and math.isfinite(omega):
            self.scale = min(1.0, omega / bound)
        h_max = self.interval / omega if omega > 0 else math.inf
        ratio = h / h_max if h_max > 0 else math.inf
        self.last = (sim.step, ratio)
        if ratio <= SAFETY:
            return
        where = (f"at step {sim.step} (t = {sim.time:.6g}) the stability limit of {sim.integrator.name} is "
                 f"h_max ≈ {h_max:.4g} (ω_max ≈ {omega:.4g}, "
                 + (f"the thermal waves' (mechanical {est.omega_max:.4g}), " if omega_w > est.omega_max else "")
                 + f"{est.method}, re-estimated from the current stiffnesses)")
        if ratio > REFUSE and self.mode == "stop":
            raise StabilityLimitExceeded(
                f"{where}, and h = {h:g} is {ratio:.3g}× it: the run is no longer stable")
        if not self.warned:
            self.warned = True
            warnings.warn(f"{where}; h = {h:g} is {ratio:.2f}× it, the run may blow up", StepWarning, stacklevel=2)


def energy_departure(rows: list, tolerance: float | None) -> float | None:
    """The relative departure |H − H(0)|/|H(0)| of the last diagnostics row (with heat flow,
    or loads, of its energy balance |H − H(0) − W − ΣQ|/|H(0)|) when it exceeds ``tolerance`` (None: no
    guard), else None."""
    if tolerance is None or len(rows) < 2:
        return None
    e0, e = rows[0]["energy"], rows[-1]["energy"]
    scale = abs(e0)
    last = rows[-1]
    if "energy_balance" in last:  # heat or work moves energy in or out: the balance is what must
        scale = max(scale, abs(e - e0))  # hold, against the energy that moved as well as H(0)
        if "heat_in" in last:
            scale = max(scale, abs(last["heat_in"] - rows[0]["heat_in"]))
        if "work" in last:
            scale = max(scale, abs(last["work"]))
        e = e0 + last["energy_balance"]
    if abs(e - e0) <= tolerance * max(scale, np.finfo(float).tiny):
        return None
    return abs(e - e0) / max(scale, 1e-300)


def broken_conservation(sim, energy_tolerance: float | None = None) -> list[str]:
    """What a finished run failed to conserve, one phrase each (empty when all is well): energy
    beyond ``energy_tolerance`` (default :data:`DEFAULT_ENERGY_TOLERANCE`) relative to |H(0)|,
    entropy (thermal runs) beyond :data:`ENTROPY_TOLERANCE` relative."""
    summary = sim.diagnostics.summary()
    tol = DEFAULT_ENERGY_TOLERANCE if energy_tolerance is None else energy_tolerance
    out = []
    checks = [("energy", tol)] + ([("entropy", ENTROPY_TOLERANCE)] if "entropy" in summary else [])
    if "energy_balance" in summary:  # heat flow, loads: energy changes, its balance holds
        checks[0] = ("energy_balance", tol)
    if "entropy_balance" in summary:  # heat flow: entropy changes, its balance holds
        checks[1:] = [("entropy_balance", ENTROPY_TOLERANCE)]
    for name, limit in checks:
        s = summary.get(name)
        if s is None:
            continue
        rel = s["relative"]
        if not (rel <= limit):
            out.append(f"{name} departed from its initial value by {rel:.3g} (relative; at most {limit:g} expected)")
    return out
