"""The sparsity of the implicit integrators' Newton matrix: B unknowns per free node, the springs
coupling the blocks of their two ends, so the block sparsity of the node graph. Built once per
net as a scalar CSR structure with the block rows in a fill-reducing order, together with each
spring's and node's block places in the CSR value array (the kernels refill only the values,
every iteration).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import InputError


@dataclass(frozen=True, eq=False)
class BlockPattern:
    """The Jacobian's sparsity for B unknowns per free node, built once per net.

    block: B. n_free: free nodes. size: B n_free unknowns.
    free_index: (n,) int64, block row of each internal node (−1 on anchored nodes).
    indptr (size+1,), indices (nnz,): scalar CSR structure (int32), block rows in fill-reducing
        order, each block stored row-major inside its block row.
    node_base, node_stride: (n_free,) int64, data index of the (0, 0) entry of diagonal block k
        and the distance between its rows.
    spring_base, spring_stride: (m, 4) int64, the same for the blocks (a,a), (a,b), (b,a),
        (b,b) of spring e = (a, b); −1 where an end is anchored.
    """

    block: int
    n_free: int
    free_index: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray
    node_base: np.ndarray
    node_stride: np.ndarray
    spring_base: np.ndarray
    spring_stride: np.ndarray

    @property
    def size(self) -> int:
        return self.block * self.n_free

    @property
    def nnz(self) -> int:
        return len(self.indices)

    @functools.cached_property
    def transpose(self) -> np.ndarray:
        """(nnz,) int64: data[transpose] are the values of the transposed matrix in this same
        structure (the block sparsity is symmetric), so the CSR arrays with them read as CSC
        are the matrix itself (SuperLU then solves without transposing: 15–20 % faster solves
        at 47 637 unknowns)."""
        rows = np.repeat(np.arange(self.size, dtype=np.int64), np.diff(self.indptr))
        cols = self.indices.astype(np.int64)
        return np.searchsorted(rows * self.size + cols, cols * self.size + rows)

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """The CSR matrix with these values (shares ``data``)."""
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.size, self.size))

    @classmethod
    def build(cls, edges: np.ndarray, anchored: np.ndarray, block: int, ordering: str = "mmd") -> "BlockPattern":
        """Pattern for springs ``edges`` (m, 2) on nodes with ``anchored`` (n,) bool.

        ordering: "mmd" (minimum degree, computed once; on nets of METIS_MIN_NODES free nodes
        or more METIS's nested dissection, where pymetis is installed), or "natural" (the
        layout's own reverse Cuthill–McKee numbering)."""
        n = len(anchored)
        B = int(block)
        free_nodes = np.flatnonzero(~anchored)
        nf = len(free_nodes)
        rank = np.full(n, -1, dtype=np.int64)
        rank[free_nodes] = np.arange(nf)
        ea, eb = rank[edges[:, 0]], rank[edges[:, 1]]
        both = (ea >= 0) & (eb >= 0)
        order = _node_ordering(ea[both], eb[both], nf, ordering)
        new_of = np.empty(nf, dtype=np.int64)
        new_of[order] = np.arange(nf)
        free_index = np.full(n, -1, dtype=np.int64)
        free_index[free_nodes] = new_of
        ka = free_index[edges[:, 0]]
        kb = free_index[edges[:, 1]]
        both = (ka >= 0) & (kb >= 0)
        rows = np.concatenate([np.arange(nf), ka[both], kb[both]])
        cols = np.concatenate([np.arange(nf), kb[both], ka[both]])
        keys = np.unique(rows * nf + cols)
        brow, bcol = keys // nf, keys % nf
        bptr = np.zeros(nf + 1, dtype=np.int64)
        np.cumsum(np.bincount(brow, minlength=nf), out=bptr[1:])
        nb = np.diff(bptr)  # blocks per block row

        # scalar CSR: row (k, r) holds, for each block slot s of block row k, columns B bcol + c
        row_len = np.repeat(B * nb, B)
        indptr = np.zeros(B * nf + 1, dtype=np.int64)
        np.cumsum(row_len, out=indptr[1:])
        slot_cols = B * bcol[:, None] + np.arange(B)[None, :]  # (nnzb, B)
        indices = _scalar_indices(slot_cols, bptr, B)

        def place(r, c):
            """(base, stride) of block (r, c); −1 where r or c < 0."""
            r = np.asarray(r)
            c = np.asarray(c)
            ok = (r >= 0) & (c >= 0)
            key = np.where(ok, r * nf + c, 0)
            pos = np.searchsorted(keys, key)
            rr = np.where(ok, r, 0)
            slot = pos - bptr[rr]
            base = B * B * bptr[rr] + slot * B
            stride = B * nb[rr]
            return np.where(ok, base, -1), np.where(ok, stride, 0)

        node_base, node_stride = place(np.arange(nf), np.arange(nf))
        sb = np.empty((len(edges), 4), dtype=np.int64)
        ss = np.empty((len(edges), 4), dtype=np.int64)
        for q, (r, c) in enumerate(((ka, ka), (ka, kb), (kb, ka), (kb, kb))):
            sb[:, q], ss[:, q] = place(r, c)
        return cls(B, nf, free_index, indptr.astype(np.int32), indices.astype(np.int32),
                   node_base.astype(np.int64), node_stride.astype(np.int64), sb, ss)


def _scalar_indices(slot_cols: np.ndarray, bptr: np.ndarray, B: int) -> np.ndarray:
    """Column indices of the scalar CSR: each block row's column list repeated for its B rows."""
    nf = len(bptr) - 1
    nb = np.diff(bptr)
    flat = slot_cols.ravel()  # block rows' column lists, concatenated
    starts = B * bptr[:-1]
    lengths = B * nb
    # for each scalar row (k, r): the range flat[starts[k] : starts[k] + lengths[k]]
    row_start = np.repeat(starts, B)
    row_len = np.repeat(lengths, B)
    offsets = np.arange(row_len.sum()) - np.repeat(np.cumsum(row_len) - row_len, row_len)
    return flat[np.repeat(row_start, row_len) + offsets] if nf else np.zeros(0, dtype=np.int64)


#: "mmd" orders nets of this many free nodes or more by METIS's nested dissection (pymetis):
#: on the steel part of benchmarks/em2_paths.py at 15 879 free nodes (97 958 springs) SuperLU's
#: factors hold 27.2e6 entries with it against 33.7e6 with minimum degree (factorization and
#: solves 10–15 % faster); at 1 724 free nodes (9 270 springs) both hold 1.1e6
METIS_MIN_NODES = 5000


def _node_ordering(ra: np.ndarray, rb: np.ndarray, nf: int, ordering: str) -> np.ndarray:
    """Fill-reducing order of the free nodes (new → old) for the graph with edges (ra, rb)."""
    if ordering == "natural" or nf <= 2:
        return np.arange(nf)
    if ordering != "mmd":
        raise InputError(f"unknown ordering {ordering!r}; known: mmd, natural")
    adj = sp.coo_matrix((np.ones(len(ra)), (ra, rb)), shape=(nf, nf))
    adj = (adj + adj.T).tocsc()
    if nf >= METIS_MIN_NODES:
        order = _nested_dissection(adj)
        if order is not None:
            return order
    degree = np.asarray(adj.sum(axis=1)).ravel()
    graph = (adj + sp.diags(degree + 1.0)).tocsc()  # diagonally dominant: no pivoting
    lu = spla.splu(graph, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                   options=dict(SymmetricMode=True))
    return np.argsort(lu.perm_c)


def _nested_dissection(adj: sp.csc_matrix) -> np.ndarray | None:
    """METIS's nested dissection of the graph ``adj`` (symmetric, (nf, nf)) as new → old,
    or None where pymetis is not installed."""
    try:
        import pymetis
    except ImportError:
        return None
    adj = (sp.triu(adj, 1) + sp.tril(adj, -1)).tocsr()  # (METIS takes no self-loops)
    if hasattr(pymetis, "CSRAdjacency"):  # (pymetis 2025 on; before, the arrays by keyword)
        perm, _ = pymetis.nested_dissection(pymetis.CSRAdjacency(adj.indptr, adj.indices))
    else:
        perm, _ = pymetis.nested_dissection(xadj=adj.indptr, adjncy=adj.indices)
    return np.asarray(perm, dtype=np.int64)
