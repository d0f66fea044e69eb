"""The whole net's arrays put together from the processes' parts: gathered to rank 0, and from
there broadcast to every process when every process reads them.

Rank 0 receives each process's part (one ``Gatherv``) and places it; a broadcast of the placed
arrays then gives them to the others. This moves each value once to rank 0 and once from it, and
needs the receive buffer on rank 0 only. (An ``Allgatherv`` of the same parts would do it in one
call; MPICH's, on one machine, took 1.1–1.7 s for 2 × 24 MB where ``Gatherv`` and ``Bcast`` each
took 0.02–0.04 s.)
"""

from __future__ import annotations

import numpy as np


def counts_offsets(counts) -> tuple[np.ndarray, np.ndarray]:
    """(counts, offsets) int64 of consecutive parts of the given sizes."""
    counts = np.asarray(counts, dtype=np.int64)
    return counts, np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)


def gather_to_root(comm, send: np.ndarray, counts: np.ndarray, offsets: np.ndarray,
                   recv: np.ndarray | None = None) -> np.ndarray | None:
    """Every process's ``send`` (counts[q] doubles from process q) concatenated in rank order on
    rank 0 (into ``recv`` (Σ counts,) where given, else a fresh array), None elsewhere."""
    from mpi4py import MPI

    root = comm.Get_rank() == 0
    if root and recv is None:
        recv = np.empty(int(counts.sum()))
    recv = recv if root else None
    comm.Gatherv(np.ascontiguousarray(send), [recv, counts, offsets, MPI.DOUBLE] if root else None, root=0)
    return recv


def broadcast(comm, arrays) -> None:
    """Rank 0's values of each array into the same arrays on every process (in place)."""
    for a in arrays:
        if a is None or a.size == 0:
            continue
        if a.flags.c_contiguous:
            comm.Bcast(a, root=0)
        else:  # (a view: sent through a contiguous copy)
            buf = np.ascontiguousarray(a)
            comm.Bcast(buf, root=0)
            a[...] = buf


class IndexGather:
    """Whole-net arrays from each process's part: process q gives the values at whole indices
    ``parts[q]``, taking them from positions ``local`` of its own arrays; several arrays per call.

    parts: one (k_q,) int64 array per process, needed on rank 0 only (None elsewhere); local:
    (k_r,) int64 positions in this process's arrays of the values it gives, or None: all of them,
    in order; counts: (P,) the k_q (default: from parts).
    """

    def __init__(self, parts: list | None, local: np.ndarray | None, counts=None):
        self.parts, self.local = parts, None if local is None else np.asarray(local, dtype=np.int64)
        self.counts = np.asarray([len(p) for p in parts] if counts is None else counts, dtype=np.int64)

    def to_root(self, comm, pairs: list) -> None:
        """For each (local array, whole array) of ``pairs``: on rank 0, whole[parts[q]] ← q's values."""
        k = len(pairs)
        if k == 0:
            return
        send = np.concatenate([local if self.local is None else np.take(local, self.local) for local, _ in pairs])
        counts, offsets = counts_offsets(k * self.counts)
        recv = gather_to_root(comm, send, counts, offsets)
        if recv is None:
            return
        for q, (count, offset) in enumerate(zip(self.counts, offsets)):
            chunk = recv[offset:offset + k * count].reshape(k, count)
            for j, (_, whole) in enumerate(pairs):
                whole[self.parts[q]] = chunk[j]

    def gather(self, comm, pairs: list) -> None:
        """As :meth:`to_root`, then the whole arrays broadcast to every process."""
        self.to_root(comm, pairs)
        broadcast(comm, [whole for _, whole in pairs])


def broadcast_value(comm, value):
    """Rank 0's ``value`` (ignored elsewhere) on every process: its NumPy arrays, wherever they
    sit in dicts, lists, tuples or a dataclass's fields, sent as buffers (``Bcast``, no pickling
    of their bytes), the rest pickled once with the arrays' shapes and types."""
    root = comm.Get_rank() == 0
    arrays: list = []
    skeleton = comm.bcast(_skeleton(value, arrays) if root else None, root=0)
    if root:
        for a in arrays:
            comm.Bcast(a, root=0)
        return value
    received: list = []
    out = _fill(skeleton, received)
    for a in received:
        comm.Bcast(a, root=0)
    return out


class _ArraySlot:
    """Where an array goes in a broadcast value: its shape and type."""

    def __init__(self, a: np.ndarray):
        self.shape, self.dtype = a.shape, a.dtype


def _map_leaves(value, is_leaf, leaf):
    """``value`` with each part for which ``is_leaf`` holds replaced by ``leaf(part)``, found
    through dicts, lists, tuples (named ones too) and a dataclass's fields, in that order."""
    import dataclasses

    def walk(v):
        if is_leaf(v):
            return leaf(v)
        if isinstance(v, dict):
            return {k: walk(w) for k, w in v.items()}
        if isinstance(v, tuple) and hasattr(v, "_fields"):  # (a named tuple)
            return type(v)(*(walk(w) for w in v))
        if isinstance(v, (list, tuple)) and type(v) in (list, tuple):
            return type(v)(walk(w) for w in v)
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            return dataclasses.replace(v, **{f.name: walk(getattr(v, f.name)) for f in dataclasses.fields(v) if f.init})
        return v

    return walk(value)


def _skeleton(value, arrays: list):
    """``value`` with an :class:`_ArraySlot` in place of each NumPy array (the arrays, contiguous,
    appended to ``arrays`` in the order met)."""
    def slot(a):
        arrays.append(np.ascontiguousarray(a))
        return _ArraySlot(a)

    return _map_leaves(value, lambda v: isinstance(v, np.ndarray), slot)


def _fill(skeleton, received: list):
    """The value of ``skeleton`` with an empty array in each slot (appended to ``received``)."""
    def empty(s):
        received.append(np.empty(s.shape, s.dtype))
        return received[-1]

    return _map_leaves(skeleton, lambda v: isinstance(v, _ArraySlot), empty)
