"""Conservation diagnostics: energy, entropy, linear and angular momentum, as a time series.

Measured at a chosen cadence, outside the time-stepping loop, from the state alone (nothing
is assigned): H = Σ|p|²/2m + Σ U(l, η) (+ gravity's potential −Σ m g·x), S = Σ η,
P = Σ p, L = Σ (x − x_ref) × p over free nodes.

Each sum is exactly rounded (:mod:`thermonet.kernels.exact`): reduced into an accumulator without
rounding, rounded once at the end. A row therefore has the same bits whatever the number of
threads, and a run over several processes, each reducing its own springs and nodes into
accumulators that are then added, has the rows of one process (:func:`row_sums`).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field

import numpy as np

from .kernels import exact, records
from .kernels.reductions import EVERY, ROW_SUMS, diagnostic_sums_kernel, row_sums_kernel
from .kernels.springs import spring_field_kernel

CONSERVED = ("energy", "entropy", "px", "py", "pz", "Lx", "Ly", "Lz")


@dataclass
class SpringFields:
    """Per-spring fields at one state, internal numbering: length, temperature, tension,
    internal energy U (free energy F(l, θ0) when thermal coupling is off); all (m,)."""

    length: np.ndarray
    temperature: np.ndarray
    tension: np.ndarray
    internal_energy: np.ndarray


def spring_fields(system, positions: np.ndarray, entropy: np.ndarray, parallel: bool = False) -> SpringFields:
    """Per-spring fields at (positions (n, 3), entropy (m,) or None), internal numbering."""
    m = system.n_springs
    out = SpringFields(np.empty(m), np.empty(m), np.empty(m), np.empty(m))
    kernel = spring_field_kernel(system.model, system.thermal, parallel)
    if entropy is None:
        entropy = np.empty(0)
    kernel(positions, entropy, system.rest_lengths, system.parameters, system.edges.view(np.uint32),
           out.length, out.temperature, out.tension, out.internal_energy)
    return out


#: the rows of a diagnostics row's accumulators (one (SUMS, WIDTH) int64 array): Σ U, Σ η, then
#: the node sums (thermonet.kernels.reductions.NODE_SUMS order)
INTERNAL, ENTROPY, NODES = 0, 1, 2
SUMS = ROW_SUMS


def row_sums(system, x, p, eta, edges, springs, nodes, uniform: bool, counted=EVERY, parallel: bool = False,
             closing=None, energy=None) -> tuple[np.ndarray, float, float]:
    """The accumulators (SUMS, WIDTH) int64 of a row's sums over a net or a process's share of
    one, and the range (θ_min, θ_max) of the springs' temperatures.

    x, p: (n, 3); eta: (m,) (empty without thermal coupling); edges: (m, 2) uint32; springs: a
    :class:`~thermonet.kernels.records.Springs` (rest lengths, parameters as the kernels read
    them; ``uniform``: a shared (k, 1) column, see
    :func:`~thermonet.kernels.specialize.kernel_parameters`); nodes: a
    :class:`~thermonet.kernels.records.Nodes` (a node it marks anchored counts for nothing: a
    share's ghosts); counted: (m,) uint8, the springs whose U and η count (a share's
    own), or empty: all; closing: (energy (m,), θ_min, θ_max, node accumulators (C, 8, WIDTH)
    or None) that a closing kick left for this state, taken instead of a pass over the springs
    (and over the nodes, with node accumulators); energy: (m,) scratch for the springs' energies
    where there is no ``closing`` (default: a new array).
    """
    node_accs = None
    if closing is None:
        spring_energies = diagnostic_sums_kernel(system.model, system.thermal, parallel, uniform)
        energy = np.empty(edges.shape[0]) if energy is None else energy
        theta_min, theta_max = spring_energies(x, eta, springs.rest, springs.P, edges, energy)
    else:
        energy, theta_min, theta_max, node_accs = closing
    if node_accs is not None:  # the nodes' terms were reduced by the closing kick: springs only
        x = p = _NO_NODES
    acc = row_sums_kernel(parallel)(x, p, nodes.masses, nodes.anchored, nodes.reference, nodes.gravity, energy,
                                    eta if system.thermal else _EMPTY, counted)
    if node_accs is not None:
        acc[NODES:] += node_accs.sum(axis=0)
    return acc, float(theta_min), float(theta_max)


def sums_of(acc: np.ndarray, theta_min: float, theta_max: float, thermal: bool) -> dict:
    """The rounded sums of the accumulators of :func:`row_sums` (of the whole net: added over the
    processes' shares where there are several), keyed as :func:`diagnostics_row`'s arguments."""
    v = exact.values(acc).tolist()
    kinetic, potential, px, py, pz, Lx, Ly, Lz = v[NODES:]
    return dict(kinetic=kinetic, internal=v[INTERNAL], potential=potential,
                entropy=v[ENTROPY] if thermal else None, momentum=(px, py, pz), angular_momentum=(Lx, Ly, Lz),
                theta_min=theta_min, theta_max=theta_max)


def measure(system, state, parallel: bool = False) -> dict[str, float]:
    """One diagnostics row for ``state`` (internal numbering): a pass over the springs (their
    energies into one (m,) array) and one exact reduction of those, η and the nodes' terms."""
    eta = state.entropy if system.thermal else _EMPTY
    P, uniform = system.kernel_parameters
    acc, theta_min, theta_max = row_sums(system, state.positions, state.momenta, eta, system.edges.view(np.uint32),
                                         records.Springs(system.rest_lengths, P), records.nodes(system), uniform,
                                         parallel=parallel)
    return diagnostics_row(system, state, **sums_of(acc, theta_min, theta_max, system.thermal))


def diagnostics_row(system, state, kinetic, internal, potential, entropy, momentum, angular_momentum,
                    theta_min, theta_max) -> dict[str, float]:
    """The row of one diagnostics stop from its sums (thermal columns only with thermal coupling);
    shared by the CPU reductions and the CUDA backend's device reductions."""
    row = {
        "step": state.step,
        "time": state.time,
        "energy": kinetic + internal + potential,
        "kinetic": kinetic,
        "internal": internal,
        "potential": potential,
    }
    if system.thermal:
        row["entropy"] = entropy
    row.update(zip(("px", "py", "pz"), momentum))
    row.update(zip(("Lx", "Ly", "Lz"), angular_momentum))
    if system.thermal:
        row["theta_min"] = theta_min
        row["theta_max"] = theta_max
    return row


_EMPTY = np.empty(0)
_NO_NODES = np.empty((0, 3))


@dataclass
class Diagnostics:
    """A time series of diagnostics rows. Columns are attributes: ``d.time``, ``d.energy``, ...
    (each a (k,) array); ``d.linear_momentum`` and ``d.angular_momentum`` are (k, 3)."""

    rows: list[dict] = field(default_factory=list)

    def __repr__(self) -> str:
        if not self.rows:
            return "<Diagnostics: no rows>"
        first, last = self.rows[0], self.rows[-1]
        text = (f"<Diagnostics {len(self.rows)} rows, steps {first['step']}..{last['step']}, "
                f"t = {first['time']:.6g}..{last['time']:.6g}")
        energy = self.summary().get("energy")
        if energy is not None:
            text += f", energy {energy['initial']:.10g} (max rel. deviation {energy['relative']:.2e})"
        return text + f"; columns {', '.join(self.columns)}>"

    def append(self, row: dict) -> None:
        self.rows.append(row)

    def __len__(self) -> int:
        return len(self.rows)

    @property
    def columns(self) -> list[str]:
        cols: list[str] = []
        for row in self.rows:
            for k in row:
                if k not in cols:
                    cols.append(k)
        return cols

    def column(self, name: str) -> np.ndarray:
        return np.array([row.get(name, np.nan) for row in self.rows], dtype=np.float64)

    def __getattr__(self, name: str):
        if name.startswith("_") or name == "rows":
            raise AttributeError(name)
        if name == "linear_momentum":
            return np.column_stack([self.column(c) for c in ("px", "py", "pz")])
        if name == "angular_momentum":
            return np.column_stack([self.column(c) for c in ("Lx", "Ly", "Lz")])
        if self.rows and any(name in row for row in self.rows):
            return self.column(name)
        raise AttributeError(f"no diagnostics column {name!r}; columns: {', '.join(self.columns)}")

    def summary(self) -> dict[str, dict[str, float]]:
        """Initial value, max absolute deviation and max relative deviation of each conserved
        quantity (relative to the quantity's scale: |initial|, or for momenta the largest
        component magnitude seen, so a zero component is judged against a meaningful size; for
        the heat-flow balances the larger of |H(0)| and the largest |H − H(0)|, resp. for S)."""
        out = {}
        for name in CONSERVED:
            if not self.rows or name not in self.rows[0]:
                continue
            v = self.column(name)
            dev = float(np.max(np.abs(v - v[0])))
            if name in ("px", "py", "pz", "Lx", "Ly", "Lz"):
                group = ("px", "py", "pz") if name.startswith("p") else ("Lx", "Ly", "Lz")
                scale = max(float(np.max(np.abs(self.column(g)))) for g in group)
            else:
                scale = abs(float(v[0]))
            out[name] = {"initial": float(v[0]), "max_deviation": dev, "relative": dev / scale if scale > 0 else dev}
        for name, of in (("energy_balance", "energy"), ("entropy_balance", "entropy")):
            if self.rows and name in self.rows[-1]:  # heat flow, loads: a balance, zero at the start,
                dev = float(np.nanmax(np.abs(self.column(name))))  # judged against what moved too
                v = self.column(of)
                scale = max(abs(float(v[0])), float(np.nanmax(np.abs(v - v[0]))))
                if of == "energy" and "work" in self.rows[-1]:
                    scale = max(scale, float(np.nanmax(np.abs(self.column("work")))))
                out[name] = {"initial": 0.0, "max_deviation": dev, "relative": dev / scale if scale > 0 else dev}
        return out

    def to_csv(self, path) -> None:
        """Write all rows to ``path`` atomically (a temporary file renamed into place)."""
        from .io.atomic import atomic_write

        cols = self.columns
        with atomic_write(path, "w") as f:
            w = csv.writer(f)
            w.writerow(cols)
            for row in self.rows:
                w.writerow([_fmt(row.get(c, "")) for c in cols])


def _fmt(v):
    if isinstance(v, float):
        return repr(v)
    return v
