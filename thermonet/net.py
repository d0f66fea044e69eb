"""The spring net: point masses joined by springs, as a struct of arrays in the user's numbering."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import InputError


@dataclass
class Net:
    """Nodes (point masses) and springs (edges between two nodes).

    Attributes
    ----------
    positions: (n, 3) float64, initial node positions.
    edges: (m, 2) int32, node indices of each spring's ends (spring e joins edges[e, 0] to edges[e, 1]).
    masses: (n,) float64, node masses (> 0; ignored for anchored nodes).
    anchored: (n,) bool, nodes fixed in space.
    rest_lengths: (m,) float64, l0 per spring (> 0). Defaults to the initial lengths.
    node_groups: named node sets (e.g. a mesh's physical groups), name -> int array of node indices.
    spring_groups: named spring sets (material regions), name -> int array of spring indices.
    source: where the net came from (a file path or a generator), for messages.
    point_ids: (n,) int, for nets read from a mesh: the mesh point index of each node.
    spring_volumes: (m,) float64, for nets read from a mesh: each spring's share of the measure
        of the mesh's cells of the highest dimension (volume in 3D, area in 2D, length in 1D;
        every cell split equally over its edges; 0 for a spring of no such cell). Continuum
        materials (:mod:`thermonet.materials`) turn it into spring parameters.
    cell_dimension: the dimension of those cells (1, 2, 3); 0 when the net is not from a mesh.
    """

    positions: np.ndarray
    edges: np.ndarray
    masses: np.ndarray | None = None
    anchored: np.ndarray | None = None
    rest_lengths: np.ndarray | None = None
    node_groups: dict[str, np.ndarray] = field(default_factory=dict)
    spring_groups: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = "<net>"
    point_ids: np.ndarray | None = None
    spring_volumes: np.ndarray | None = None
    cell_dimension: int = 0

    def __post_init__(self):
        where = self.source
        try:
            x = np.array(self.positions, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise InputError(f"{where}: positions are not numbers ({exc})") from None
        if x.ndim != 2 or x.shape[1] not in (2, 3):
            raise InputError(f"{where}: positions must have shape (n, 3) (or (n, 2)), got {x.shape}")
        if x.shape[1] == 2:
            x = np.column_stack([x, np.zeros(len(x))])
        n = len(x)
        if n == 0:
            raise InputError(f"{where}: the net has no nodes")
        bad = ~np.isfinite(x).all(axis=1)
        if bad.any():
            a = int(np.flatnonzero(bad)[0])
            raise InputError(f"{where}: node {a} has a non-finite coordinate {x[a].tolist()}")
        self.positions = x

        try:
            edges = np.asarray(self.edges)
        except (TypeError, ValueError) as exc:
            raise InputError(f"{where}: edges are not integers ({exc})") from None
        if edges.size == 0:
            raise InputError(f"{where}: the net has no springs (no edges)")
        try:
            integral = np.issubdtype(edges.dtype, np.integer) or bool(np.all(np.equal(np.mod(edges, 1), 0)))
            edges = edges.astype(np.int64)
        except (TypeError, ValueError) as exc:
            raise InputError(f"{where}: edges are not integers ({exc})") from None
        if not integral:
            raise InputError(f"{where}: spring node indices must be integers")
        if edges.ndim != 2 or edges.shape[1] != 2:
            raise InputError(f"{where}: edges must have shape (m, 2), got {edges.shape}")
        bad = (edges < 0) | (edges >= n)
        if bad.any():
            e = int(np.flatnonzero(bad.any(axis=1))[0])
            raise InputError(f"{where}: spring {e} joins nodes {edges[e].tolist()} but node indices run 0..{n - 1}")
        same = edges[:, 0] == edges[:, 1]
        if same.any():
            e = int(np.flatnonzero(same)[0])
            raise InputError(f"{where}: spring {e} has both ends on node {edges[e, 0]}")
        key = np.sort(edges, axis=1)
        _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
        if (counts > 1).any():
            k = int(np.flatnonzero(counts > 1)[0])
            dup = np.flatnonzero((key == key[first[k]]).all(axis=1))
            raise InputError(
                f"{where}: springs {dup[0]} and {dup[1]} both join nodes {key[first[k]].tolist()} (duplicate spring)"
            )
        self.edges = edges.astype(np.int32)
        m = len(edges)

        lengths = self.lengths()
        zero = lengths <= 0
        if zero.any():
            e = int(np.flatnonzero(zero)[0])
            raise InputError(
                f"{where}: spring {e} (nodes {self.edges[e].tolist()}) has zero length: its two nodes coincide"
            )

        if self.masses is None:
            self.masses = np.ones(n)
        masses = _floats(self.masses, "masses", where)
        if masses.ndim == 0:
            masses = np.full(n, float(masses))
        if masses.shape != (n,):
            raise InputError(f"{where}: masses must have one value per node ({n}), got shape {masses.shape}")
        if self.anchored is None:
            self.anchored = np.zeros(n, dtype=bool)
        anchored = np.asarray(self.anchored)
        if anchored.dtype != bool:
            idx = anchored.astype(np.int64).ravel()
            if idx.size and (idx.min() < 0 or idx.max() >= n):
                raise InputError(f"{where}: anchored node index out of range 0..{n - 1}")
            anchored = np.zeros(n, dtype=bool)
            anchored[idx] = True
        if anchored.shape != (n,):
            raise InputError(f"{where}: anchored must be a boolean mask of {n} nodes or a list of node indices")
        self.anchored = anchored
        bad = ~(np.isfinite(masses) & (masses > 0)) & ~anchored
        if bad.any():
            a = int(np.flatnonzero(bad)[0])
            raise InputError(f"{where}: node {a} has mass {masses[a]}; masses must be finite and > 0")
        masses = np.where(anchored & ~(masses > 0), 1.0, masses)
        self.masses = masses

        if self.rest_lengths is None:
            self.rest_lengths = lengths.copy()
        l0 = _floats(self.rest_lengths, "rest_lengths", where)
        if l0.ndim == 0:
            l0 = np.full(m, float(l0))
        if l0.shape != (m,):
            raise InputError(f"{where}: rest_lengths must have one value per spring ({m}), got shape {l0.shape}")
        bad = ~(np.isfinite(l0) & (l0 > 0))
        if bad.any():
            e = int(np.flatnonzero(bad)[0])
            raise InputError(f"{where}: spring {e} has rest length {l0[e]}; rest lengths must be finite and > 0")
        self.rest_lengths = l0

        if self.spring_volumes is not None:
            volumes = _floats(self.spring_volumes, "spring_volumes", where)
            if volumes.shape != (m,) or not (np.isfinite(volumes) & (volumes >= 0)).all():
                raise InputError(f"{where}: spring_volumes must be {m} finite values >= 0")
            self.spring_volumes = volumes

        for kind, groups, size in (("node", self.node_groups, n), ("spring", self.spring_groups, m)):
            for name, idx in list(groups.items()):
                idx = np.asarray(idx, dtype=np.int64).ravel()
                if idx.size and (idx.min() < 0 or idx.max() >= size):
                    raise InputError(f"{where}: {kind} group {name!r} has indices outside 0..{size - 1}")
                groups[name] = idx

    @property
    def n_nodes(self) -> int:
        return len(self.positions)

    @property
    def n_springs(self) -> int:
        return len(self.edges)

    def nodes(self, group, where: str = "group", named: str = "the net", *, empty: bool = False) -> np.ndarray:
        """(k,) int64 node indices of ``group``: a node group's name or node indices, checked.
        The one resolver of node groups (baths, loads, anchors, probes, scenes); its errors
        begin with ``where`` (the key that gave the group) and call the net ``named``. A group
        that selects nothing is an error unless ``empty`` (regions of a scene may be empty)."""
        return self._members(group, "node", where, named, False, empty)

    def springs(self, group, where: str = "group", named: str = "the net", *, joining: bool = False,
                empty: bool = False) -> np.ndarray:
        """(k,) int64 spring indices of ``group``: a spring group's name (``"all"``: every spring)
        or spring indices, checked; with ``joining``, a node group's name also selects the springs
        that join two of its nodes. The one resolver of spring groups (sources, materials,
        temperatures, probes); errors as :meth:`nodes`."""
        return self._members(group, "spring", where, named, joining, empty)

    def _members(self, group, what: str, where: str, named: str, joining: bool, empty: bool) -> np.ndarray:
        springs = what == "spring"
        count = self.n_springs if springs else self.n_nodes
        if isinstance(group, str):
            groups = self.spring_groups if springs else self.node_groups
            if springs and group == "all" and group not in groups:
                return np.arange(count, dtype=np.int64)
            if group in groups:
                idx = np.asarray(groups[group], dtype=np.int64)
            elif joining and group in self.node_groups:
                inside = np.zeros(self.n_nodes, dtype=bool)
                inside[self.node_groups[group]] = True
                idx = np.flatnonzero(inside[self.edges].all(axis=1)).astype(np.int64)
            else:
                kinds = "spring or node" if joining else what
                known = (["all"] if springs else []) + sorted(set(groups) | (set(self.node_groups) if joining else set()))
                raise InputError(f"{where}: no {kinds} group {group!r} in {named}; {kinds} groups: "
                                 f"{', '.join(known) or 'none'}")
            if idx.size == 0 and not empty:
                held = ("holds no node of the net: its mesh points touch no spring (only points that springs join "
                        "become nodes)") if not springs else "holds no spring"
                raise InputError(f"{where}: {what} group {group!r} {held}")
            return idx
        if isinstance(group, (bool, np.bool_)):
            raise InputError(f"{where}: expected a {what} group name or {what} indices, got {group!r}")
        try:
            idx = np.asarray(group, dtype=np.int64).reshape(-1)
        except (TypeError, ValueError):
            raise InputError(f"{where}: expected a {what} group name or {what} indices, got {group!r}") from None
        bad = idx[(idx < 0) | (idx >= count)]
        if bad.size:
            raise InputError(f"{where}: {what} index {int(bad[0])} is out of range 0..{count - 1}")
        if idx.size == 0 and not empty:
            raise InputError(f"{where}: the group has no {what}s")
        return idx

    def lengths(self, positions: np.ndarray | None = None) -> np.ndarray:
        """(m,) spring lengths at ``positions`` ((n, 3), default the initial positions)."""
        x = self.positions if positions is None else positions
        d = x[self.edges[:, 1]] - x[self.edges[:, 0]]
        return np.sqrt(np.einsum("ij,ij->i", d, d))

    def anchor_point(self) -> np.ndarray | None:
        """The common position of all anchored nodes if they coincide (angular momentum is taken
        about it), the origin if there are no anchors, ``None`` if anchors are spread out."""
        if not self.anchored.any():
            return np.zeros(3)
        pts = self.positions[self.anchored]
        if np.all(pts == pts[0]):
            return pts[0].copy()
        return None

    def pieces(self) -> list[np.ndarray]:
        """The node indices of each piece of the net that no spring joins to another (connected
        components of the spring graph; a node touching no spring is a piece), largest first."""
        import scipy.sparse as sp
        from scipy.sparse.csgraph import connected_components

        n = self.n_nodes
        e = np.asarray(self.edges, dtype=np.int64)
        graph = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)) if len(e) else sp.coo_matrix((n, n))
        count, labels = connected_components(graph, directed=False)
        if count == 1:
            return [np.arange(n)]
        groups = [np.flatnonzero(labels == c) for c in range(count)]
        return sorted(groups, key=lambda g: (-len(g), int(g[0])))

    def pieces_note(self) -> str | None:
        """One sentence when the net falls apart into pieces no spring joins (None when it is in
        one piece): how many, their sizes, and how many hold no anchored node (they move freely
        where other pieces are held)."""
        pieces = self.pieces()
        if len(pieces) == 1:
            return None
        sizes = ", ".join(str(len(p)) for p in pieces[:6]) + (", …" if len(pieces) > 6 else "")
        text = (f"the net is {len(pieces)} pieces that no spring joins ({sizes} nodes; a mesh of volumes that were not "
                f"fused has duplicate nodes where they meet: fuse them, e.g. gmsh's BooleanFragments or Coherence)")
        if self.anchored.any():
            loose = sum(1 for p in pieces if not self.anchored[p].any())
            if loose:
                text += f"; {loose} of them hold{'s' if loose == 1 else ''} no anchored node and move{'s' if loose == 1 else ''} freely"
        return text

    def to_meshio(self):
        """The net as a ``meshio.Mesh`` (springs as "line" cells; point data ``mass``,
        ``anchored``; cell data ``rest_length``), e.g. ``net.to_meshio().write("net.vtu")``."""
        from .io.convert import net_mesh

        return net_mesh(self)

    def to_pyvista(self):
        """The net as a ``pyvista.UnstructuredGrid`` (the fields of :meth:`to_meshio`; needs PyVista)."""
        from .io.convert import net_mesh, to_pyvista

        return to_pyvista(net_mesh(self))

    def __repr__(self) -> str:
        groups = ""
        if self.node_groups:
            groups += f", node groups {', '.join(sorted(self.node_groups))}"
        if self.spring_groups:
            groups += f", spring groups {', '.join(sorted(self.spring_groups))}"
        return (f"<Net {self.n_nodes} nodes ({int(self.anchored.sum())} anchored), {self.n_springs} springs"
                f"{groups}, from {self.source}>")

    def summary(self) -> str:
        n_anch = int(self.anchored.sum())
        return (
            f"{self.n_nodes} nodes ({n_anch} anchored), {self.n_springs} springs, "
            f"total mass {self.masses[~self.anchored].sum():.6g}, from {self.source}"
        )


def _floats(values, what: str, where: str) -> np.ndarray:
    """``values`` as float64, or an :class:`InputError` naming ``what``."""
    try:
        return np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{where}: {what} are not numbers ({exc})") from None
