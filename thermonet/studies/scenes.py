"""Resolve a study's SCENE argument into simulations.

A scene is named by a string so that it can travel to Dask workers: the built-in names
``"chain"`` and ``"triangle"`` (the paper's examples, :mod:`thermonet.paper`), or the path of a
scene file, read by :mod:`thermonet.scene` (imported only when a path is given).
"""

from __future__ import annotations

import os

from ..errors import InputError
from ..simulation import Simulation

BUILTIN = ("chain", "triangle")


def make_simulation(scene: str, integrator: str, h: float, **options) -> Simulation:
    """A fresh simulation of ``scene`` at its initial state with ``integrator`` and step ``h``.

    options: passed on to :class:`~thermonet.Simulation` (e.g. ``threads=1``).
    """
    if scene == "chain":
        from ..paper import chain_simulation

        return chain_simulation(integrator, h, **options)
    if scene == "triangle":
        from ..paper import triangle_simulation

        return triangle_simulation(integrator, h, **options)
    return _scene_file_simulation(scene, integrator, h, **options)


def check_scene(scene: str) -> None:
    """Raise :class:`InputError` now (in the client) if ``scene`` cannot be resolved."""
    if scene in BUILTIN:
        return
    if not os.path.exists(scene):
        raise InputError(f"scene {scene!r}: neither a built-in scene ({', '.join(BUILTIN)}) nor an existing file")
    _scene_loader()


def _scene_loader():
    try:
        from .. import scene as scene_module
    except ImportError:
        raise InputError(
            "scene files need thermonet.scene, which this installation does not have; "
            f"use a built-in scene ({', '.join(BUILTIN)})") from None
    return scene_module


def _scene_file_simulation(path: str, integrator: str, h: float, **options) -> Simulation:
    check_scene(path)
    scene_module = _scene_loader()
    load = getattr(scene_module, "load_scene", None) or getattr(scene_module, "load", None)
    if load is None:
        raise InputError("thermonet.scene has no load_scene(path): cannot read scene files")
    scene = load(path)
    build = getattr(scene, "build_simulation", None) or getattr(scene, "simulation", None)
    if build is None:
        raise InputError(f"{path}: the loaded scene cannot build a Simulation")
    return build(integrator=integrator, h=h, **options)
