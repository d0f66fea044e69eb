"""Heat flow on the GPU: the conduction and thermal-wave rows of the explicit schedule
(docs/theory.md §5–6), built from the CPU's per-element functions (:mod:`thermonet.heat.exchange`).

A heat row is a sequence of *phases*, each a parallel pass whose elements share no spring:

- conduction forward (CONDUCTION_FORWARD, on the first step of a conduction cycle): the
  springs' θ kept as the sweep's start (``theta_start``), the boundary entries (baths, sources:
  one thread per boundary spring), the star colours in order (one thread per block, in the GPU's
  order one junction node each), then each spring's entropy update ``η += C ln(θ'/θ)``
  (``finish_spring``); in reverse (CONDUCTION_REVERSE, on a cycle's last step) the colours run
  backwards and the boundary entries after them (each spring's entries in reverse);
- thermal waves (THERMAL_WAVES): the pair colours in order.

A conduction row of a step that does not start (forward) or end (reverse) a cycle is skipped
(:func:`conduction_due`); its sweep is over τ = k·c·h for a cycle of k steps.

:func:`_sweep_phase` runs one phase over a grid-stride loop: the two-launch path launches
:func:`_sweep_kernel` once per phase (one thread per element), the fused kernel calls it between
grid-wide barriers. A conduction sweep works on the springs' temperatures in the device copy of
the ``theta`` log (``heat.theta``), valid when ``theta_ok`` says so, as the CPU's ``theta_keep``:
after a sweep, and across calls. Where θ is not valid, a temperature pass
(:func:`_temperature_update`) computes θ(l, η) before the sweep; where the stage right before a
due sweep does not drift (a kick), its spring pass keeps the θ it computed, and l, instead
(:func:`_keep_temperature`, the same function of the same l and η, as the CPU reuses that θ).
The kick after the sweeps evaluates θ(l, η) again, at the stored length, where the CPU takes
the swept θ (``refresh_pass``): equal to round-off. Both keep the lengths in ``heat.length``, so
the logs stay valid for a CPU run continuing from the state, and θ as the sweep's start
(``theta_start``): then the row skips its start phase (:func:`first_phase`). A call's first sweep
without such a pass runs it, so the bits do not depend on where calls end.

A cycle boundary of a table ``[CF, stages…, CR]`` runs as the CPU's kernel runs it: the closing
kick is deferred past it (:func:`deferred_closing`), and the reverse and forward rows are one
exchange with one entropy update and their meeting colours one phase (:func:`joined_boundary`,
:func:`conduction_plan`); a call that ends between them keeps the update pending in the state's
``pending_*`` logs, as the CPU does.

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
from ..explicit.cuda import FLAG_SET
from ..explicit.schedule import STAGE
from ..kernels.records import Heat, no_heat
from ..kernels.specialize import rebind
from . import exchange
from .rows import CONDUCTION_FORWARD, CONDUCTION_REVERSE, THERMAL_WAVES
from .setup import entry_decay

# Bound per kernel variant by bind_device_heat() (see thermonet.heat.exchange).
star_node = star_block = boundary_exchange = finish_spring = wave_exchange = spring_temperature = squared_length = None
reverse_half = exchange.reverse_half  # (plain Python too: DeviceHeat.phases runs _phase_span on the host)
phase_span = phase_count = phase_elements = sweep_phase = temperature_update = None
CONDUCTION = False
WAVES = False
UNIFORM = False

#: the record's logs (kept in the state) and working arrays, after its static fields
LOGS = ("produced", "entry_heat", "entry_flux", "theta", "theta_ok", "length", "pending_eta", "pending_produced",
        "pending_theta")
WORK = ("s_before", "theta_start", "strain")
#: what a phase runs over (see _phase_span)
PAIRS, BLOCKS, BOUNDARY, START, FINISH = range(5)
#: how a phase runs (:func:`_sweep_phase`'s ``mode``, see :func:`conduction_plan`): PLAIN; SAVE, a
#: reverse row's finish that ends a call first keeps each spring's η, production log and start
#: θ as pending (``theta_ok`` 2); RESUME, a forward row's start phase takes them back instead of
#: θ as the start; JOINED, a colour phase runs each block in reverse, then forward
PLAIN, SAVE, RESUME, JOINED = 0, 1, 2, 4
#: the arrays of DeviceHeat.kept, by position
KEPT_THETA, KEPT_LENGTH, KEPT_START, KEPT_CAPACITY, KEPT_PRODUCED = range(5)


def _conduction_due(code, every, step_in_cycle):
    """Whether conduction row ``code`` runs on a step that is step ``step_in_cycle`` (0..k−1)
    of its conduction cycle of ``every`` = k steps: the forward row on the first, the reverse row
    on the last."""
    if code == CONDUCTION_FORWARD:
        return step_in_cycle == 0
    return step_in_cycle == every - 1


conduction_due = _conduction_due  # (plain Python too: the two-launch path asks _sweep_follows on the host)


def _phase_span(code, phase, colour_ptr, star_colour_ptr, n_bound, m, sweeps):
    """(kind, lo, hi, reverse): phase ``phase`` of heat row ``code`` runs elements lo:hi of kind
    PAIRS (one colour's wave pairs), BLOCKS (one star colour's blocks), BOUNDARY (boundary
    springs), START or FINISH (all m springs); ``reverse``: its blocks' nodes last to first, its
    entries in reverse. A conduction row is START, its ``sweeps`` half sweeps (the CPU's: those
    of a boundary's 2j alternately reverse and forward, the middle between a reverse and a
    forward one; the reverse row the first j, the forward row the last j), FINISH."""
    if code == THERMAL_WAVES:
        return PAIRS, colour_ptr[phase], colour_ptr[phase + 1], False
    n_colours = star_colour_ptr.shape[0] - 1
    if phase == 0:
        return START, 0, m, False
    if phase == sweeps * (n_colours + 1) + 1:
        return FINISH, 0, m, False
    half = (phase - 1) // (n_colours + 1) + (0 if code == CONDUCTION_REVERSE else sweeps)
    within = (phase - 1) % (n_colours + 1)
    reverse = reverse_half(half, sweeps)
    if within == (n_colours if reverse else 0):
        return BOUNDARY, 0, n_bound, reverse
    colour = n_colours - 1 - within if reverse else within - 1
    return BLOCKS, star_colour_ptr[colour], star_colour_ptr[colour + 1], reverse


def _phase_count(code, colour_ptr, star_colour_ptr, sweeps):
    """Phases of heat row ``code``: the wave pairs' colours, or for conduction the start phase,
    the star colours and boundary phase of each of its ``sweeps`` half sweeps, the finish."""
    if code == THERMAL_WAVES:
        return colour_ptr.shape[0] - 1
    return sweeps * (star_colour_ptr.shape[0] - 1 + 1) + 2


def _phase_elements(code, phase, heat):
    """How many elements phase ``phase`` of heat row ``code`` runs over (the fused kernel skips
    the grid-wide barrier after an empty one: baths and sources on a net without them)."""
    _, lo, hi, _ = phase_span(code, phase, heat.colour_ptr, heat.star_colour_ptr, heat.bound_spring.shape[0],
                              heat.capacity.shape[0], heat.sweeps[0])
    return hi - lo


def _sweep_phase(code, phase, heat, tau, t, phi, eta, first, stride, mode):
    """The elements first, first + stride, ... of phase ``phase`` of heat row ``code`` at time
    t, the row over τ (a conduction row's half sweeps each over τ / heat.sweeps[0]; conduction
    on heat.theta; see the module docstring), run as ``mode`` says (PLAIN, SAVE, RESUME,
    JOINED). phi, eta: (m,)."""
    sweeps = heat.sweeps[0]
    kind, lo, hi, reverse = phase_span(code, phase, heat.colour_ptr, heat.star_colour_ptr,
                                       heat.bound_spring.shape[0], heat.capacity.shape[0], sweeps)
    if WAVES and code == THERMAL_WAVES:
        for k in range(lo + first, hi, stride):
            wave_exchange(k, heat.first, heat.second, heat.wave, tau, phi, eta)
    elif CONDUCTION and kind == BLOCKS:
        joined = mode == JOINED
        for b in range(lo + first, hi, stride):
            if joined:  # the reverse half's last colour, then the forward half's first
                star_block(b, heat, True, heat.theta)
            star_block(b, heat, reverse and not joined, heat.theta)
    elif CONDUCTION and kind == BOUNDARY:
        logs = (heat.produced, heat.entry_heat, heat.entry_flux)
        for j in range(lo + first, hi, stride):
            boundary_exchange(j, heat, tau / sweeps, t, reverse, heat.theta, logs)
    elif CONDUCTION and kind == START:
        for e in range(lo + first, hi, stride):
            if mode == RESUME:  # the last call's reverse half sweep: its entropy update continues
                heat.theta_start[e] = heat.pending_theta[e]
                eta[e] = heat.pending_eta[e]
                heat.produced[e] = heat.pending_produced[e]
            else:
                heat.theta_start[e] = heat.theta[e]
    elif CONDUCTION:
        for e in range(lo + first, hi, stride):
            if mode == SAVE:
                heat.pending_theta[e] = heat.theta_start[e]
                heat.pending_eta[e] = eta[e]
                heat.pending_produced[e] = heat.produced[e]
            finish_spring(e, heat.theta, heat.theta_start, eta, heat.capacity, heat.produced)
            if code == CONDUCTION_REVERSE:  # the forward row that follows starts from this θ
                heat.theta_start[e] = heat.theta[e]


def joined_boundary(table):
    """Whether the reverse row ending a conduction cycle and the forward row starting the next
    meet with nothing between them: a table ``[CF, stages…, CR]`` whose closing kick is deferred
    past both (:func:`deferred_closing`). Then, as the
    CPU's kernel runs a cycle boundary, the two rows are one exchange: the springs' entropy
    update covers both half sweeps (the reverse row's finish is left out, the forward row keeps
    its start θ: one ``η += C ln(θ'/θ)`` instead of two), the meeting colours run as one phase
    (:func:`colours_meet`), and a call that ends between them keeps the pending update for the
    next call (SAVE, RESUME), so the bits do not depend on where calls end."""
    code = table.code
    n = code.shape[0]
    return (n >= 3 and code[0] == CONDUCTION_FORWARD and code[1] == STAGE and code[n - 1] == CONDUCTION_REVERSE
            and deferred_closing(table) == n - 2)


def colours_meet(sweeps, n_bound, n_colours):
    """Whether, at a joined boundary, the reverse half sweep's last colour and the forward one's
    first (the same colour) run as one phase, each block in reverse then forward: one half sweep
    a side (``sweeps`` 1), no baths or sources between them (``n_bound`` boundary springs), more
    than one colour."""
    return sweeps == 1 and n_bound == 0 and n_colours > 1


def conduction_plan(code, count, n_colours, sweeps, n_bound, start_kept, finish_pending, joined, follows, resume):
    """Which of the ``count`` phases of due conduction row ``code`` run, and how: (lo, hi, skip,
    together, start_mode, finish_mode) — phases lo … hi − 1 but ``skip``, phase ``together``
    JOINED, the start phase (0) as ``start_mode``, the finish as ``finish_mode``. ``n_colours``,
    ``sweeps``, ``n_bound``: the star colours, sub-sweeps and boundary springs (:func:`colours_meet`).
    ``start_kept``: the pass
    before wrote θ as the start (:func:`first_phase`); ``finish_pending``: the spring pass after
    it finishes (:func:`finish_deferred`); at a joined boundary (:func:`joined_boundary`):
    ``joined``, a forward row right after the reverse row that left it its update; ``follows``,
    a reverse row whose forward row follows in this call (else it ends the call: SAVE);
    ``resume``, a forward row at a call's first step after a call that saved (RESUME; as on the
    CPU, a saved update is continued only there)."""
    meet = colours_meet(sweeps, n_bound, n_colours)
    lo = first_phase(code, start_kept)
    hi = count - (1 if finish_pending else 0)
    skip = -1
    together = -1
    start_mode = PLAIN
    finish_mode = PLAIN
    if code == CONDUCTION_REVERSE:
        if follows:
            hi = count - 1
            if meet:
                skip = n_colours  # its last colour (the forward row's first)
        else:
            finish_mode = SAVE
    elif joined:
        lo = 1  # theta_start is still the reverse row's start
        if meet:
            together = 2  # (phase 1 is its boundary entries, none here)
    elif resume and lo == 0:
        start_mode = RESUME
    return lo, hi, skip, together, start_mode, finish_mode


def phase_mode(phase, count, together, start_mode, finish_mode):
    """The mode of phase ``phase`` of a conduction row of ``count`` phases (see :func:`conduction_plan`)."""
    if phase == together:
        return JOINED
    if phase == 0:
        return start_mode
    return finish_mode if phase == count - 1 else PLAIN


def _temperature_update(e, x, eta, edges, springs, heat):
    """heat.theta[e] = heat.theta_start[e] = θ(l_e, η_e) and heat.length[e] = l_e at positions
    x (the CPU's temperature pass, per spring; the sweep that follows starts from this θ)."""
    l = math.sqrt(squared_length(x, edges, e))
    c = 0 if UNIFORM else e
    theta = spring_temperature(l, eta[e], springs.rest[e], springs.P, c)
    heat.length[e] = l
    heat.theta[e] = theta
    heat.theta_start[e] = theta


def _keep_temperature(e, l, theta, kept):
    """A spring pass right before a conduction sweep keeps spring e's θ(l, η) and l for it, as
    the temperature pass would. kept: :attr:`DeviceHeat.kept`."""
    kept[KEPT_THETA][e] = theta
    kept[KEPT_LENGTH][e] = l
    kept[KEPT_START][e] = theta


def _kept_length(e, kept):
    """Spring e's length where the last conduction sweep ran (kept with its θ by the pass before
    it). kept: :attr:`DeviceHeat.kept`."""
    return kept[KEPT_LENGTH][e]


def _finish_before_kick(e, eta, kept):
    """The finish of the forward sweep before this spring pass (:func:`finish_deferred`),
    spring e's ``η += C ln(θ'/θ)``, before the pass reads η. kept: :attr:`DeviceHeat.kept`."""
    finish_spring(e, kept[KEPT_THETA], kept[KEPT_START], eta, kept[KEPT_CAPACITY], kept[KEPT_PRODUCED])


def finish_deferred(table, r):
    """Whether row r of the stage table, a forward conduction row, leaves its finish phase to
    the spring pass of the stage right after it (row r + 1 a stage with a kick, which reads η
    anyway: :func:`_finish_before_kick`)."""
    code = table.code
    return code[r] == CONDUCTION_FORWARD and r + 1 < code.shape[0] and code[r + 1] == STAGE and table.kick[r + 1] != 0.0


def deferred_closing(table):
    """The row of the closing kick the GPU defers past a step boundary's conduction rows, or −1.

    A table with conduction rows at both ends of the step (``[CF, stages…, CR]``, no carry: the
    sweeps stand between one step's last kick and the next one's first) ends each step with a
    kick without drift. Where no sweep is due at a boundary (k > 1), that kick and the next
    step's first act at the same positions and entropies: they run as one stage of two kicks
    (two additions, as the carry of a table without heat rows). Where a sweep is due, the closing
    kick's spring pass runs before it (its forces into ``heat.s_before``, θ and l kept for the
    sweep) and its node pass joins the next stage's (:func:`thermonet.explicit.cuda.kernels._kick_split`):
    the same operations on the same operands as two stages, one node pass fewer. A call's last
    closing kick runs at its end. This is that row: the table's last stage, with a kick and no
    drift, every row after it and before the first stage a conduction row; −1 for any other table.
    """
    code = table.code
    first = -1
    last = -1
    for r in range(code.shape[0]):
        if code[r] == STAGE:
            if first < 0:
                first = r
            last = r
    if last <= first or table.drift[last] != 0.0 or table.kick[last] == 0.0 or table.carry != 0.0:
        return -1
    for r in range(code.shape[0]):
        if (r < first or r > last) and code[r] != CONDUCTION_FORWARD and code[r] != CONDUCTION_REVERSE:
            return -1
    return last


def _sweep_follows(table, r, every, step_in_cycle):
    """Whether row r + 1 of the stage table is a conduction row due on this step (step
    ``step_in_cycle`` of a cycle of ``every`` steps): then the spring pass of row r, if its
    stage does not drift, keeps the temperatures for the sweep (:func:`_keep_temperature`)
    instead of a temperature pass."""
    if r + 1 >= table.code.shape[0]:
        return False
    code = table.code[r + 1]
    if code != CONDUCTION_FORWARD and code != CONDUCTION_REVERSE:
        return False
    return conduction_due(code, every, step_in_cycle)


def first_phase(code, start_kept):
    """The first phase of heat row ``code`` to run: a conduction row skips its start phase
    (θ copied to ``theta_start``) when ``start_kept``, i.e. when the pass before it wrote
    ``theta_start`` = θ already: a temperature pass, a spring pass that kept θ, or a reverse row's
    finish (a forward row right after it)."""
    return 1 if code != THERMAL_WAVES and start_kept else 0


def _sweep_kernel(code, phase, heat, tau, t, phi, eta, flag, mode):
    """Thread i: element i of the phase (see :func:`_sweep_phase`), unless the call stopped."""
    if flag[FLAG_SET] == 0:
        sweep_phase(code, phase, heat, tau, t, phi, eta, cuda.grid(1), cuda.gridsize(1), mode)


def _temperature_kernel(x, eta, edges, springs, heat, flag):
    """Thread e: :func:`_temperature_update` of spring e, unless the call stopped."""
    e = cuda.grid(1)
    if e < edges.shape[0] and flag[FLAG_SET] == 0:
        temperature_update(e, x, eta, edges, springs, heat)


def source_digest() -> str:
    """A short hash of this module's source (part of the kernels' cache names)."""
    return hashlib.sha256(inspect.getsource(sys.modules[__name__]).encode()).hexdigest()[:8]


def bind_device_heat(ns: dict, tag: str, inline) -> None:
    """Bind the heat-flow device functions into the kernel namespace ``ns`` (which holds the
    model, the sub-flows and CONDUCTION / WAVES), each compiled by ``inline``."""
    from ..timefunctions import evaluate_py

    ns["evaluate"] = inline(evaluate_py)
    ns["log"] = math.log  # (the CPU binds a vectorizing log; one call per spring here)
    for name in exchange.SHARED:
        ns[name] = inline(rebind(getattr(exchange, name), tag, ns))
    for name, template in (("phase_span", _phase_span), ("phase_count", _phase_count),
                           ("phase_elements", _phase_elements), ("sweep_phase", _sweep_phase),
                           ("temperature_update", _temperature_update), ("conduction_due", _conduction_due),
                           ("keep_temperature", _keep_temperature), ("sweep_follows", _sweep_follows),
                           ("first_phase", first_phase), ("finish_before_kick", _finish_before_kick),
                           ("kept_length", _kept_length),
                           ("finish_deferred", finish_deferred), ("deferred_closing", deferred_closing),
                           ("joined_boundary", joined_boundary), ("colours_meet", colours_meet),
                           ("conduction_plan", conduction_plan), ("phase_mode", phase_mode)):
        ns[name] = inline(rebind(template, tag, ns))


def heat_kernels(compile_):
    """(sweep, temperature) kernels compiled by ``compile_(template)``."""
    return compile_(_sweep_kernel), compile_(_temperature_kernel)


def conduction_coefficient(integrator) -> float:
    """The coefficient c of the integrator's conduction rows (τ = c h; 0 when none): one for all
    of them, as the CPU stepper's half sweeps."""
    from ..explicit.schedule import BuiltinFlow

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
        host = setup.record(0.0, setup.new_logs(), "cuda") if setup is not None else no_heat()
        self.colour_ptr = np.asarray(host.colour_ptr)
        self.star_colour_ptr = np.asarray(host.star_colour_ptr)
        self.n_bound = int(host.bound_spring.shape[0])
        self.m = int(host.capacity.shape[0])
        n_static = len(Heat._fields) - len(LOGS) - len(WORK)
        assert Heat._fields[n_static:] == LOGS + WORK
        self._static = [to_device(np.ascontiguousarray(a)) for a in host[:n_static]]
        self.logs = tuple(to_device(np.ascontiguousarray(getattr(host, k))) for k in LOGS)
        self._work = tuple(to_device(np.zeros_like(getattr(host, k))) for k in WORK)
        #: (theta, length, theta_start, capacity, produced), positions KEPT_*: what a spring pass
        #: reads and writes when it keeps θ and l for the sweep after it or finishes the one before
        capacity = self._static[Heat._fields.index("capacity")]
        self.kept = (self.logs[LOGS.index("theta")], self.logs[LOGS.index("length")],
                     self._work[WORK.index("theta_start")], capacity, self.logs[LOGS.index("produced")])
        #: (m,) T/l of a deferred closing kick, computed before the sweep (see deferred_closing)
        self.s_before = self._work[WORK.index("s_before")]
        self._factor = (None, None)  # ((τ, j), device weight, decay, node scale, sweeps, bath decays)

    def record(self, h: float, every: int = 1, sweeps: int = 1) -> Heat:
        """The device :class:`Heat` for a conduction row over τ = coefficient · k · h (a cycle of
        k steps), as ``sweeps`` half sweeps over τ / sweeps each."""
        static = list(self._static)
        if self.setup is not None and self.setup.conduction:
            tau = self.coefficient * every * h
            if self._factor[0] != (tau, sweeps):
                factors = (*self.setup.factors(tau / sweeps), np.array([sweeps], dtype=np.int64),
                           entry_decay(self.setup.entry_rate, tau / sweeps))
                self._factor = ((tau, sweeps), tuple(self._to_device(np.ascontiguousarray(a)) for a in factors))
            for name, value in zip(("weight", "decay", "factor_mask", "node_scale", "sweeps", "entry_decay"),
                                   self._factor[1]):
                static[Heat._fields.index(name)] = value
        return Heat(*static, *self.logs, *self._work)

    def upload(self, state) -> None:
        """The logs of ``state`` onto the device."""
        if self.setup is None:
            return
        from .logs import heat_logs

        logs = heat_logs(state, self.setup)
        for name, target in zip(LOGS, self.logs):
            if target.size:
                target.copy_to_device(np.ascontiguousarray(logs[name]))

    def download(self, state) -> None:
        """The device logs into ``state.extra["heat"]``."""
        if self.setup is None:
            return
        from .logs import heat_logs

        logs = heat_logs(state, self.setup)
        for name, source in zip(LOGS, self.logs):
            if source.size:
                source.copy_to_host(logs[name])

    def theta_ok(self) -> float:
        """0: heat.theta is not valid; 1: it holds the springs' temperatures where the last call
        ended; 2: and that call ended with a reverse row that kept its update pending (SAVE)."""
        return float(self.logs[LOGS.index("theta_ok")].copy_to_host()[0]) if self.setup is not None else 0.0

    def set_theta_ok(self, value: float) -> None:
        self.logs[LOGS.index("theta_ok")].copy_to_device(np.array([float(value)]))

    def phases(self, code: int, sweeps: int = 1):
        """(phase, number of elements) of heat row ``code`` with ``sweeps`` sub-sweeps, in order
        (see :func:`_phase_span`)."""
        out = []
        for phase in range(_phase_count(code, self.colour_ptr, self.star_colour_ptr, sweeps)):
            _, lo, hi, _ = _phase_span(code, phase, self.colour_ptr, self.star_colour_ptr, self.n_bound, self.m, sweeps)
            out.append((phase, int(hi - lo)))
        return out


def compile_heat_ptx(model, uniform: bool = True, cc=(9, 0)) -> dict[str, str]:
    """PTX of the heat kernels (conduction and thermal waves compiled in) for ``model`` and
    compute capability ``cc``, as :func:`thermonet.explicit.cuda.kernels.compile_ptx` does for the
    stepping kernels (the toolkit, no GPU). Returns name -> PTX text."""
    from numba import njit, typeof

    from ..kernels import records
    from ..kernels.specialize import kernel_namespace
    from ..kernels.subflows import bind_subflows

    ns = kernel_namespace(model, True, uniform)
    ns["CONDUCTION"] = ns["WAVES"] = True
    tag = f"{model.name}_heat_ptx"
    inline = njit(inline="always")
    bind_subflows(ns, tag, inline)
    bind_device_heat(ns, tag, inline)
    v, x, i = np.empty(1), np.empty((1, 3)), np.empty(1, np.int64)
    heat = sample_heat()
    springs = records.Springs(v, np.empty((len(model.parameters), 1)))
    flag = np.zeros(4, np.int64)
    samples = {"sweep": (_sweep_kernel, (-2, 0, heat, 1.0, 0.0, v, v, flag, 0)),
               "temperature": (_temperature_kernel, (x, v, np.empty((1, 2), np.uint32), springs, heat, flag))}
    out = {}
    for name, (template, args) in samples.items():
        out[name], _ = cuda.compile_ptx(rebind(template, tag, ns), tuple(typeof(a) for a in args), cc=cc)
    return out


def sample_heat():
    """A :class:`Heat` record of one-element arrays of the kernels' types (for compiling)."""
    v, i, i32 = np.empty(1), np.empty(1, np.int64), np.empty(1, np.int32)
    return Heat(i, i, i, i, np.empty(1, np.uint32), v, v, np.zeros(1, np.uint64), v, np.ones(1, np.int64), i32, i32,
                v, i, v, v, i, i, i, i, v, i, np.empty((1, 4)), i, v, v, v, v, v, v, v, v, v, v, v, v, v, v)
