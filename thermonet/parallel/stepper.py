"""The explicit step over several processes: the CPU kernel's own passes on each process's
share, the ghosts' positions exchanged after every drift.

Each process runs the stage rows of the integrator's schedule as the CPU kernel
(:mod:`thermonet.explicit.cpu`) does, calling its compiled spring and node passes (the same
functions, from the same disk cache) on its share (:mod:`thermonet.parallel.domain`): per spring
θ, T/l and Φ; per owned node the force gathered in the whole net's order, the kick and the drift;
then the halo. Two kicks meeting at a step boundary stay two additions and a call ends with the
closing kick, exactly as in one process, so every owned node and spring gets the same bits as in
one process. Rank 0 builds every process's stepper from the whole net
(:meth:`~DistributedStepper.for_rank`) and sends it to its process (:mod:`thermonet.parallel.ship`).

Between calls the state stays in the shares: a call starts from the share's arrays where the
Simulation's state is the one they were taken from (:meth:`DistributedStepper._bind`; a state
loaded or replaced is taken again) and leaves its result there. The whole net's arrays are put
together only when something reads them (a diagnostics row does not: each process reduces its
share into exact sums, added over the processes, :meth:`~DistributedStepper.row_sums`);
:meth:`~DistributedStepper.sync` (``Simulation.internal_state``: frames, probes, ``sim.state``;
a checkpoint is written in pieces, :meth:`~DistributedStepper.piece`) gives them to every
process, so reading them is a step every process takes. The runner's backup for blow-up replays
is a copy of the shares (:meth:`~DistributedStepper.backup_state`). Between a call's end and the
next read, processes other than rank 0 hold no whole x, p, Φ, η or heat logs (empty arrays stand
in for them, so a read that skipped ``sync`` fails instead of seeing old values); the share's heat
logs are the conduction's (:mod:`thermonet.parallel.conduction`).
"""

from __future__ import annotations


import numpy as np

from ..blowup import blowup_failure
from ..diagnostics import row_sums, sums_of
from ..kernels.reductions import rows_digest
from ..errors import InputError
from ..explicit import cpu
from ..explicit.codes import FORCE_KEPT
from ..explicit.schedule import STAGE
from ..heat.logs import ENTRY_LOGS, PER_SPRING_LOGS, heat_columns_of
from ..integrators.base import Stepper
from ..kernels import records
from ..kernels.specialize import model_fingerprint
from ..loads.elements import NO_LOADS
from ..loads.stepping import StepperLoads
from ..state import copy_extra
from .conduction import DistributedConduction
from .domain import decomposition, share
from .halo import Halo
from .loads import ShareLoads, load_functions
from .partition import partition
from .stages import stage_functions
from .whole import broadcast, broadcast_value, counts_offsets, gather_to_root
from .world import on_root


def splitting_passes(model, parallel: bool, thermal: bool, uniform: bool, loads: bool = False,
                     conduction: bool = False) -> tuple[dict, str]:
    """(namespace, variant): the passes of the CPU kernel's variant without flows (with loads
    where ``loads``, with the conduction sweeps where ``conduction``) and a name unique to it."""
    advance = cpu.splitting_kernels(model, parallel, thermal, uniform, (), conduction, False, loads)
    ns = next(cpu._PASSES[k] for k, v in cpu._CACHE.items() if v is advance)  # that variant's passes
    variant = (f"{model.name}_{model_fingerprint(model)}_{'par' if parallel else 'ser'}"
               f"_{'thermal' if thermal else 'mech'}{'_uniform' if uniform else ''}{'_loads' if loads else ''}"
               f"{'_conduction' if conduction else ''}_r{rows_digest()}")
    return ns, variant


def splitting_stages(model, parallel: bool, thermal: bool, uniform: bool, loads: bool = False):
    """(stage, closing) of :mod:`thermonet.parallel.stages` around the passes of the CPU kernel's
    variant without flows or heat flow (with loads where ``loads``), and with loads the loads'
    functions (:func:`thermonet.parallel.loads.load_functions`), else None."""
    ns, variant = splitting_passes(model, parallel, thermal, uniform, loads)
    return stage_functions(ns, variant), (load_functions(ns, variant) if loads else None)


def conduction_stages(model, parallel: bool, uniform: bool) -> tuple[tuple, object, tuple]:
    """(stage functions, temperature_pass, sweep phases) of :mod:`thermonet.parallel.heat_stages`
    around the CPU kernel's conducting variant (thermal, without flows or loads)."""
    from .heat_stages import heat_stage_functions, sweep_phase_functions

    ns, variant = splitting_passes(model, parallel, True, uniform, False, True)
    return (heat_stage_functions(ns, variant), ns["temperature_pass"],
            sweep_phase_functions(ns, variant, parallel))


def compiled_parts(model, parallel: bool, thermal: bool, uniform: bool, loads: bool, conduction: bool) -> list:
    """Every compiled function a :class:`DistributedStepper` of these options holds, in a fixed
    order (what :mod:`thermonet.parallel.ship` names instead of sending: each process gets the
    same ones from its disk cache)."""
    (stage, closing), load_fns = splitting_stages(model, parallel, thermal, uniform, loads)
    passes, _ = splitting_passes(model, parallel, thermal, uniform, loads)
    parts = [stage, closing, *(load_fns or ()), passes["boundary_node_pass"], passes["thermal_kick"]]
    if conduction:
        functions, temperature_pass, phases = conduction_stages(model, parallel, uniform)
        parts += [*functions, temperature_pass, *phases]
    return parts


class DistributedStepper(Stepper):
    """An explicit :class:`~thermonet.explicit.splitting.Splitting` over the processes of
    ``comm``: see the module docstring.

    integrator: the splitting; system: the whole net's System (rank 0's: the other processes get
    their steppers from rank 0, built by :meth:`for_rank`, with stand-ins for its whole arrays);
    points: (n, 3) reference positions, internal numbering (the partition's input);
    parallel: multi-threaded passes; method: "rcb", "metis" or "blocks"
    (:mod:`thermonet.parallel.partition`), default "blocks" with conduction, else "rcb".
    """

    #: advance(..., measure=True) keeps the closing kick's spring energies for :meth:`row_sums`
    measures = True

    def __init__(self, integrator, system, comm, points, parallel: bool = False, method: str | None = None):
        table = integrator.table_between_sweeps
        if (np.asarray(table.code) != STAGE).any():
            raise InputError(f"{integrator.name}: a run over MPI processes runs kick/drift stages only")
        size, edges = comm.Get_size(), system.edges
        conducting = integrator.heat_rows[0]
        method = method or ("blocks" if conducting else "rcb")
        spans = _block_spans(system.heat.star_order("cpu")) if method == "blocks" and conducting else None
        dec = decomposition(partition(points, edges, size, method, spans), edges, size)
        self._build(integrator, system, comm, dec, comm.Get_rank(), parallel)

    def for_rank(self, rank: int, state) -> "DistributedStepper":
        """The stepper of process ``rank``, built here from the whole net (rank 0 builds every
        process's: :mod:`thermonet.parallel.ship`), holding its share of ``state``; it keeps no
        decomposition (rank 0's alone)."""
        other = DistributedStepper.__new__(DistributedStepper)
        other._build(self.integrator, self.system, self.comm, self.decomposition, rank, self.parallel, self.loads)
        other._bind(state)
        other._fresh = ROOT
        other.decomposition = None
        return other

    def _build(self, integrator, system, comm, dec, rank: int, parallel: bool, loads=None) -> None:
        """Process ``rank``'s stepper for the decomposition ``dec`` of the whole ``system``;
        loads: the whole net's StepperLoads where built already (they are made from ``system``)."""
        self.integrator, self.system, self.comm, self.parallel = integrator, system, comm, bool(parallel)
        self.size, self.rank = dec.size, int(rank)
        table = integrator.table_between_sweeps
        self._kicks, self._drifts, self._carry = list(table.kick), list(table.drift), float(table.carry)
        edges = system.edges
        conducting = integrator.heat_rows[0]
        self.decomposition = dec
        self.share = sh = share(dec, edges, self.rank)
        self.halo = Halo(comm, sh.send, sh.recv)
        thermal = system.thermal
        P, uniform = system.kernel_parameters
        self._uniform = uniform
        with_loads = system.loads is not None
        (self._stage, self._closing), functions = splitting_stages(system.model, parallel, thermal, uniform,
                                                                   with_loads)
        # a call continuing from the state the last call ended in starts from its closing kick's
        # forces and temperatures, as one process does (thermonet.explicit.cpu, "reuse")
        passes, _ = splitting_passes(system.model, parallel, thermal, uniform, with_loads)
        self._kept_node_pass, self._thermal_kick = passes["boundary_node_pass"], passes["thermal_kick"]
        #: (state, step) whose forces and temperatures the last call's closing kick left in the
        #: share's f_keep and theta_keep
        self._boundary = None
        self._topology = sh.topology
        self._springs = records.Springs(np.ascontiguousarray(system.rest_lengths[sh.springs]),
                                        P if uniform else np.ascontiguousarray(P[:, sh.springs]))
        base = records.nodes(system)
        #: the loads' clock and arrays (the Simulation points ``loads.time_origin`` at its clock)
        self.loads = (loads or StepperLoads.of(system, table)) if with_loads else None
        self._loads = ShareLoads(self.loads, sh, dec, base, functions) if with_loads else None
        self._nodes = records.Nodes(np.ascontiguousarray(base.masses[sh.nodes]),
                                    np.ascontiguousarray(base.inv_mass[sh.nodes]),
                                    np.ascontiguousarray(base.anchored[sh.nodes] | ~sh.owned),  # ghosts held
                                    base.gravity, base.with_gravity, base.reference)
        nl, ml = len(sh.nodes), len(sh.springs)
        self._x, self._p = np.empty((nl, 3)), np.empty((nl, 3))
        self._phi = np.empty(ml if thermal else 0)
        self._eta = np.empty(ml if thermal else 0)
        self._scratch = records.scratch(nl, ml, thermal)
        self._no_heat = records.no_heat_cpu()
        self._bad = np.zeros(1, dtype=np.int64)
        self._gather = _OwnedGather(dec, sh, thermal, conducting, self.rank, system.layout)
        #: (state, step) whose closing kick left the share's spring energies (advance(..., measure))
        self._measured = None
        #: (ml,) uint8: the share's springs this process reports, whose U and η its diagnostics
        #: sums count (a spring between two parts is in both shares, counted by one)
        self._counted = np.zeros(ml, dtype=np.uint8)
        self._counted[self._gather.local_springs] = 1
        #: the State whose arrays the shares were taken from (None: none yet), and how far its
        #: whole arrays are up to date with the shares: on every process (ALL), on rank 0 (ROOT; ROW:
        #: but for Φ), nowhere (NONE); the same on every process, as every process takes the same steps
        self._bound, self._fresh = None, ALL
        #: rank 0 inside :meth:`on_root`: its reads of the whole state are its own
        self.local = False
        self._conduction = None
        #: the number of the whole net's bath and source entries (its entry logs' length)
        self._entries = len(system.heat.entry_spring) if conducting else 0
        if conducting:  # conduction: its own call (thermonet.parallel.conduction)
            self._conduction = DistributedConduction(self, *conduction_stages(system.model, parallel, uniform))

    # ------------------------------------------------------------------------------------------
    def advance(self, state, n_steps: int, h: float, measure: bool = False):
        """``n_steps`` steps of h of the whole net's ``state`` (in place, on every process)."""
        self._measured = None
        reuse = self._boundary is not None and self._boundary[0] is state and self._boundary[1] == state.step
        self._boundary = None
        if n_steps <= 0:
            return None
        self._bind(state)
        if self._conduction is not None:
            return self._conduction.advance(state, n_steps, h)
        lo, hi = self.system.stretch_bounds
        # (with measure, the closing kick's spring pass keeps each spring's energy in energy_buf)
        run = records.Run(float(h), float(state.time), int(n_steps), bool(self.integrator.track_phi), float(lo),
                          float(hi), False, bool(measure), 1, 0)
        arrays = records.StateArrays(self._x, self._p, self._phi, self._eta)
        cur, nxt = self._x, self._scratch.x_buf
        local = (self._topology, self._springs, self._nodes, self._scratch)
        loads = self._loads
        la = NO_LOADS if loads is None else loads.arrays_for(state, h)
        extra = (self._no_heat.length, (self._no_heat.s_before, la))
        pending = 0.0
        for step in range(n_steps):
            for r, (k2, drift) in enumerate(zip(self._kicks, self._drifts)):
                k1 = pending if r == 0 else 0.0
                steps = records.KickDrift(k1 * h, k2 * h, drift * h, k1 != 0.0 or k2 != 0.0)
                if loads is not None and steps.with_force:  # (as the CPU kernel: thermonet.explicit.cpu)
                    loads.evaluate(la, _stage_time(la, h, step, la.kick_time[r]))
                if reuse and step == 0 and r == 0 and steps.with_force:
                    bad = self._kept_kick(cur, nxt, arrays, steps, extra)
                else:
                    bad = self._stage(cur, nxt, arrays, *local, steps, run, extra)
                if steps.with_force and self._any(bad):  # row 0's positions end the previous step: that one was bad
                    return self._stopped(state, cur, step - 1 if r == 0 and step > 0 else step)
                if loads is not None and steps.with_force:
                    loads.add_work(self.comm, cur, self._scratch.s, self._topology, self._nodes, steps.kick1,
                                   steps.kick2)
                cur, nxt = nxt, cur
                if drift != 0.0:
                    self.halo.exchange(cur)
                    if loads is not None:
                        loads.evaluate(la, _stage_time(la, h, step, la.drift_time[r]))
                        loads.drive(cur, la)
            pending = self._carry
        if pending != 0.0:  # the closing kick (drift 0: the positions stay in cur)
            if loads is not None:
                loads.evaluate(la, _stage_time(la, h, n_steps, 0.0))
            if self._any(self._closing(cur, nxt, arrays, *local, pending * h, run, extra)):
                return self._stopped(state, cur, n_steps - 1)
            if loads is not None:
                loads.add_work(self.comm, cur, self._scratch.s, self._topology, self._nodes, 0.0, pending * h)
            if measure:
                self._measured = (state, state.step + int(n_steps))
            self._boundary = (state, state.step + int(n_steps))
        self._ended(cur)
        return None

    def _kept_kick(self, cur, nxt, arrays, steps, extra) -> int:
        """A call's first stage at the positions the last call's closing kick evaluated: its
        forces (f_keep) and temperatures (theta_keep) taken instead of a spring pass. Returns 0
        (no spring is evaluated)."""
        if self.system.thermal and self.integrator.track_phi:
            self._thermal_kick(arrays.phi, self._scratch.theta_keep, steps.kick2)
        self._kept_node_pass(cur, nxt, arrays.p, self._topology, self._nodes, self._scratch, steps,
                             np.int64(FORCE_KEPT), np.bool_(False), extra[1])
        return 0

    def _any(self, bad: int) -> bool:
        """Whether a spring left the admissible states on any process (all learn it together)."""
        from mpi4py import MPI

        self._bad[0] = bad
        self.comm.Allreduce(MPI.IN_PLACE, self._bad, op=MPI.SUM)
        return bool(self._bad[0])

    def _stopped(self, state, cur, steps_done: int):
        """A spring left the admissible states: the positions where it was found into the whole
        state on every process (the runner rewinds and replays), and the failure naming the spring."""
        self._ended(cur)
        raise self.on_root(state, lambda: blowup_failure(self.system, state.positions, state.entropy,
                                                         max(steps_done, 0)))

    # ------------------------------------------------------------------------------------------
    # the shares and the whole state

    def _bind(self, state) -> None:
        """Take this process's share of ``state`` unless the shares hold it already."""
        if state is self._bound:
            return
        sh = self.share
        np.take(state.positions, sh.nodes, axis=0, out=self._x)
        np.take(state.momenta, sh.nodes, axis=0, out=self._p)
        if self.system.thermal:
            np.take(state.thermal_displacement, sh.springs, out=self._phi)
            np.take(state.entropy, sh.springs, out=self._eta)
        if self._conduction is not None:
            self._conduction.take(state)
        self._bound, self._fresh = state, ALL

    def _ended(self, cur: np.ndarray) -> None:
        """A call ended with the positions in ``cur``: they become the share's (the two position
        buffers trade places), and the whole arrays are behind the shares."""
        if cur is not self._x:
            self._x, x_buf = cur, self._x
            self._scratch = self._scratch._replace(x_buf=x_buf)
        self._fresh = NONE
        self._release_whole()

    def row_sums(self, state) -> dict:
        """The sums of a diagnostics row of ``state``, keyed as
        :func:`thermonet.diagnostics.diagnostics_row`'s arguments, the same on every process (every
        process must call it): each process reduces its share (its own nodes, the springs it
        reports) into exact accumulators, which are added over the processes (one ``Allreduce``
        of integers, whose order cannot change the sum) and rounded once, as one process rounds
        its own; the temperature range is a minimum and a maximum over the processes. No whole
        array is put together."""
        from mpi4py import MPI

        self._bind(state)
        closing = None
        if self._measured is not None and self._measured[0] is state and self._measured[1] == state.step:
            # the closing kick of the call that ended here left U and the θ range of the share's
            # springs and the exact sums over its own nodes (ghosts are anchored in the share: they
            # count nothing)
            closing = (self._scratch.energy_buf, *self._scratch.sums, self._scratch.node_accs)
        acc, theta_min, theta_max = row_sums(self.system, self._x, self._p, self._eta, self._topology.edges,
                                             self._springs, self._nodes, self._uniform, self._counted,
                                             self.parallel, closing, self._scratch.energy_buf)
        self.comm.Allreduce(MPI.IN_PLACE, acc, op=MPI.SUM)
        theta = np.array([theta_min, -theta_max])
        self.comm.Allreduce(MPI.IN_PLACE, theta, op=MPI.MIN)
        return sums_of(acc, float(theta[0]), -float(theta[1]), self.system.thermal)

    def keep_share(self, state) -> None:
        """Rank 0, its Simulation built: take its share of ``state`` (the whole state stays
        up to date here until the first call)."""
        self._bind(state)
        self._fresh = ROOT
        self._release_whole()

    def _release_whole(self) -> None:
        if self.rank != 0:  # until something reads them, the whole x, p, Φ, η and heat logs are rank 0's alone
            state = self._bound
            state.positions = state.momenta = _RELEASED_NODES
            if self.system.thermal:
                state.thermal_displacement = state.entropy = _RELEASED_SPRINGS
            for k in self._share_log_keys(state):
                state.extra["heat"][k] = _RELEASED_SPRINGS

    def _share_log_keys(self, state) -> list:
        """The keys of ``state``'s heat logs each process keeps per share
        (:meth:`DistributedConduction.share_logs`): none without conduction."""
        if self._conduction is None:
            return []
        return [k for k in SHARE_LOGS if k in state.extra["heat"]]

    def _to_root(self, state, whole: bool = True) -> None:
        """The owned values of every process into ``state``'s whole arrays on rank 0: all of
        them, or (not ``whole``) those a diagnostics row reads, all but Φ."""
        if self._fresh == NONE or (whole and self._fresh == ROW):
            self._gather.to_root(self.comm, state, self._x, self._p, self._phi, self._eta, whole)
            if self._conduction is not None:
                self._conduction.to_root(state)
            self._fresh = ROOT if whole else ROW

    def sync(self, state) -> None:
        """The shares into ``state``'s whole arrays on every process (every process must call it)."""
        if state is not self._bound or self._fresh == ALL or self.local:
            return
        self._to_root(state)
        if state.positions is _RELEASED_NODES:  # (ranks > 0)
            n, m = self.system.n_nodes, self.system.n_springs
            state.positions, state.momenta = np.empty((n, 3)), np.empty((n, 3))
            if self.system.thermal:
                state.thermal_displacement, state.entropy = np.empty(m), np.empty(m)
            for k in self._share_log_keys(state):
                state.extra["heat"][k] = np.empty(self._entries if k in ENTRY_LOGS else m)
        thermal = [state.entropy, state.thermal_displacement] if self.system.thermal else []
        logs = [state.extra["heat"][k] for k in self._share_log_keys(state)]
        broadcast(self.comm, [state.positions, state.momenta] + thermal + logs)
        self._fresh = ALL

    def on_root(self, state, fn, whole: bool = True, arrays: bool = False):
        """``fn()`` run by rank 0 with the whole arrays of ``state`` put together there (x, p, η,
        and Φ where ``whole``), its result or its error on every process (every process must call
        it; ``arrays``: a result holding large arrays, sent as buffers). Inside, rank 0's reads of
        the state (``Simulation.internal_state``) are its own and send nothing; the other
        processes hold no whole x, p, Φ then."""
        if state is self._bound and self._fresh != ALL:
            self._to_root(state, whole)
        self.local = True
        try:
            if not arrays:
                return on_root(self.comm, fn)
            result = []
            on_root(self.comm, lambda: result.append(fn()))  # (its error raised on every process)
        finally:
            self.local = False
        return broadcast_value(self.comm, result[0] if result else None)

    def backup_state(self, state, into=None, entropy: bool = True):
        """A :class:`ShareBackup` of ``state`` (its share taken first where the shares do not
        hold it): the share's x, p, Φ, η and heat logs, the rest of the state's ``extra`` (the
        logs' cycle and theta_ok, the loads' work)."""
        self._bind(state)
        b = into if isinstance(into, ShareBackup) else ShareBackup.like(self)
        for source, target in zip(self._share_arrays(), b.arrays()):
            np.copyto(target, source)
        if self._conduction is not None:
            for k, part in self._conduction.share_logs().items():
                kept = b.logs.get(k)
                if kept is None:
                    kept = b.logs[k] = np.empty_like(part)
                np.copyto(kept, part)
        copy_extra(_without(state.extra, self._share_log_keys(state)), b.extra)
        return b

    def restore_state(self, backup, state, entropy: bool = True) -> None:
        """Put a :meth:`backup_state` copy back: the shares and their heat logs (the whole arrays
        then behind them), the rest of ``extra``."""
        for source, target in zip(backup.arrays(), self._share_arrays()):
            np.copyto(target, source)
        copy_extra(backup.extra, state.extra)
        if self._conduction is not None:
            for k, part in self._conduction.share_logs().items():
                np.copyto(part, backup.logs[k])
            self._conduction.continue_from_logs(state)
        self._bound, self._fresh = state, NONE
        self._release_whole()

    def heat_columns(self, state) -> dict:
        """The heat-flow columns of a diagnostics row of ``state``
        (:func:`thermonet.heat.logs.heat_columns`), the same on every process (every process must
        call it): each process's exact sums of the springs it reports and its entries, added over
        the processes (one ``Allreduce``) and rounded once. Nothing whole is put together."""
        from mpi4py import MPI

        self._bind(state)
        acc = self._conduction.heat_sums()
        self.comm.Allreduce(MPI.IN_PLACE, acc, op=MPI.SUM)
        return heat_columns_of(self.system.heat, acc)

    def _share_arrays(self) -> tuple:
        return self._x, self._p, self._phi, self._eta

    def piece(self, state) -> dict:
        """This process's part of ``state`` as a checkpoint piece keeps it, keyed as the
        checkpoint's arrays (:mod:`thermonet.parallel.pieces`): ``nodes`` (n_r,) its nodes in the
        user's numbering with their ``positions``, ``momenta`` (n_r, 3); ``springs`` (m_r,) the
        springs it reports with their ``thermal_displacement``, ``entropy`` and per-spring heat
        logs ``heat_<name>``; ``entries`` (E_r,) its bath and source entries with their logs. Each
        node, spring and entry is in exactly one process's piece. Copies; nothing is sent."""
        self._bind(state)
        g = self._gather
        out = {"nodes": g.user_nodes, "positions": self._x[g.local_nodes], "momenta": self._p[g.local_nodes]}
        if self.system.thermal:
            out.update(springs=g.user_springs, thermal_displacement=self._phi[g.local_springs],
                       entropy=self._eta[g.local_springs])
        if self._conduction is not None:
            for k, part in self._conduction.share_logs().items():
                out[f"heat_{k}"] = part.copy() if k in ENTRY_LOGS else part[g.local_springs]
            out["entries"] = self._conduction.entries
        return out

    def summary(self) -> dict | None:
        return None


def _block_spans(order) -> np.ndarray:
    """(B, 2) the first and last node of each block of a conduction sweep's order."""
    return np.stack([order.node[order.block_ptr[:-1]], order.node[order.block_ptr[1:] - 1]], axis=1)


def _stage_time(loads, h: float, step: int, tau: float) -> float:
    """:func:`thermonet.loads.elements.stage_time`, the same operations in the same order."""
    return loads.clock[0] + ((loads.clock[1] + step) + tau) * h


def _root_lists(of, size: int, rank: int) -> list | None:
    """[of(q) for every process q] on rank 0 (what it places), None elsewhere."""
    return [of(q) for q in range(size)] if rank == 0 else None


#: what the whole x, p (and Φ) of a state are on ranks > 0 while only the shares are up to date
#: (empty: a read that skipped DistributedStepper.sync fails instead of seeing old values)
_RELEASED_NODES, _RELEASED_SPRINGS = np.empty((0, 3)), np.empty(0)
_RELEASED_NODES.flags.writeable = _RELEASED_SPRINGS.flags.writeable = False

#: how far the whole arrays are up to date with the shares (DistributedStepper._fresh): on every
#: process, on rank 0, on rank 0 but for Φ (a diagnostics row's), nowhere
ALL, ROOT, ROW, NONE = "all", "root", "row", "none"


class ShareBackup:
    """A copy of a process's share: x, p (nl, 3), Φ, η (ml,); logs: each per-spring heat log at
    the springs the process reports; extra: the rest of the state's ``extra``; the ``step`` and
    ``time`` the runner sets."""

    def __init__(self, x, p, phi, eta):
        self.x, self.p, self.phi, self.eta = x, p, phi, eta
        self.logs: dict = {}
        self.extra: dict = {}
        self.step, self.time = 0, 0.0

    @classmethod
    def like(cls, stepper) -> "ShareBackup":
        return cls(*(np.empty_like(a) for a in stepper._share_arrays()))

    def arrays(self) -> tuple:
        return self.x, self.p, self.phi, self.eta


class _OwnedGather:
    """Where each process's owned nodes and reported springs go in the whole state: one
    ``Gatherv`` to rank 0 of [x (3 n_q), p (3 n_q), η (m_q, with conduction), Φ (m_q)] per
    process q, or, for a diagnostics row (which does not read Φ), of all but Φ. Rank 0 alone
    holds the whole-net index lists and the receive buffer; each process the user's numbers of
    its own nodes and springs (its checkpoint piece names them: :mod:`thermonet.parallel.pieces`).

    local_nodes, local_springs: (n_r,), (m_r,) int64 positions in the share of the owned nodes and
    reported springs; user_nodes, user_springs: the same nodes and springs in the user's numbering.
    """

    def __init__(self, dec, sh, thermal: bool, conducting: bool, rank: int, layout):
        self.thermal, self.conducting = thermal, conducting
        self.local_nodes = np.flatnonzero(sh.owned)
        self.local_springs = np.searchsorted(sh.springs, dec.owned_springs(rank))
        self.user_nodes = np.take(layout.node_order, sh.nodes[self.local_nodes]).astype(np.int64)
        self.user_springs = np.take(layout.spring_order, sh.springs[self.local_springs]).astype(np.int64)
        node_counts = np.bincount(dec.owner, minlength=dec.size)
        spring_counts = np.bincount(dec.spring_owner, minlength=dec.size)
        row = 6 * node_counts + (spring_counts if conducting else 0)
        #: (counts, offsets) of a whole gather (True) and of a row's (False)
        self.layout = {True: counts_offsets(row + (spring_counts if thermal else 0)), False: counts_offsets(row)}
        self.rank = rank
        self.root = rank == 0
        self.nodes = _root_lists(dec.owned_nodes, dec.size, rank) or []
        self.springs = _root_lists(dec.owned_springs, dec.size, rank) or []
        self.recv = np.empty(int(self.layout[True][0].sum())) if self.root else None

    def whole_arrays(self, state) -> list:
        """The whole arrays a whole gather fills."""
        arrays = [state.positions, state.momenta]
        if self.conducting:
            arrays.append(state.entropy)
        if self.thermal:
            arrays.append(state.thermal_displacement)
        return arrays

    def to_root(self, comm, state, x, p, phi, eta, whole: bool = True) -> None:
        """The owned rows of x, p (nl, 3) and reported springs of η (with conduction) and, where
        ``whole``, Φ (ml,) of every process into ``state``'s whole arrays on rank 0."""
        n, m = len(self.local_nodes), len(self.local_springs)
        send = np.empty(int(self.layout[whole][0][self.rank]))  # (only while gathering: a share's x, p, η, Φ)
        send[:3 * n] = x[self.local_nodes].ravel()
        send[3 * n:6 * n] = p[self.local_nodes].ravel()
        at = 6 * n
        if self.conducting:
            send[at:at + m] = eta[self.local_springs]
            at += m
        with_phi = whole and self.thermal
        if with_phi:
            send[at:at + m] = phi[self.local_springs]
            at += m
        counts, offsets = self.layout[whole]
        recv = gather_to_root(comm, send[:at], counts, offsets, self.recv)
        if recv is None:
            return
        for q, (nodes, springs) in enumerate(zip(self.nodes, self.springs)):
            k, j = len(nodes), len(springs)
            at = offsets[q]
            state.positions[nodes] = recv[at:at + 3 * k].reshape(k, 3)
            state.momenta[nodes] = recv[at + 3 * k:at + 6 * k].reshape(k, 3)
            at += 6 * k
            if self.conducting:
                state.entropy[springs] = recv[at:at + j]
                at += j
            if with_phi:
                state.thermal_displacement[springs] = recv[at:at + j]


#: the heat logs each process keeps per share (DistributedConduction.share_logs)
SHARE_LOGS = PER_SPRING_LOGS + ENTRY_LOGS


def _without(extra: dict, logs: list) -> dict:
    """``extra`` without the heat logs named in ``logs`` (a shallow copy; nothing copied where none)."""
    if not logs:
        return extra
    heat = {k: v for k, v in extra["heat"].items() if k not in logs}
    return {**extra, "heat": heat}


def threads_per_process(comm) -> int:
    """The cores this process may use divided by the processes of ``comm`` on its machine (≥ 1)."""
    import os

    from mpi4py import MPI

    local = comm.Split_type(MPI.COMM_TYPE_SHARED)
    try:
        on_machine = local.Get_size()
    finally:
        local.Free()
    affinity = getattr(os, "sched_getaffinity", None)
    cores = len(affinity(0)) if affinity is not None else (os.cpu_count() or 1)
    return max(1, cores // on_machine)


#: environment variable choosing the partitioner ("rcb", "metis" or "blocks"; the default: "blocks"
#: with conduction, else "rcb")
PARTITION_VARIABLE = "THERMONET_PARTITION"


def distribute(sim, comm, method: str | None = None) -> DistributedStepper:
    """The stepper of ``sim`` (rank 0's, built whole) over the processes of ``comm`` (its effects
    checked first); method: the partitioner, default ``$THERMONET_PARTITION`` or "blocks" with
    conduction, else "rcb". No message is exchanged (rank 0 alone builds:
    :mod:`thermonet.parallel.ship`)."""
    import os

    from .support import check_support

    method = method or os.environ.get(PARTITION_VARIABLE) or None
    check_support(sim, comm.Get_size())
    points = sim.layout.nodes_to_internal(np.asarray(sim.net.positions, dtype=np.float64))
    stepper = DistributedStepper(sim.integrator, sim.system, comm, points, sim.parallel, method)
    if stepper.loads is not None:
        stepper.loads.time_origin = sim.time_origin  # the run's clock, as assemble() does
    return stepper
