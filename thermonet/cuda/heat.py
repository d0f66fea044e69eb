"""Heat flow on the GPU: the conduction and thermal-wave rows of the explicit schedule
(spec-heat §1–2), built from the CPU's per-element functions (:mod:`thermonet.kernels.heat_flow`).

A heat row is a sequence of *phases*, each a parallel pass whose elements share no spring:

- conduction forward (code −2): the boundary entries (baths, sources: one thread per boundary
  spring), then the pair colours in order; in reverse (−3): the colours backwards, then the
  boundary entries (each spring's entries in reverse);
- thermal waves (−4): the pair colours in order.

:func:`_sweep_phase` runs one phase over a grid-stride loop: the two-launch path launches
:func:`_sweep_kernel` once per phase (one thread per element), the fused kernel calls it between
grid-wide barriers. A conduction sweep works on the springs' temperatures in the device copy of
the ``theta`` log (``heat.theta``), valid when ``theta_ok`` says so, as the CPU's ``theta_keep``:
after a sweep, and across calls. Where the CPU reuses the θ its spring pass computed (a stage
without drift), the GPU recomputes it with a temperature pass (:func:`_temperature_update`, the
same function of the same l and η, so the same bits) instead of writing θ from the spring update.

:class:`DeviceHeat` keeps the heat record and its logs on the device for the stepper.
"""

from __future__ import annotations

import hashlib
import inspect
import math
import sys

import numpy as np
from numba import cuda

from ..errors import InputError
from ..integrators.schedule import CONDUCTION_REVERSE, THERMAL_WAVES, BuiltinFlow
from ..kernels import heat_flow
from ..kernels.heat_passes import bind_heat_flow
from ..kernels.records import Heat, no_heat
from ..kernels.specialize import rebind
from . import FLAG_SET

# Bound per kernel variant by bind_device_heat() (see thermonet.kernels.heat_flow).
pair_exchange = boundary_exchange = wave_exchange = spring_temperature = squared_length = None
phase_span = sweep_phase = temperature_update = None
CONDUCTION = False
WAVES = False
UNIFORM = False

LOGS = ("produced", "entry_heat", "entry_flux", "theta", "theta_ok")


def _phase_span(code, phase, colour_ptr, n_bound):
    """(boundary, lo, hi): phase ``phase`` of heat row ``code`` runs the boundary springs
    lo:hi (boundary True) or the pairs lo:hi of one colour."""
    n_colours = colour_ptr.shape[0] - 1
    if code == THERMAL_WAVES:
        colour = phase
    else:
        reverse = code == CONDUCTION_REVERSE
        if phase == (n_colours if reverse else 0):
            return True, 0, n_bound
        colour = n_colours - 1 - phase if reverse else phase - 1
    return False, colour_ptr[colour], colour_ptr[colour + 1]


def _sweep_phase(code, phase, heat, tau, t, phi, eta, first, stride):
    """The elements first, first + stride, ... of phase ``phase`` of heat row ``code`` over τ at
    time t (conduction on heat.theta; see the module docstring). phi, eta: (m,)."""
    boundary, lo, hi = phase_span(code, phase, heat.colour_ptr, heat.bound_spring.shape[0])
    if WAVES and code == THERMAL_WAVES:
        for k in range(lo + first, hi, stride):
            wave_exchange(k, heat.first, heat.second, heat.wave, tau, phi, eta)
    elif CONDUCTION and boundary:
        logs = (heat.produced, heat.entry_heat, heat.entry_flux)
        for j in range(lo + first, hi, stride):
            boundary_exchange(j, heat, tau, t, code == CONDUCTION_REVERSE, heat.theta, eta, logs)
    elif CONDUCTION:
        for k in range(lo + first, hi, stride):
            pair_exchange(k, heat.first, heat.second, heat.factor, heat.capacity, heat.inv_capacity, heat.theta,
                          eta, heat.produced)


def _temperature_update(e, x, eta, edges, springs, theta):
    """theta[e] = θ(l_e, η_e) at positions x (the CPU's temperature pass, per spring)."""
    l = math.sqrt(squared_length(x, edges, e))
    c = 0 if UNIFORM else e
    theta[e] = spring_temperature(l, eta[e], springs.rest[e], springs.P, c)


def _sweep_kernel(code, phase, heat, tau, t, phi, eta, flag):
    """Thread i: element i of the phase (see :func:`_sweep_phase`), unless the call stopped."""
    if flag[FLAG_SET] == 0:
        sweep_phase(code, phase, heat, tau, t, phi, eta, cuda.grid(1), cuda.gridsize(1))


def _temperature_kernel(x, eta, edges, springs, theta, flag):
    """Thread e: :func:`_temperature_update` of spring e, unless the call stopped."""
    e = cuda.grid(1)
    if e < edges.shape[0] and flag[FLAG_SET] == 0:
        temperature_update(e, x, eta, edges, springs, theta)


def source_digest() -> str:
    """A short hash of this module's source (part of the kernels' cache names)."""
    return hashlib.sha256(inspect.getsource(sys.modules[__name__]).encode()).hexdigest()[:8]


def bind_device_heat(ns: dict, tag: str, inline) -> None:
    """Bind the heat-flow device functions into the kernel namespace ``ns`` (which holds the
    model, the sub-flows and CONDUCTION / WAVES), each compiled by ``inline``."""
    bind_heat_flow(ns, tag, inline)
    for name, template in (("phase_span", _phase_span), ("sweep_phase", _sweep_phase),
                           ("temperature_update", _temperature_update)):
        ns[name] = inline(rebind(template, tag, ns))


def heat_kernels(compile_):
    """(sweep, temperature) kernels compiled by ``compile_(template)``."""
    return compile_(_sweep_kernel), compile_(_temperature_kernel)


def conduction_coefficient(integrator) -> float:
    """The coefficient c of the integrator's conduction rows (τ = c h; 0 when none), as the CPU
    stepper requires: one for all of them."""
    taus = sorted({c for _, f, c in integrator.flows if isinstance(f, BuiltinFlow) and f.code != THERMAL_WAVES})
    if len(taus) > 1:
        raise InputError(f"{integrator.name}: conduction rows with different coefficients {taus}")
    return taus[0] if taus else 0.0


class DeviceHeat:
    """The heat record on the device: static arrays uploaded once, the conduction factors per
    step size, the logs (:meth:`HeatSetup.new_logs`) uploaded with the state and copied back
    with it. ``setup`` None: the empty record of a run without heat flow."""

    def __init__(self, setup, integrator, to_device):
        self.setup = setup
        self._to_device = to_device
        self.coefficient = conduction_coefficient(integrator) if setup is not None else 0.0
        host = setup.record(0.0, setup.new_logs()) if setup is not None else no_heat()
        self.colour_ptr = np.asarray(host.colour_ptr)
        self.n_bound = int(host.bound_spring.shape[0])
        self._static = [to_device(np.ascontiguousarray(a)) for a in host[:len(Heat._fields) - len(LOGS)]]
        self.logs = tuple(to_device(np.ascontiguousarray(getattr(host, k))) for k in LOGS)
        self._factor = (None, None)  # (τ, device factors)

    def record(self, h: float) -> Heat:
        """The device :class:`Heat` for sweeps over τ = coefficient · h."""
        static = list(self._static)
        if self.setup is not None and self.setup.conduction:
            tau = self.coefficient * h
            if self._factor[0] != tau:
                self._factor = (tau, self._to_device(self.setup.factor(tau)))
            static[Heat._fields.index("factor")] = self._factor[1]
        return Heat(*static, *self.logs)

    def upload(self, state) -> None:
        """The logs of ``state`` onto the device."""
        if self.setup is None:
            return
        from ..integrators.splitting import heat_logs

        logs = heat_logs(state, self.setup)
        for name, target in zip(LOGS, self.logs):
            if target.size:
                target.copy_to_device(np.ascontiguousarray(logs[name]))

    def download(self, state) -> None:
        """The device logs into ``state.extra["heat"]``."""
        if self.setup is None:
            return
        from ..integrators.splitting import heat_logs

        logs = heat_logs(state, self.setup)
        for name, source in zip(LOGS, self.logs):
            if source.size:
                source.copy_to_host(logs[name])

    def theta_ok(self) -> bool:
        """Whether heat.theta holds the springs' temperatures where the last call ended."""
        return self.setup is not None and bool(self.logs[-1].copy_to_host()[0] == 1.0)

    def set_theta_ok(self, valid: bool) -> None:
        self.logs[-1].copy_to_device(np.array([1.0 if valid else 0.0]))

    def phases(self, code: int):
        """(phase, number of elements) of heat row ``code``, in order (see :func:`_phase_span`)."""
        n = self.colour_ptr.shape[0] - 1 + (0 if code == THERMAL_WAVES else 1)
        out = []
        for phase in range(n):
            _, lo, hi = _phase_span(code, phase, self.colour_ptr, self.n_bound)
            out.append((phase, int(hi - lo)))
        return out


def compile_heat_ptx(model, uniform: bool = True, cc=(9, 0)) -> dict[str, str]:
    """PTX of the heat kernels (conduction and thermal waves compiled in) for ``model`` and
    compute capability ``cc``, as :func:`thermonet.cuda.kernels.compile_ptx` does for the
    stepping kernels (the toolkit, no GPU). Returns name -> PTX text."""
    from numba import njit, typeof

    from ..kernels import records
    from ..kernels.specialize import kernel_namespace
    from ..kernels.splitting import bind_subflows

    ns = kernel_namespace(model, True, uniform)
    ns["CONDUCTION"] = ns["WAVES"] = True
    tag = f"{model.name}_heat_ptx"
    inline = njit(inline="always")
    bind_subflows(ns, tag, inline)
    bind_device_heat(ns, tag, inline)
    v, x, i = np.empty(1), np.empty((1, 3)), np.empty(1, np.int64)
    heat = records.Heat(i, i, v, v, i, v, v, i, i, i, i, v, i, np.empty((1, 4)), i, v, v, v, v, v, v, v)
    springs = records.Springs(v, np.empty((len(model.parameters), 1)))
    flag = np.zeros(4, np.int64)
    samples = {"sweep": (_sweep_kernel, (-2, 0, heat, 1.0, 0.0, v, v, flag)),
               "temperature": (_temperature_kernel, (x, v, np.empty((1, 2), np.uint32), springs, v, flag))}
    out = {}
    for name, (template, args) in samples.items():
        out[name], _ = cuda.compile_ptx(rebind(template, tag, ns), tuple(typeof(a) for a in args), cc=cc)
    return out
