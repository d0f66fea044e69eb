"""The records only the implicit integrators' kernels take: named tuples of arrays (and a few
scalars), which Numba passes as heterogeneous tuples and unpacks inside compiled code at no cost.
The springs, the nodes and a state's arrays are the explicit kernels' records
(:class:`~thermonet.kernels.records.Springs`, :class:`~thermonet.kernels.records.Nodes`,
:class:`~thermonet.kernels.records.StateArrays`): one record per concept. The topology is not:
the explicit gather reads each incidence's other end, Newton's system each incidence's sign and
the free nodes' blocks of unknowns (:class:`BlockTopology`).

Shapes: n nodes, m springs, k parameters per spring, n_free free nodes, B unknowns per free node
(3 for GTR-α, 6 for HO4), size = B n_free. Per-spring arrays are component-major, (k, m).

The kernels unpack each record by position, in the order of its fields, at their top (so their
loops compile as with separate arguments), and are called with :func:`plain` tuples: Numba
types a named tuple's argument ≈ 0.6 µs slower per record and call than a plain tuple, ≈ 40 µs
per implicit step, which a small net would feel.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


def plain(record) -> tuple:
    """``record`` as a plain tuple, its nested record (a work record's ``start``, its first
    field) too: what the kernels are called with."""
    first = record[0]
    if isinstance(first, tuple):
        return (tuple(first),) + record[1:]
    return tuple(record)


class BlockTopology(NamedTuple):
    """The net's connectivity as Newton's system reads it (internal numbering): the springs'
    ends, each free node's block of unknowns, the incidence with its signs.

    edges: (m, 2) uint32, the springs' end nodes (read as unsigned).
    free_index: (n,) int64, the block of unknowns of each node (−1: anchored).
    ends: (m, 2) int32, ``free_index`` of each spring's ends (the matrix-free sweeps').
    inc_ptr: (n + 1,), inc_spring: (2m,) uint32, inc_sign: (2m,) int8: the node → spring
        incidence (CSR), with the spring's sign at that node (+1 at its first end).
    """

    edges: np.ndarray
    free_index: np.ndarray
    ends: np.ndarray
    inc_ptr: np.ndarray
    inc_spring: np.ndarray
    inc_sign: np.ndarray


class StepStart(NamedTuple):
    """The state a step starts from: positions x0 (n, 3), momenta p (n, 3), entropy eta (m,),
    and the step h."""

    x0: np.ndarray
    p: np.ndarray
    eta: np.ndarray
    h: float


class Residuals(NamedTuple):
    """R, Rabs: (size,) the residual and the sum of the magnitudes of each row's terms; peak:
    (2, n_free) each free node's largest |R| and Rabs (HO4; (2, 0) where a scheme has none)."""

    R: np.ndarray
    Rabs: np.ndarray
    peak: np.ndarray


class BlockPlaces(NamedTuple):
    """Where the Jacobian's blocks lie in the CSR value array (solvers.pattern.BlockPattern):
    node_base, node_stride (n_free,) int64 for the diagonal blocks; spring_base, spring_stride
    (m, 4) int64 for the blocks (a,a), (a,b), (b,a), (b,b) of spring e = (a, b), −1 where an
    end is anchored; block (6, 6): scratch for one spring's block (the kernels allocate nothing).
    """

    node_base: np.ndarray
    node_stride: np.ndarray
    spring_base: np.ndarray
    spring_stride: np.ndarray
    block: np.ndarray


class StartWork(NamedTuple):
    """The start kernel's per-spring record, part of every scheme's work record (``work.start``).

    len0: (m,), dir0: (3, m) lengths and unit vectors at x⁰; keep: (KEEP_ROWS, m), or
    (KEEP_ROWS, 0) without KEEP_START, what the start kernel keeps of the step's start for the
    residuals; fs: (6, m) per-spring force terms; ws: (B, m) scratch of the predictor's second
    rate (RATE 2, B = 6), the same memory as ``sweep``, (m, B), the matrix-free sweeps' scratch
    (the start kernel's use ends first); nodal: (n + 1, 6), or (0, 6) below RATE 2, each node's
    acceleration and jerk, and in its last row, column 0, the step h of the last committed step
    whose converged unknowns the unknown vector still holds, 0 if none (:attr:`history`); guess:
    (m,) thermal seeds; code: (m,) int8 per-spring status.
    """

    len0: np.ndarray
    dir0: np.ndarray
    keep: np.ndarray
    fs: np.ndarray
    ws: np.ndarray
    sweep: np.ndarray
    nodal: np.ndarray
    guess: np.ndarray
    code: np.ndarray

    @classmethod
    def allocate(cls, n: int, m: int, block: int, keep_rows: int, keep: bool, rate: int) -> "StartWork":
        ws = np.empty((block, m))
        return cls(len0=np.empty(m), dir0=np.empty((3, m)), keep=np.empty((keep_rows, m if keep else 0)),
                   fs=np.empty((6, m)), ws=ws, sweep=ws.reshape(m, block), nodal=np.zeros((n + 1 if rate > 1 else 0, 6)),
                   guess=np.empty(m), code=np.zeros(m, dtype=np.int8))

    @property
    def history(self) -> np.ndarray:
        """A (1,) view of the committed step's h (``nodal``'s last row; set where a step is
        committed, the compiled driver and ImplicitStepper; read and cleared by the start kernel,
        whose predictor extrapolates from it for HO4), empty below RATE 2. (A field of its own
        would have made every kernel's record a tuple longer, which cost the paper's chain 0.4 µs
        per step.)"""
        return self.nodal[self.nodal.shape[0] - 1:, 0] if self.nodal.shape[0] else self.nodal[:0, 0]
