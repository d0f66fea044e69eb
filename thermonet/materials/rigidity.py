"""Is a net rigid? Zero-frequency modes beyond the rigid-body ones (a mechanism).

A central-force net is rigid when its linear stiffness, springs of any positive stiffness, has
no zero modes besides the d(d+1)/2 rigid motions of its own dimension d (6 in 3D; 3 in-plane
for a flat 2D net, whose out-of-plane motion a membrane never resists; 1 along a line). A mesh of
hexahedra without diagonals is not: its cubes shear freely.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from ..errors import InputError

#: nets with more degrees of freedom than this are checked by Maxwell's count only
EXACT_DOFS = 30000
_DENSE_DOFS = 60
_ZERO = 1e-8  # eigenvalues of the Jacobi-scaled stiffness below this are zero modes


class FloppyModes(NamedTuple):
    """count: zero modes beyond the rigid ones (at least this many when not ``exact``);
    rigid: the rigid-body modes of dimension ``dimension``; method: how it was counted."""

    count: int
    exact: bool
    rigid: int
    dimension: int
    method: str


def net_dimension(net) -> int:
    """The dimension a net is rigid or elastic in: its cells' for triangles, quads and 3D cells
    (``Net.cell_dimension``), else (line cells: a bar or a truss) the dimension its nodes span."""
    if net.cell_dimension >= 2:
        return int(net.cell_dimension)
    return span_dimension(net.positions)


def span_dimension(positions: np.ndarray) -> int:
    """How many dimensions the points span (singular values above 1e-9 of the largest)."""
    x = positions - positions.mean(axis=0)
    s = np.linalg.svd(x, compute_uv=False)
    return int(max(1, (s > 1e-9 * max(s[0], 1e-300)).sum()))


def principal_frame(positions: np.ndarray, d: int) -> tuple[np.ndarray, np.ndarray]:
    """(centre (3,), axes (d, 3)): the net's centroid and the d principal directions it spans
    (the coordinate axes when d = 3, so that 3D tensors read in x, y, z)."""
    centre = positions.mean(axis=0)
    if d == 3:
        return centre, np.eye(3)
    _, _, vt = np.linalg.svd(positions - centre, full_matrices=False)
    axes = vt[:d]
    for a in axes:  # a readable sign: the largest component positive
        if a[np.argmax(np.abs(a))] < 0:
            a *= -1.0
    return centre, axes


def stiffness(positions: np.ndarray, edges: np.ndarray, k: np.ndarray, axes: np.ndarray) -> sp.csr_matrix:
    """(d n, d n) linear stiffness of central springs k (m,) in the frame ``axes`` (d, 3):
    spring e's block k_e n n^T, n its unit direction in that frame. Node i's coordinate a is
    row d i + a."""
    d = len(axes)
    diff = positions[edges[:, 1]] - positions[edges[:, 0]]
    n = diff @ axes.T
    n /= np.linalg.norm(diff, axis=1)[:, None]
    block = k[:, None, None] * n[:, :, None] * n[:, None, :]
    a, b = edges[:, 0].astype(np.int64), edges[:, 1].astype(np.int64)
    ii, jj = np.meshgrid(np.arange(d), np.arange(d), indexing="ij")
    rows, cols, vals = [], [], []
    for u, v, sign in ((a, a, 1.0), (b, b, 1.0), (a, b, -1.0), (b, a, -1.0)):
        rows.append((d * u[:, None, None] + ii[None]).ravel())
        cols.append((d * v[:, None, None] + jj[None]).ravel())
        vals.append((sign * block).ravel())
    size = d * len(positions)
    return sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(size, size)).tocsr()


def floppy_modes(net) -> FloppyModes:
    """Count the net's zero modes beyond the rigid ones (unit spring stiffnesses: rigidity is
    geometry). Exact up to :data:`EXACT_DOFS` degrees of freedom (eigenvalues of the
    Jacobi-scaled stiffness; shift-invert Lanczos above a small size, asking for a dozen modes
    beyond the rigid ones, or Maxwell's count d n − d(d+1)/2 − m plus six, at most 200: "at least"
    when all it found are zero), Maxwell's count (a lower bound) above."""
    d = net_dimension(net)
    rigid = d * (d + 1) // 2
    n, m = net.n_nodes, net.n_springs
    dofs = d * n
    maxwell = max(0, dofs - rigid - m)
    if dofs > EXACT_DOFS:
        return FloppyModes(maxwell, False, rigid, d, "Maxwell count (a lower bound)")
    _, axes = principal_frame(net.positions, d)
    K = stiffness(net.positions, net.edges, np.ones(m), axes)
    diag = K.diagonal()
    diag = np.where(diag > 0, diag, 1.0)  # a coordinate no spring pulls along: a zero row, a zero mode
    scale = sp.diags(1.0 / np.sqrt(diag))
    Ks = (scale @ K @ scale).tocsc()
    if dofs <= _DENSE_DOFS:
        lam = np.linalg.eigvalsh(Ks.toarray())
        return FloppyModes(max(0, int((lam < _ZERO).sum()) - rigid), True, rigid, d, "eigenvalues")
    from scipy.sparse.linalg import eigsh

    want = min(rigid + min(max(12, maxwell + 6), 200), dofs - 2)
    lam = eigsh(Ks, k=want, sigma=-1e-3, which="LM", return_eigenvectors=False)
    zero = int((lam < _ZERO).sum())
    if zero < want:
        return FloppyModes(max(0, zero - rigid), True, rigid, d, "shift-invert Lanczos")
    return FloppyModes(max(zero - rigid, maxwell), False, rigid, d, "shift-invert Lanczos (at least)")


def require_rigid(net, where: str) -> FloppyModes:
    """:func:`floppy_modes`, and an InputError naming ``where`` when the net is a mechanism."""
    found = floppy_modes(net)
    note = net.pieces_note() if found.count > 0 else None
    if note is not None:  # the zero modes are the pieces' rigid motions: no other mesh would help
        raise InputError(f"{where}: {note.replace('the net is', f'the net of {net.source} is', 1)}; continuum "
                         f"materials need one rigid net")
    if found.count > 0:
        many = "" if found.exact else "at least "
        raise InputError(
            f"{where}: the net of {net.source} is a mechanism: {many}{found.count} zero-frequency mode(s) beyond "
            f"the {found.rigid} rigid-body ones of a {found.dimension}D net ({found.method}). Continuum materials "
            "need a rigid net: mesh with tetrahedra (triangles in 2D), or add diagonals to hexahedra and quads")
    return found
