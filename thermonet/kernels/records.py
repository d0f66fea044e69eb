"""The records the explicit kernels take: a few named tuples of arrays, grouped by what they
describe. Numba passes a named tuple of arrays like the arrays themselves (a struct of pointers,
unpacked once per call), on the CPU and on CUDA alike.

Arrays are in the internal numbering (:class:`~thermonet.layout.Layout`); index arrays are
unsigned views (a negative-index test per access would otherwise cost a third of the gather
pass and block vectorization).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .blocks import BLOCK
from .exact import WIDTH
from .reductions import NODE_SUMS, closing_chunks


class Topology(NamedTuple):
    """Which springs join which nodes.

    edges: (m, 2) uint32; inc_ptr: (n+1,) int64 CSR offsets of each node's incident springs;
    inc_spring, inc_other: (2m,) uint32, the incident spring and the node at its other end.
    """

    edges: np.ndarray
    inc_ptr: np.ndarray
    inc_spring: np.ndarray
    inc_other: np.ndarray


class Springs(NamedTuple):
    """Per-spring data: rest (m,) rest lengths; P (k, m) model parameters, or (k, 1) when every
    spring has the same (see :func:`thermonet.kernels.specialize.kernel_parameters`)."""

    rest: np.ndarray
    P: np.ndarray


class Nodes(NamedTuple):
    """Per-node data: masses, inv_mass (n,) (inv_mass 0 on anchors); anchored (n,) bool;
    gravity (3,) acceleration, applied when with_gravity; reference (3,) the point angular
    momentum is taken about."""

    masses: np.ndarray
    inv_mass: np.ndarray
    anchored: np.ndarray
    gravity: np.ndarray
    with_gravity: bool
    reference: np.ndarray


class StateArrays(NamedTuple):
    """The state a step changes: x, p (n, 3); phi, eta (m,) (empty when not thermal)."""

    x: np.ndarray
    p: np.ndarray
    phi: np.ndarray
    eta: np.ndarray


class Scratch(NamedTuple):
    """A stepper's buffers: x_buf (n, 3) the other position buffer; s (m,) T/l per spring;
    f_keep (n, 3) and theta_keep (m,) a call's closing forces and temperatures; energy_buf (m,)
    each spring's internal energy at a call's end; sums (2,) the closing spring pass's min θ and
    max θ; node_accs (C, len(NODE_SUMS), WIDTH) int64 the closing node pass's exact node sums per
    chunk and node_terms (C, len(NODE_SUMS) + 1, BLOCK) its terms per chunk (C: :func:`scratch`)."""

    x_buf: np.ndarray
    s: np.ndarray
    f_keep: np.ndarray
    theta_keep: np.ndarray
    energy_buf: np.ndarray
    sums: np.ndarray
    node_accs: np.ndarray
    node_terms: np.ndarray


def scratch(n: int, m: int, thermal: bool) -> Scratch:
    """A stepper's buffers for n nodes and m springs (see :class:`Scratch`)."""
    chunks = closing_chunks(n)
    return Scratch(np.empty((n, 3)), np.empty(m), np.empty((n, 3)), np.empty(m if thermal else 0), np.empty(m),
                   np.empty(2), np.zeros((chunks, len(NODE_SUMS), WIDTH), dtype=np.int64),
                   np.empty((chunks, len(NODE_SUMS) + 1, BLOCK)))


class KickDrift(NamedTuple):
    """A node pass's work (each a fraction of h already multiplied by h): two kicks of p by the
    node's force, added one after the other (kick1, then kick2), then the drift of x by p/m;
    with_force: the stage has a force evaluation (else the spring pass before it is skipped)."""

    kick1: float
    kick2: float
    drift: float
    with_force: bool


class Run(NamedTuple):
    """What one call does: n_steps of h from time t0; track_phi (False for NM2); admissible
    stretches (stretch_min, stretch_max); reuse_boundary (the previous call's closing forces
    are valid here); want_sums (reduce the end state's diagnostics sums); conduction_every:
    the steps k of one conduction cycle ``K(k h/2) ∘ A(h)^k ∘ K(k h/2)`` (1: every step);
    cycle_step: how many steps of its cycle the state has made at the call's start (0..k−1)."""

    h: float
    t0: float
    n_steps: int
    track_phi: bool
    stretch_min: float
    stretch_max: float
    reuse_boundary: bool
    want_sums: bool
    conduction_every: int = 1
    cycle_step: int = 0


class Heat(NamedTuple):
    """Heat flow (docs/heat.md): the conduction sweep's order and factors, the thermal waves'
    coloured spring pairs, the bath and source entries, and the logs (all arrays empty when heat
    flow is off; the kernels then compile its code out).

    Conduction (:mod:`thermonet.heat.exchange`): star_colour_ptr (C+1,) int64, colour c is blocks
    star_colour_ptr[c]:star_colour_ptr[c+1] (no two blocks of a colour share a spring); block_ptr
    (B+1,) int64, block b is the junction nodes block_node[block_ptr[b]:block_ptr[b+1]] (int64),
    swept in that order; inc_ptr (n+1,) int64 and inc_spring (2m,) uint32 each node's springs;
    weight, decay: (2m,) a = C (1 − exp(−g τ/C)) and exp(−g τ/C) for the sweep's τ, of the
    spring of each incidence (inc_spring's order), or (1,) when all springs share them, with
    factor_mask (1,) uint64: all ones, or 0 for the shared ones (an incidence j reads element
    j & mask); node_scale: (n,) 1 / Σ a over each node's incidences (0 where that is 0); sweeps:
    (1,) int64 j, the half sweeps over τ of each half of a cycle boundary (sub-sweeps, see
    :mod:`thermonet.heat.multirate`; 1: one reverse half sweep ends a cycle, one forward starts it).
    Thermal waves: first, second: (P,) int32 springs of each pair; wave: (P,) k* of each pair;
    colour_ptr: (K+1,) int64, colour c is pairs colour_ptr[c]:colour_ptr[c+1] (no two share a spring).
    capacity, inv_capacity: (m,) C and 1/C per spring; bound_spring: (S,) int64 springs with
    bath ends or sources; bound_ptr: (S+1,) int64 their entries; entry_kind (E,) int64 (0 bath,
    1 source), entry_fn (E,) int64 the entry's time function, entry_decay (E,) exp(−g τ/C) of a
    bath end for the sweep's τ (:func:`thermonet.heat.setup.entry_decay`);
    fn_*: the time functions (:func:`thermonet.timefunctions.pack`); produced: (m,) cumulative
    entropy produced, per spring; entry_heat, entry_flux: (E,) cumulative heat given and entropy
    brought by each entry; theta, length: (m,) the springs' temperatures and lengths where a call
    ended, valid for the next call when theta_ok[0] ≥ 1 (a call continues its predecessor's
    sweeps bit for bit); pending_eta, pending_produced, pending_theta: (m,) when theta_ok[0] == 2,
    the entropies, production log and temperatures before the reverse half sweep that ended the
    last call (the CPU's explicit kernel: the next call's forward half sweep continues from them,
    so that the entropy update covers both half sweeps as in one call); s_before, theta_start,
    strain: (m,) working arrays (the forces of a kick deferred past the sweeps; the temperatures
    the sweeps started from; the model's strain of each kept length, ``Model.strain``, valid
    where the CPU kernel's last spring pass of the call kept it).
    """

    star_colour_ptr: np.ndarray
    block_ptr: np.ndarray
    block_node: np.ndarray
    inc_ptr: np.ndarray
    inc_spring: np.ndarray
    weight: np.ndarray
    decay: np.ndarray
    factor_mask: np.ndarray
    node_scale: np.ndarray
    sweeps: np.ndarray
    first: np.ndarray
    second: np.ndarray
    wave: np.ndarray
    colour_ptr: np.ndarray
    capacity: np.ndarray
    inv_capacity: np.ndarray
    bound_spring: np.ndarray
    bound_ptr: np.ndarray
    entry_kind: np.ndarray
    entry_fn: np.ndarray
    entry_decay: np.ndarray
    fn_kind: np.ndarray
    fn_params: np.ndarray
    fn_ptr: np.ndarray
    fn_times: np.ndarray
    fn_values: np.ndarray
    produced: np.ndarray
    entry_heat: np.ndarray
    entry_flux: np.ndarray
    theta: np.ndarray
    theta_ok: np.ndarray
    length: np.ndarray
    pending_eta: np.ndarray
    pending_produced: np.ndarray
    pending_theta: np.ndarray
    s_before: np.ndarray
    theta_start: np.ndarray
    strain: np.ndarray


def no_heat() -> Heat:
    """The :class:`Heat` record of a run without heat flow (empty arrays)."""
    i = np.empty(0, dtype=np.int64)
    f = np.empty(0)
    i32 = np.empty(0, dtype=np.int32)
    ptr = np.zeros(1, dtype=np.int64)
    return Heat(ptr, ptr, i, ptr, np.empty(0, dtype=np.uint32), f, f, np.zeros(1, dtype=np.uint64), f,
                np.ones(1, dtype=np.int64), i32, i32, f, ptr, f, f, i, ptr, i, i, f,
                i, np.empty((0, 4)), ptr, f, f, f, f, f, f, np.zeros(1), f, f, f, f, f, f, f)


class NoHeat(NamedTuple):
    """What the CPU step reads of a :class:`Heat` record when heat does not flow (its heat-flow
    code compiled out): five empty arrays instead of the whole record's 38, each of which the
    dispatcher would otherwise unbox at every call."""

    s_before: np.ndarray
    length: np.ndarray
    theta_ok: np.ndarray
    theta: np.ndarray
    strain: np.ndarray


def no_heat_cpu() -> NoHeat:
    """The CPU step's heat argument without heat flow."""
    f = np.empty(0)
    return NoHeat(f, f, np.zeros(1), f, f)


def topology(layout) -> Topology:
    """The :class:`Topology` of a :class:`~thermonet.layout.Layout`, as unsigned views."""
    return Topology(np.ascontiguousarray(layout.edges).view(np.uint32),
                    np.ascontiguousarray(layout.inc_ptr, dtype=np.int64),
                    np.ascontiguousarray(layout.inc_spring).view(np.uint32),
                    np.ascontiguousarray(layout.inc_other).view(np.uint32))


def nodes(system) -> Nodes:
    """The :class:`Nodes` record of a :class:`~thermonet.system.System`."""
    gravity = np.zeros(3) if system.gravity is None else np.asarray(system.gravity, dtype=np.float64)
    return Nodes(system.masses, system.inv_mass, np.ascontiguousarray(system.anchored, dtype=np.bool_), gravity,
                 system.gravity is not None, np.asarray(system.reference_point, dtype=np.float64))
