"""Probes: per-group time series of one quantity (mean, min, max over the group) at a chosen
cadence, written as ``probe_<name>.csv`` beside ``diagnostics.csv``.

Quantities: ``temperature``, ``strain`` (ln l/l0), ``tension`` over a spring group (or the springs
joining two nodes of a node group), ``displacement`` (|x − X|) over a node group.
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .parallel.world import on_root

SPRING_QUANTITIES = ("temperature", "strain", "tension")
QUANTITIES = SPRING_QUANTITIES + ("displacement",)
COLUMNS = ("step", "time", "mean", "min", "max")


@dataclass(frozen=True)
class Probe:
    """One probe: ``quantity`` over ``group`` (a group name or indices: node indices for
    displacement, spring indices for the rest) every ``every`` steps (None: the diagnostics
    cadence)."""

    group: object
    quantity: str
    every: int | None = None


class Probes:
    """The probes of one Simulation and their series (name -> list of rows (step, time, mean,
    min, max)). ``observers(default_every)`` gives the (cadence, callback) pairs of ``run``."""

    def __init__(self, sim, probes: dict):
        self.probes = dict(probes)
        self.index = {}
        self.series = {name: [] for name in self.probes}
        self._cache = (None, None)

        def indices():
            for name, probe in self.probes.items():
                self.index[name] = _indices(sim.net, probe, f"probes.{name}")

        # over MPI processes rank 0 alone holds the net and records the rows (its error raised everywhere)
        on_root(getattr(sim, "comm", None), indices)

    def observers(self, default_every: int) -> list:
        cadences: dict[int, list] = {}
        for name, probe in self.probes.items():
            cadences.setdefault(int(probe.every or default_every), []).append(name)
        return [(k, (lambda sim, names=tuple(names): self.record(sim, names))) for k, names in cadences.items()]

    def record(self, sim, names=None) -> None:
        """A row of each probe in ``names`` (default all) at the current state (once per step;
        over MPI processes measured by rank 0, the rows given to every process)."""
        names = [name for name in names or self.probes
                 if not (self.series[name] and self.series[name][-1][0] == sim.step)]
        if not names:
            return
        for name, row in zip(names, sim.on_root(lambda: [self._row(sim, name) for name in names])):
            self.series[name].append(row)

    def _row(self, sim, name: str) -> tuple:
        v = self._values(sim, self.probes[name].quantity)[self.index[name]]
        return (sim.step, sim.time, float(v.mean()), float(v.min()), float(v.max()))

    def _values(self, sim, quantity: str) -> np.ndarray:
        step, fields = self._cache
        if step != sim.step or fields is None:
            fields = {}
            self._cache = (sim.step, fields)
        if quantity not in fields:
            if quantity == "displacement":
                fields[quantity] = np.linalg.norm(sim.state.positions - sim.net.positions, axis=1)
            elif quantity == "strain":
                fields[quantity] = sim.strains()
            elif quantity == "temperature":
                fields[quantity] = sim.temperatures()
            else:
                fields[quantity] = sim.tensions()
        return fields[quantity]

    def to_csv(self, folder: str) -> list[str]:
        """Write ``probe_<name>.csv`` per probe (atomically); returns the file names."""
        from .io.atomic import atomic_write

        names = []
        for name, rows in self.series.items():
            fname = f"probe_{name}.csv"
            with atomic_write(os.path.join(folder, fname), "w") as f:
                w = csv.writer(f)
                w.writerow(COLUMNS)
                for row in rows:
                    w.writerow([row[0]] + [repr(float(v)) for v in row[1:]])
            names.append(fname)
        return names

    def restore(self, folder: str, step: int) -> None:
        """Take the rows up to ``step`` back from the CSV files of a run being resumed."""
        for name in self.series:
            path = os.path.join(folder, f"probe_{name}.csv")
            if not os.path.exists(path):
                continue
            with open(path) as f:
                rows = list(csv.reader(f))[1:]
            self.series[name] = [(int(r[0]),) + tuple(float(v) for v in r[1:]) for r in rows if int(r[0]) <= step]


def read_probe_csv(path: str) -> dict[str, np.ndarray]:
    """The columns of a probe CSV file as arrays."""
    data = np.atleast_2d(np.loadtxt(path, delimiter=",", skiprows=1))
    return {c: data[:, i] for i, c in enumerate(COLUMNS)} if data.size else {c: np.empty(0) for c in COLUMNS}


def _indices(net, probe: Probe, where: str) -> np.ndarray:
    if probe.quantity not in QUANTITIES:
        raise InputError(f"{where}.quantity: must be one of {', '.join(QUANTITIES)}, got {probe.quantity!r}")
    if probe.every is not None and (isinstance(probe.every, bool) or int(probe.every) < 1):
        raise InputError(f"{where}.every: must be a number of steps >= 1, got {probe.every!r}")
    if probe.quantity in SPRING_QUANTITIES:  # a node group: the springs joining two of its nodes
        return net.springs(probe.group, f"{where}.group", joining=True)
    return net.nodes(probe.group, f"{where}.group")


def scene_probes(scene, sim) -> Probes | None:
    """The ``[probes.<name>]`` tables of a scene attached to ``sim`` (``sim.add_probes``) and
    returned (None if none); errors at the key's file:line."""
    tables = scene.data.get("probes") or {}
    if not tables:
        return None
    probes = {name: Probe(t["group"], t["quantity"], t.get("every")) for name, t in tables.items()}
    try:
        return sim.add_probes(probes)
    except InputError as exc:
        message = str(exc)
        key, _, rest = message.partition(": ")
        raise scene.error(tuple(key.split(".")), rest) from None
