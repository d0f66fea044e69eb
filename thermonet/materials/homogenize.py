"""What a net is as a continuum, measured on it: the homogenized elastic tensor (uniform strains,
interior nodes relaxed, boundary nodes held to the uniform strain), the effective conductivity
(a uniform temperature gradient through the pair conductances of :mod:`thermonet.heat.graph`,
interior springs relaxed), total mass and heat capacity.

Tensors are in Voigt notation with engineering shears, in the net's frame (x, y, z in 3D; the
principal in-plane directions of a 2D net; the line of a 1D one): 3D strains (xx, yy, zz, yz,
xz, xy), 2D (11, 22, 12). Each is per unit volume (the springs' volumes V_e summed).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..builders import CELL_DIM
from ..heat.graph import pair_graph
from ..layout import build_layout
from .rigidity import principal_frame, stiffness

_VOIGT = {3: ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)), 2: ((0, 0), (1, 1), (0, 1)), 1: ((0, 0),)}

# facets (local vertex lists) of each cell type: a facet of one cell only lies on the boundary
_FACETS = {
    "line": ((0,), (1,)),
    "triangle": ((0, 1), (1, 2), (2, 0)),
    "quad": ((0, 1), (1, 2), (2, 3), (3, 0)),
    "tetra": ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2)),
    "hexahedron": ((0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)),
    "wedge": ((0, 1, 2), (3, 4, 5), (0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5)),
    "pyramid": ((0, 1, 2, 3), (0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)),
}


class Elastic(NamedTuple):
    """C: (k, k) homogenized tensor (Voigt); E, nu: the nearest isotropic material's Young's
    modulus and Poisson's ratio (plane stress in 2D); E_axes: (d,) Young's modulus along each
    frame axis (1/S_aa, S = C⁻¹); anisotropy: ‖C − C_iso‖/‖C‖ in Mandel form (0: isotropic)."""

    C: np.ndarray
    E: float
    nu: float
    E_axes: np.ndarray
    anisotropy: float


class Conductive(NamedTuple):
    """K: (d, d) effective conductivity tensor; k: its mean eigenvalue; anisotropy:
    (largest − smallest eigenvalue) / k."""

    K: np.ndarray
    k: float
    anisotropy: float


def boundary_nodes(mesh, net) -> np.ndarray:
    """(n,) bool: nodes on the surface of the mesh's cells of the highest dimension (facets
    that belong to one cell only)."""
    top = net.cell_dimension
    keys = {}
    for block in mesh.cells:
        if CELL_DIM.get(block.type) != top or block.type not in _FACETS:
            continue
        conn = np.asarray(block.data, dtype=np.int64)
        for facet in _FACETS[block.type]:
            f = np.sort(conn[:, list(facet)], axis=1)
            keys.setdefault(len(facet), []).append(f)
    point_on = np.zeros(len(mesh.points), dtype=bool)
    for facets in keys.values():
        f = np.concatenate(facets)
        uniq, counts = np.unique(f, axis=0, return_counts=True)
        point_on[uniq[counts == 1].ravel()] = True
    return point_on[net.point_ids]


def box_boundary(positions: np.ndarray, tolerance: float = 1e-9) -> np.ndarray:
    """(n,) bool: nodes on the faces of the positions' bounding box (a fallback without cells)."""
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    tol = tolerance * max(float((hi - lo).max()), 1e-300)
    span = (hi - lo) > tol
    on = (np.abs(positions - lo) <= tol) | (np.abs(positions - hi) <= tol)
    return (on & span).any(axis=1)


def elastic_tensor(positions, edges, k, volume: float, boundary, d: int) -> Elastic:
    """Homogenized elastic tensor of central springs of stiffness k (m,) (d²F/dl² at rest):
    each unit Voigt strain imposed on the boundary nodes, the interior relaxed; C_IJ = U_I·K U_J / V."""
    centre, axes = principal_frame(positions, d)
    K = stiffness(positions, edges, np.asarray(k, dtype=np.float64), axes)
    xi = (positions - centre) @ axes.T  # (n, d)
    affine = []
    for a, b in _VOIGT[d]:
        eps = np.zeros((d, d))
        eps[a, b] = eps[b, a] = 1.0 if a == b else 0.5
        affine.append((xi @ eps.T).ravel())
    U = _relax(K, np.column_stack(affine), np.repeat(~np.asarray(boundary, dtype=bool), d))
    C = U.T @ (K @ U) / volume
    C = 0.5 * (C + C.T)
    return _elastic_summary(C, d)


def conductivity_tensor(net, g, volume: float, boundary, d: int) -> Conductive:
    """Effective conductivity of spring conductances g (m,): spring temperatures θ_e = G·x_e at
    the springs' middles for springs touching a boundary node, the others relaxed, through the
    pair conductances κ_ef of :func:`thermonet.heat.graph.pair_graph`; K_ab = Θ_a·L Θ_b / V."""
    layout = build_layout(net, renumber=False)
    graph = pair_graph(layout, np.asarray(g, dtype=np.float64)[None, :])
    m = net.n_springs
    kappa = graph.kappa[:, 0]
    L = sp.coo_matrix((np.concatenate([-kappa, -kappa]),
                       (np.concatenate([graph.first, graph.second]), np.concatenate([graph.second, graph.first]))),
                      shape=(m, m)).tocsr()
    L = L - sp.diags(np.asarray(L.sum(axis=1)).ravel())
    centre, axes = principal_frame(net.positions, d)
    middle = 0.5 * (net.positions[net.edges[:, 0]] + net.positions[net.edges[:, 1]])
    theta = (middle - centre) @ axes.T  # (m, d): a unit gradient along each axis
    fixed = np.asarray(boundary, dtype=bool)[net.edges].any(axis=1)
    T = _relax(L.tocsr(), theta, ~fixed)
    Kt = T.T @ (L @ T) / volume
    Kt = 0.5 * (Kt + Kt.T)
    w = np.linalg.eigvalsh(Kt)
    mean = float(w.mean())
    return Conductive(Kt, mean, float((w[-1] - w[0]) / mean) if mean > 0 else 0.0)


def _relax(K: sp.csr_matrix, U: np.ndarray, free: np.ndarray) -> np.ndarray:
    """U with its ``free`` rows replaced by the minimizers of U·K U (the others held)."""
    U = np.array(U, dtype=np.float64)
    if free.any():
        Kff = K[free][:, free].tocsc()
        rhs = -(K[free][:, ~free] @ U[~free])
        U[free] = splu(Kff).solve(np.ascontiguousarray(rhs))
    return U


def _elastic_summary(C: np.ndarray, d: int) -> Elastic:
    if d == 1:
        E = float(C[0, 0])
        return Elastic(C, E, float("nan"), np.array([E]), 0.0)
    shear = len(C) - d
    w = np.r_[np.ones(d), np.full(shear, np.sqrt(2.0))]
    M = C * np.outer(w, w)  # Mandel form: a tensor norm
    v = np.r_[np.ones(d), np.zeros(shear)]
    J = np.outer(v, v) / d
    Kdev = np.eye(len(C)) - J
    a = float(np.trace(J @ M))  # d × bulk modulus
    b = float(np.trace(Kdev @ M)) / (len(C) - 1)  # 2 × shear modulus
    iso = a * J + b * Kdev
    bulk, mu = a / d, b / 2.0
    if d == 3:
        E, nu = 9 * bulk * mu / (3 * bulk + mu), (3 * bulk - 2 * mu) / (2 * (3 * bulk + mu))
    else:  # plane stress
        E, nu = 4 * bulk * mu / (bulk + mu), (bulk - mu) / (bulk + mu)
    S = np.linalg.inv(C)
    return Elastic(C, float(E), float(nu), 1.0 / np.diag(S)[:d],
                   float(np.linalg.norm(M - iso) / np.linalg.norm(M)))
