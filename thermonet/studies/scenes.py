"""Resolve a study's SCENE argument into simulations.

A scene is named by a string so that it can travel to Dask workers: the built-in names
``"chain"`` and ``"triangle"`` (the paper's examples, :mod:`thermonet.paper`), ``"lattice"`` (a
free jittered 8³ lattice of hencky springs, :func:`lattice_simulation`), or the path of a
scene file, read by :mod:`thermonet.scenes` (imported only when a path is given) with the
study's integrator and step as overrides. A scene file must be readable by the Dask workers
(same path on every machine).
"""

from __future__ import annotations

import os

from ..builders import lattice
from ..errors import InputError
from ..paper import chain_simulation, triangle_simulation
from ..simulation import Simulation

BUILTIN = ("chain", "triangle", "lattice")


def make_simulation(scene: str, integrator: str, h: float, **options) -> Simulation:
    """A fresh simulation of ``scene`` at its initial state with ``integrator`` and step ``h``.

    options: passed on to :class:`~thermonet.Simulation` (e.g. ``threads=1``).
    """
    if scene == "chain":
        return chain_simulation(integrator, h, **options)
    if scene == "triangle":
        return triangle_simulation(integrator, h, **options)
    if scene == "lattice":
        return lattice_simulation(integrator, h, **options)
    return _scene_file_simulation(scene, integrator, h, **options)


def lattice_simulation(integrator: str, h: float, cells: int = 8, **options) -> Simulation:
    """The cost study's net: a free cubic lattice of ``cells``³ cells ((cells+1)³ nodes; 8³: 729
    nodes, 1944 springs), 6 neighbours, jitter 0.1 (rest lengths the jittered lengths), unit
    masses, default "hencky" springs (c = 100, β = 0.2, C0 = 5, θ0 = 300), temperatures uniform in
    250–350, velocities normal with standard deviation 0.2 per component; all seeded (seed 1)."""
    import numpy as np

    net = lattice((cells, cells, cells), neighbours=6, jitter=0.1, seed=1)
    rng = np.random.default_rng(1)
    temperatures = rng.uniform(250.0, 350.0, net.n_springs)
    velocities = rng.normal(0.0, 0.2, (net.n_nodes, 3))
    return Simulation(net, model="hencky", temperatures=temperatures, velocities=velocities,
                      integrator=integrator, h=h, **options)


def effects_beyond_hamilton(sim) -> list[str]:
    """What a simulation does that Hamilton's equations of its net (SciPy's reference,
    :mod:`thermonet.studies.ode`) leave out: heat flow (conduction, thermal waves, baths,
    sources) and loads, each named (e.g. ``"baths (hot)"``); empty for an adiabatic net under
    gravity and anchors only."""
    out = []
    heat = sim.system.heat
    if heat is not None:
        if heat.conduction:
            out.append("conduction")
        if heat.waves:
            out.append("thermal waves")
        names = list(heat.names)
        if heat.n_baths:
            out.append(f"baths ({', '.join(names[:heat.n_baths])})")
        if len(names) > heat.n_baths:
            out.append(f"sources ({', '.join(names[heat.n_baths:])})")
    loads = sim.loads
    if loads is not None:
        out.append(f"loads ({', '.join(loads.set.names)})")
    return out


def scene_effects(scene: str) -> list[str]:
    """:func:`effects_beyond_hamilton` of ``scene``'s simulation."""
    return effects_beyond_hamilton(make_simulation(scene, "co2", 1.0))


def scene_time(scene: str) -> tuple[float, float | None]:
    """(h, t_end) of a scene file (t_end = steps · h when the scene gives steps); (PAPER_DT,
    None) for a built-in scene, which has no end of its own."""
    if scene in BUILTIN:
        return 0.1, None
    integ = _scene_loader().load_scene(scene)["integrator"]
    h = float(integ["h"])
    return h, float(integ["t_end"]) if integ.get("t_end") is not None else int(integ["steps"]) * h


def check_scene(scene: str) -> None:
    """Raise :class:`InputError` now (in the client) if ``scene`` cannot be resolved."""
    if scene in BUILTIN:
        return
    if not os.path.exists(scene):
        raise InputError(f"scene {scene!r}: neither a built-in scene ({', '.join(BUILTIN)}) nor an existing file")
    _scene_loader()


def _scene_loader():
    try:
        from .. import scenes as scene_module
    except ImportError:
        raise InputError(
            "scene files need thermonet.scenes, which this installation does not have; "
            f"use a built-in scene ({', '.join(BUILTIN)})") from None
    return scene_module


def _scene_file_simulation(path: str, integrator: str, h: float, threads: int | None = None) -> Simulation:
    check_scene(path)
    # the study sets the step and the end: the scene's own t_end need not be a whole number of h;
    # conduction every step: a study measures convergence in h, and "auto" would pick its own
    # conduction step for each h
    overrides = [f'integrator.name="{integrator}"', f"integrator.h={float(h)!r}", "integrator.steps=1",
                 "effects.conduction_every=1"]
    if threads is not None:
        overrides.append(f"integrator.threads={int(threads)}")
    return _scene_loader().load_scene(path, overrides=overrides).build().simulation
