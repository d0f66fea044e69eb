"""Heat flow as a run sets it up: conduction, thermal waves, baths and sources (docs/theory.md §5–6).

Users give :class:`Bath` and :class:`Source` records (or mappings with the same keys) and the
transport parameters ``g``, ``g_star`` (:mod:`thermonet.heat.parameters`); :func:`build_heat`
checks them against the net and the model and returns the :class:`HeatSetup` a stepper runs, in
the engine's internal numbering.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ..errors import InputError
from ..kernels.records import Heat
from ..timefunctions import TimeFunction, pack, time_function
from .exchange import BATH, SOURCE
from .graph import PairGraph, StarOrder, bath_ends, fastest_rate, pair_graph, star_order


@dataclass(frozen=True)
class Bath:
    """A node group held at temperature θ_b(t) > 0: every spring touching one of its nodes
    exchanges heat with it through its conductance g. group: a node group name of the net, or
    node indices; temperature: a number or a :class:`~thermonet.timefunctions.TimeFunction`
    (or a mapping of one, see :func:`~thermonet.timefunctions.time_function`)."""

    group: object
    temperature: object


@dataclass(frozen=True)
class Source:
    """A spring group receiving power P(t) per spring (heat per time; negative: a sink). group:
    a spring group name of the net (a material region), or spring indices."""

    group: object
    power: object


@dataclass(eq=False)
class HeatSetup:
    """What the kernels need for heat flow, internal numbering.

    conduction, waves: which flows run. graph: the thermal waves' coloured pairs (empty without
    waves), kappa (P, 2) with k* from g* in column 1. layout: the run's layout (the conduction
    sweep's order is built from it, per backend: :meth:`star_order`). capacity: (m,) C per
    spring. names: the baths' then the sources' names; functions: their time functions (same order). Entries (E,) sorted by spring:
    entry_spring, entry_kind (BATH/SOURCE), entry_fn (index into functions and names),
    entry_rate (g/C of a bath end). bath_nodes: (n,) int64 bath of each node (−1 none).
    conductance, wave_conductance: (m,) g and g*; n_baths: the first n_baths names are baths.
    """

    conduction: bool
    waves: bool
    graph: PairGraph
    capacity: np.ndarray
    names: list
    functions: list
    entry_spring: np.ndarray
    entry_kind: np.ndarray
    entry_fn: np.ndarray
    entry_rate: np.ndarray
    bath_nodes: np.ndarray
    conductance: np.ndarray
    wave_conductance: np.ndarray
    n_baths: int
    layout: object = None

    def new_logs(self) -> dict:
        """Zeroed logs: produced (m,), entry_heat (E,), entry_flux (E,), the sweeps' working
        temperatures and lengths theta, length (m,) with theta_ok (1,) = 0 (not valid yet), and
        cycle (3,): the conduction cycle's length k, the step it is counted from (multirate
        conduction: a cycle starts at every step s with (s − cycle[1]) % cycle[0] == 0) and the
        half sweeps j of each half of its boundaries (:mod:`thermonet.heat.multirate`);
        pending_eta, pending_produced, pending_theta (m,): see :class:`~thermonet.kernels.records.Heat`."""
        return {"produced": np.zeros(len(self.capacity)), "entry_heat": np.zeros(len(self.entry_spring)),
                "entry_flux": np.zeros(len(self.entry_spring)), "theta": np.zeros(len(self.capacity)),
                "theta_ok": np.zeros(1), "length": np.zeros(len(self.capacity)), "cycle": np.array([1.0, 0.0, 1.0]),
                "pending_eta": np.zeros(len(self.capacity)), "pending_produced": np.zeros(len(self.capacity)),
                "pending_theta": np.zeros(len(self.capacity))}

    def star_order(self, backend: str = "cpu") -> StarOrder:
        """The conduction sweep's order on ``backend`` (:func:`thermonet.heat.graph.star_order`):
        blocks of the net's bandwidth on the CPU, single nodes on the GPU. Another discretization
        of the same flow each (both second order, energy exact, entropy non-decreasing); a CPU
        run reproduces a GPU run to round-off with ``backend="cuda"``."""
        cached = self.__dict__.setdefault("_orders", {})
        if backend not in cached:
            g = self.conductance if self.conduction else np.zeros_like(self.conductance)
            cached[backend] = star_order(self.layout, g, self.bath_nodes < 0, self.block_nodes(backend))
        return cached[backend]

    def block_nodes(self, backend: str) -> int | None:
        """Nodes per block of ``backend``'s sweep order (None: the net's bandwidth)."""
        return self.__dict__.get("_block_nodes", {}).get(backend, None if backend == "cpu" else 1)

    def use_order_of(self, backend: str, on: str = "cpu") -> None:
        """Sweep in ``backend``'s order on ``on`` (before the first step): a CPU run then
        reproduces a GPU run to round-off (tests, and to check a device's results)."""
        self.__dict__.setdefault("_block_nodes", {})[on] = self.block_nodes(backend)
        self.__dict__.get("_orders", {}).pop(on, None)

    def fastest_rate(self) -> float:
        """The conduction's fastest rate, ``max_e (Σ_f κ_ef + g_e at bath ends) / C_e`` (1/time),
        0 without conduction."""
        if not self.conduction or len(self.capacity) == 0:
            return 0.0
        cached = self.__dict__.get("_fastest")
        if cached is None:
            cached = self.__dict__["_fastest"] = float(
                fastest_rate(self.layout, self.conductance, self.capacity, self.bath_nodes < 0).max())
        return cached

    def factors(self, tau: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(weight, decay, factor_mask, node_scale): ``a = C (1 − exp(−g τ/C))`` and
        ``exp(−g τ/C)`` for a sweep over τ, (2m,) each, of the spring of each incidence of the
        layout (``inc_spring``'s order, so that a sweep reads them in sequence) — or (1,) each
        when every spring has the same g and C, with factor_mask (1,) uint64 0 (else all ones);
        and (n,) 1 / Σ a at each node (0 where the sum is 0)."""
        cached = self.__dict__.setdefault("_factors", {})
        if tau not in cached:
            g = self.conductance if self.conduction else np.zeros_like(self.conductance)
            cached.clear()
            cached[tau] = incidence_factors(g, self.capacity, tau, self.layout.inc_ptr, self.layout.inc_spring,
                                            self.uniform_exchange())
        return cached[tau]

    def uniform_exchange(self) -> bool:
        """Whether every spring has the same g and C (the sweep's factors are then one value each)."""
        g = self.conductance if self.conduction else np.zeros_like(self.conductance)
        return len(g) > 0 and bool(np.all(g == g[0]) and np.all(self.capacity == self.capacity[0]))

    def packed_functions(self) -> tuple:
        """The baths' and sources' time functions packed for the kernels (:func:`thermonet.timefunctions.pack`)."""
        return pack(self.functions) if self.functions else pack([TimeFunction.constant(0.0)])

    def record(self, tau: float, logs: dict, backend: str = "cpu", sweeps: int = 1) -> Heat:
        """The kernels' :class:`~thermonet.kernels.records.Heat` for conduction half sweeps over
        τ in ``backend``'s order, ``sweeps`` of them in each half of a cycle boundary, logging
        into ``logs`` (:meth:`new_logs`, kept in the state). The last one is kept and returned
        again while τ, the sweeps, the order and the log arrays are the same (a run asks for one
        per call: building it costs more than a small net's step)."""
        order = self.star_order(backend)
        last = self.__dict__.get("_last_record")
        if (last is not None and last[0] == (tau, sweeps) and last[1] is order and len(last[2]) == len(logs)
                and all(logs.get(k) is v for k, v in last[2].items())):
            return last[3]
        record = self._record(tau, logs, order, sweeps)
        self.__dict__["_last_record"] = ((tau, sweeps), order, dict(logs), record)
        return record

    def _record(self, tau: float, logs: dict, order: StarOrder, sweeps: int = 1) -> Heat:
        cached = self.__dict__.get("_static")
        if cached is None:
            spring = self.entry_spring
            bound, starts = np.unique(spring, return_index=True)
            ptr = np.append(starts, len(spring)).astype(np.int64)
            packed = self.packed_functions()
            cached = (bound.astype(np.int64), ptr, packed, 1.0 / self.capacity)
            self.__dict__["_static"] = cached
        bound, ptr, packed, inv_capacity = cached
        g = self.graph
        inc = self.__dict__.get("_incidence")
        if inc is None:
            inc = self.__dict__["_incidence"] = (np.ascontiguousarray(self.layout.inc_ptr, dtype=np.int64),
                                                 np.ascontiguousarray(self.layout.inc_spring).view(np.uint32))
        return Heat(order.colour_ptr, order.block_ptr, order.node, *inc, *self.factors(tau),
                    np.array([sweeps], dtype=np.int64), g.first, g.second, np.ascontiguousarray(g.kappa[:, 1]),
                    g.colour_ptr, self.capacity, inv_capacity,
                    bound, ptr, self.entry_kind, self.entry_fn, entry_decay(self.entry_rate, tau), *packed,
                    logs["produced"], logs["entry_heat"], logs["entry_flux"], logs["theta"], logs["theta_ok"],
                    logs["length"], logs["pending_eta"], logs["pending_produced"], logs["pending_theta"],
                    *self._work())

    def _work(self) -> tuple:
        """The working arrays s_before, theta_start, strain (m,) of the kernels (allocated once)."""
        work = self.__dict__.get("_work_arrays")
        if work is None:
            m = len(self.capacity)
            work = self.__dict__["_work_arrays"] = (np.empty(m), np.empty(m), np.empty(m))
        return work


def entry_decay(entry_rate: np.ndarray, tau: float) -> np.ndarray:
    """(E,) exp(−r τ) of each bath end's rate r = g/C for a half sweep over τ (a source's entry
    ignores it): made once with the sweep's record, not at every exchange."""
    return np.exp(-np.asarray(entry_rate, dtype=np.float64) * tau)


def incidence_factors(conductance: np.ndarray, capacity: np.ndarray, tau: float, inc_ptr: np.ndarray,
                      inc_spring: np.ndarray, uniform: bool) -> tuple:
    """(weight, decay, factor_mask, node_scale) of :meth:`HeatSetup.factors` for the springs of
    conductances and capacities (k,) over τ, at incidence lists ``inc_ptr`` (n+1,) and
    ``inc_spring`` (2m,) into those springs (a whole net's, or a process's part of one: the same
    operations on the same operands, so the same bits); ``uniform``: every spring of the net has
    the same g and C (weight and decay cut to one value)."""
    x = -conductance * tau / capacity
    spring = np.asarray(inc_spring, dtype=np.int64)
    weight = np.ascontiguousarray((-capacity * np.expm1(x))[spring])
    ptr = np.asarray(inc_ptr, dtype=np.int64)
    # (bincount adds each node's incidences in order, from 0)
    total = np.bincount(np.repeat(np.arange(len(ptr) - 1), np.diff(ptr)), weights=weight, minlength=len(ptr) - 1)
    scale = np.divide(1.0, total, out=np.zeros_like(total), where=total > 0.0)
    decay = np.ascontiguousarray(np.exp(x)[spring])
    mask = np.array([0 if uniform else np.iinfo(np.uint64).max], dtype=np.uint64)
    if uniform:
        weight, decay = weight[:1].copy(), decay[:1].copy()
    return weight, decay, mask, np.ascontiguousarray(scale)


def _named(spec, where: str, kind):
    if isinstance(spec, kind):
        return spec
    if isinstance(spec, Mapping):
        keys = {"group", "temperature"} if kind is Bath else {"group", "power"}
        unknown = set(spec) - keys
        missing = keys - set(spec)
        if unknown or missing:
            raise InputError(f"{where}: expected keys {sorted(keys)}"
                             + (f"; unknown {sorted(unknown)}" if unknown else "")
                             + (f"; missing {sorted(missing)}" if missing else ""))
        return kind(**spec)
    raise InputError(f"{where}: expected a {kind.__name__} or a table with keys group and "
                     f"{'temperature' if kind is Bath else 'power'}, got {spec!r}")


def _check_bath_temperature(f: TimeFunction, where: str) -> None:
    """A bath temperature stays > 0 for t ≥ 0; else an InputError saying when it reaches 0."""
    when = f.first_at_or_below(0.0)
    if when == 0.0:
        raise InputError(f"{where}: a bath temperature must be > 0, got {f(0.0):g} at t = 0"
                         + ("" if f.kind == "constant" else f" ({f.describe()})"))
    if when is not None:
        raise InputError(f"{where}: a bath temperature must stay > 0, but {f.describe()} reaches 0 at t = {when:.6g}")


def build_heat(net, layout, model, P_user, transport: dict, *, thermal: bool, conduction, waves, baths,
               sources) -> HeatSetup | None:
    """The :class:`HeatSetup` of a run, or None when no heat flow is asked for.

    transport: the user's ``g`` / ``g_star`` (user numbering, see
    :func:`~thermonet.heat.parameters.transport_array`); conduction, waves: on, off, or None
    (on when ``g`` / ``g_star`` is given); baths, sources: name -> :class:`Bath` /
    :class:`Source` (or mappings). Errors name the key.
    """
    from .parameters import transport_array

    m, n = net.n_springs, net.n_nodes
    baths = dict(baths or {})
    sources = dict(sources or {})
    conduction = ("g" in transport) if conduction is None else bool(conduction)
    waves = ("g_star" in transport) if waves is None else bool(waves)
    if not (conduction or waves):
        if baths or sources:
            raise InputError(f"{'baths' if baths else 'sources'} need conduction on (conduction=True, scene: "
                             "effects.conduction = true) and a conductance g")
        return None
    if not thermal:
        raise InputError(f"{'conduction' if conduction else 'thermal waves'} needs thermal coupling on "
                         "(thermal=True, scene: effects.thermal = true)")
    if (baths or sources) and not conduction:
        raise InputError("baths and sources need conduction on (conduction=True, scene: effects.conduction = true)")
    if "C0" not in model.parameters:
        raise InputError(f"heat flow needs a model with a constant heat capacity (parameter C0); model "
                         f"{model.name!r} has parameters {', '.join(model.parameters)}")
    for key, on in (("g", conduction), ("g_star", waves)):
        if on and key not in transport:
            raise InputError(f"{'conduction' if key == 'g' else 'thermal waves'} is on but no conductance "
                             f"{key!r} is given (parameters, scene: a material region's {key} = ...)")
    g_user = transport_array("g", transport.get("g", 0.0), m) if conduction else np.zeros(m)
    gs_user = transport_array("g_star", transport.get("g_star", 0.0), m) if waves else np.zeros(m)
    capacity_user = P_user[model.parameter_index("C0")]

    bath_of_node_user = np.full(n, -1, dtype=np.int64)
    names, functions = [], []
    for i, (name, spec) in enumerate(baths.items()):
        where = f"baths.{name}"
        bath = _named(spec, where, Bath)
        nodes = net.nodes(bath.group, f"{where}.group")
        f = time_function(bath.temperature, f"{where}.temperature")
        _check_bath_temperature(f, f"{where}.temperature")
        taken = bath_of_node_user[nodes] >= 0
        if taken.any():
            a = int(nodes[taken][0])
            raise InputError(f"{where}.group: node {a} is already in bath {names[bath_of_node_user[a]]!r}")
        bath_of_node_user[nodes] = i
        names.append(name)
        functions.append(f)
    source_springs = []
    for name, spec in sources.items():
        where = f"sources.{name}"
        source = _named(spec, where, Source)
        source_springs.append(layout.spring_rank[net.springs(source.group, f"{where}.group")])
        names.append(name)
        functions.append(time_function(source.power, f"{where}.power"))

    g = np.ascontiguousarray(layout.springs_to_internal(g_user))
    g_star = np.ascontiguousarray(layout.springs_to_internal(gs_user))
    capacity = np.ascontiguousarray(layout.springs_to_internal(capacity_user))
    bath_nodes = np.ascontiguousarray(layout.nodes_to_internal(bath_of_node_user))
    if waves:
        graph = pair_graph(layout, np.vstack([np.zeros_like(g), g_star]), junction=bath_nodes < 0)
    else:
        graph = PairGraph(np.empty(0, np.int32), np.empty(0, np.int32), np.empty((0, 2)), np.zeros(1, np.int64))

    spring_b, bath_b = bath_ends(layout, bath_nodes)
    keep = g[spring_b] > 0.0
    spring_b, bath_b = spring_b[keep], bath_b[keep]
    spring_s = np.concatenate(source_springs) if source_springs else np.empty(0, dtype=np.int64)
    fn_s = (np.concatenate([np.full(len(s), len(baths) + j) for j, s in enumerate(source_springs)])
            if source_springs else np.empty(0, dtype=np.int64))
    spring = np.concatenate([spring_b, spring_s]).astype(np.int64)
    kind = np.concatenate([np.full(len(spring_b), BATH), np.full(len(spring_s), SOURCE)]).astype(np.int64)
    fn = np.concatenate([bath_b, fn_s]).astype(np.int64)
    rate = np.where(kind == BATH, g[spring] / capacity[spring], 0.0)
    order = np.argsort(spring, kind="stable")
    return HeatSetup(conduction, waves, graph, capacity, names, functions,
                     np.ascontiguousarray(spring[order]), np.ascontiguousarray(kind[order]),
                     np.ascontiguousarray(fn[order]), np.ascontiguousarray(rate[order]), bath_nodes, g, g_star,
                     len(baths), layout)
