"""A conduction sweep divided among the processes, bit for bit the whole net's sweep of one
process (:func:`thermonet.heat.passes._conduction_sweep`).

Each process sweeps its blocks (:mod:`thermonet.parallel.heat_share`) colour by colour with the
CPU kernel's own star exchange, and after each colour, and after the baths and sources, sends
the temperatures it changed to the processes that hold them (non-blocking point-to-point
messages, as the position halo). Every spring's temperature thus goes through the same
exchanges, in the same order, with the same operands as in one process. The entropy update and
the logs are kept per process for its share's springs and its boundary entries, from call to
call; they are put together on rank 0 only when the whole state is read
(:meth:`DistributedSweep.to_root`), and a diagnostics row adds up exact sums of each process's
part (:meth:`DistributedSweep.heat_sums`).
"""

from __future__ import annotations

import numpy as np

from ..heat.logs import heat_sums
from ..heat.passes import CONTINUE, FORWARD, REVERSE, SAVE
from ..heat.exchange import reverse_half
from ..heat.setup import entry_decay, incidence_factors
from ..kernels import records
from .heat_share import ascending_set, heat_shares, ranges
from .whole import IndexGather

#: message tag of the temperatures exchanged between a sweep's phases
TAG = 34


class ValueExchange:
    """Spring values sent to and received from other processes by a
    :class:`~thermonet.parallel.heat_share.Plan` (local indices), into one (ls,) array."""

    def __init__(self, comm, plan):
        self.comm = comm
        self._send = [(q, idx, np.empty(len(idx))) for q, idx in sorted(plan.send.items())]
        self._recv = [(q, idx, np.empty(len(idx))) for q, idx in sorted(plan.recv.items())]
        self.bytes = sum(buf.nbytes for _, _, buf in self._send)

    def exchange(self, values: np.ndarray) -> None:
        from mpi4py import MPI

        requests = [self.comm.Irecv(buf, source=q, tag=TAG) for q, _, buf in self._recv]
        for q, idx, buf in self._send:
            np.take(values, idx, out=buf)
            requests.append(self.comm.Isend(buf, dest=q, tag=TAG))
        MPI.Request.Waitall(requests)
        for _, idx, buf in self._recv:
            values[idx] = buf


def _entries_of(bound_ptr, reported) -> np.ndarray:
    """(E_q,) int64 the entries of the boundary springs a process reports (reported: (S,) bool,
    which of the boundary springs it reports)."""
    bound = np.flatnonzero(reported)
    sizes = bound_ptr[bound + 1] - bound_ptr[bound]
    return np.repeat(bound_ptr[bound], sizes) + ranges(sizes)


def _share_springs(dec, edges) -> list:
    """Every process's share springs (those with an end it owns), ascending: one sort of the
    springs by each end's owner."""
    edges = np.asarray(edges, dtype=np.int64)
    parts = []
    for end in (0, 1):
        owner = dec.owner[edges[:, end]]
        by_owner = np.argsort(owner, kind="stable")
        ptr = np.concatenate([[0], np.cumsum(np.bincount(owner, minlength=dec.size))])
        parts.append([by_owner[ptr[q]:ptr[q + 1]] for q in range(dec.size)])
    m = len(edges)
    return [ascending_set(np.concatenate([a, b]), m) for a, b in zip(*parts)]


class DistributedSweep:
    """The conduction sweeps of one process's share (see the module docstring).

    heat: the whole net's :class:`~thermonet.heat.setup.HeatSetup` (read while this is built:
    the sweep's plan and the process's part of the setup are cut from it); dec, sh: the decomposition
    and process ``rank``'s share; comm: the communicator; phases: (colour_phase, boundary_phase,
    finish) of :func:`~thermonet.parallel.heat_stages.sweep_phase_functions`.
    """

    def __init__(self, heat, dec, sh, comm, phases, rank: int):
        size = dec.size
        self.comm, self.heat = comm, heat
        self._colour_phase, self._boundary_phase, self._finish = phases
        layout = heat.layout
        bound_spring, starts = np.unique(heat.entry_spring, return_index=True)  # as HeatSetup.record's
        bound_spring = bound_spring.astype(np.int64)
        bound_ptr = np.append(starts, len(heat.entry_spring)).astype(np.int64)
        shares = _share_springs(dec, layout.edges)
        self.part = hs = heat_shares(heat.star_order("cpu"), layout.inc_ptr, layout.inc_spring, bound_spring,
                                     bound_ptr, dec, shares, rank)
        self.ml = ml = len(sh.springs)
        assert np.array_equal(hs.springs[:ml], sh.springs)
        ls = len(hs.springs)
        self._start = ValueExchange(comm, hs.start)
        self._colours = [ValueExchange(comm, p) for p in hs.colours]
        self._boundary = ValueExchange(comm, hs.boundary)
        self._any_boundary = len(bound_spring) > 0
        local = np.full(len(heat.capacity), -1, dtype=np.int64)
        local[hs.springs] = np.arange(ls)
        self._bound_spring = np.ascontiguousarray(local[bound_spring[hs.bound]])
        sizes = bound_ptr[hs.bound + 1] - bound_ptr[hs.bound]
        self._bound_ptr = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        # the process's part of the conduction setup, cut once from the whole net's
        self._capacity = np.ascontiguousarray(heat.capacity[hs.springs])
        self._inv_capacity = 1.0 / self._capacity
        self._conductance = np.ascontiguousarray(heat.conductance[hs.springs])
        self._uniform = heat.uniform_exchange()
        self._entry_kind = np.ascontiguousarray(heat.entry_kind[hs.entries])
        self._entry_rate = np.ascontiguousarray(heat.entry_rate[hs.entries])
        self._functions = heat.packed_functions()
        g = heat.graph  # (thermal waves are not distributed: their pairs are empty here)
        self._waves = (g.first, g.second, np.ascontiguousarray(g.kappa[:, 1]), g.colour_ptr)
        self._block_node = np.arange(len(hs.node), dtype=np.int64)
        self.theta = np.empty(ls)
        self.theta_start = np.empty(ls)
        self.produced = np.empty(ls)
        self.pending = {k: np.empty(ml) for k in ("pending_eta", "pending_produced", "pending_theta")}
        self.entry_heat = np.empty(len(hs.entries))
        self.entry_flux = np.empty(len(hs.entries))
        self._record = None
        reported = [dec.owned_springs(q) for q in range(size)] if rank == 0 else None  # (placed by rank 0)
        self._springs_gather = IndexGather(reported, np.searchsorted(sh.springs, dec.owned_springs(rank)),
                                           np.bincount(dec.spring_owner, minlength=size))
        bound_owner = dec.spring_owner[bound_spring]
        entries = [_entries_of(bound_ptr, bound_owner == q) for q in range(size)]
        assert np.array_equal(entries[rank], hs.entries)
        self._entries_gather = IndexGather(entries, np.arange(len(hs.entries)))
        self._entry_fn = np.ascontiguousarray(heat.entry_fn[hs.entries])  # (its entries' bath or source)
        self._n_names = len(heat.names)

    def take(self, logs: dict) -> None:
        """This process's part of the whole ``logs`` (a state it has not stepped yet)."""
        hs = self.part
        np.take(logs["produced"], hs.springs, out=self.produced)
        for k, v in self.pending.items():
            np.take(logs[k], hs.springs[:self.ml], out=v)
        np.take(logs["entry_heat"], hs.entries, out=self.entry_heat)
        np.take(logs["entry_flux"], hs.entries, out=self.entry_flux)

    def share_logs(self) -> dict:
        """The logs this process keeps for its share, keyed as the whole ones: produced and the
        pending ones (ml,) at the share's springs, entry_heat and entry_flux at its entries."""
        return {"produced": self.produced[:self.ml], **self.pending, "entry_heat": self.entry_heat,
                "entry_flux": self.entry_flux}

    def to_root(self, logs: dict, more: list) -> None:
        """This process's logs into the whole ``logs`` on rank 0, each spring's and entry's from
        the process that reports it (every process must call it); with them the (share array
        (ml,), whole array) pairs ``more``."""
        mine = self.share_logs()
        pairs = [(mine[k], logs[k]) for k in ("produced", *self.pending)] + list(more)
        self._springs_gather.to_root(self.comm, pairs)
        self._entries_gather.to_root(self.comm, [(self.entry_heat, logs["entry_heat"]),
                                                 (self.entry_flux, logs["entry_flux"])])

    def heat_sums(self, counted: np.ndarray) -> np.ndarray:
        """The exact accumulators of this process's part of a row's heat-flow sums
        (:func:`thermonet.heat.logs.heat_sums`): the produced entropy of the springs it reports
        (``counted`` (ml,) uint8), its entries' heat and entropy."""
        return heat_sums(self.produced[:self.ml][counted.view(bool)], self.entry_heat, self.entry_flux,
                         self._entry_fn, self._n_names)

    def _local_record(self, tau: float, theta_ok: np.ndarray, sweeps: int):
        """This process's :class:`~thermonet.kernels.records.Heat` for half sweeps over τ,
        ``sweeps`` per half boundary (its factors made from its part of the setup, as the whole
        net's are: :func:`thermonet.heat.setup.incidence_factors`); theta_ok: the logs' flag (1,)."""
        if self._record is not None and self._record[0] == (tau, sweeps) and self._record[1] is theta_ok:
            return self._record[2]
        hs = self.part
        weight, decay, mask, node_scale = incidence_factors(self._conductance, self._capacity, tau, hs.inc_ptr,
                                                            hs.inc_spring, self._uniform)
        if len(weight) == 0:  # (no blocks here: nothing reads them)
            weight, decay = np.zeros(1), np.zeros(1)
        empty = np.zeros(0)
        local = records.Heat(hs.colour_ptr, hs.block_ptr, self._block_node, hs.inc_ptr, hs.inc_spring, weight, decay,
                             mask, node_scale, np.array([sweeps], dtype=np.int64), *self._waves, self._capacity,
                             self._inv_capacity,
                             self._bound_spring, self._bound_ptr, self._entry_kind, self._entry_fn,
                             entry_decay(self._entry_rate, tau),
                             *self._functions, self.produced, self.entry_heat, self.entry_flux, empty, theta_ok, empty,
                             self.pending["pending_eta"], self.pending["pending_produced"],
                             self.pending["pending_theta"], empty, self.theta_start, empty)
        self._record = ((tau, sweeps), theta_ok, local)
        return local

    def sweep(self, theta_ok: np.ndarray, theta_keep: np.ndarray, eta: np.ndarray, tau: float, t: float,
              directions: int, sweeps: int = 1) -> None:
        """The half sweeps ``directions`` (REVERSE, FORWARD, both; SAVE, CONTINUE) over τ at t,
        ``sweeps`` per half of the boundary (alternately reverse and forward, as
        :func:`thermonet.heat.passes._conduction_sweep`'s), from the share's θ (ml,) (updated in
        place) and η (ml,) (its entropy update made); theta_ok: the heat logs' flag (1,)."""
        heat = self._local_record(tau, theta_ok, sweeps)
        ml, theta, start = self.ml, self.theta, self.theta_start
        theta[:ml] = theta_keep
        self._start.exchange(theta)
        if directions & CONTINUE:
            start[:ml] = self.pending["pending_theta"]
            eta[:] = self.pending["pending_eta"]
            self.produced[:ml] = self.pending["pending_produced"]
        else:
            start[:ml] = theta[:ml]
        n_colours = len(self._colours)
        for half in range(0 if directions & REVERSE else sweeps, 2 * sweeps if directions & FORWARD else sweeps):
            if reverse_half(half, sweeps):  # reverse: the colours backwards, then the boundary entries
                for i in range(n_colours):
                    colour = n_colours - 1 - i
                    self._colour_phase(heat, theta, colour, True)
                    self._colours[colour].exchange(theta)
                if self._any_boundary:
                    self._boundary_phase(heat, theta, tau, t, True)
                    self._boundary.exchange(theta)
            else:
                if self._any_boundary:
                    self._boundary_phase(heat, theta, tau, t, False)
                    self._boundary.exchange(theta)
                for colour in range(n_colours):
                    self._colour_phase(heat, theta, colour, False)
                    self._colours[colour].exchange(theta)
        if directions & SAVE:
            self.pending["pending_theta"][:] = start[:ml]
            self.pending["pending_eta"][:] = eta
            self.pending["pending_produced"][:] = self.produced[:ml]
        self._finish(theta, start, eta, self._capacity, self.produced, ml)
        theta_keep[:] = theta[:ml]
