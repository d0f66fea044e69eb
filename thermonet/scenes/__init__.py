"""Scene files: TOML descriptions of a run (net, materials, initial state, effects, integrator,
outputs), validated against one schema and built into the objects the Python API takes.

    >>> scene = load_scene("scenes/truss_block.toml", overrides=["integrator.h=1e-4"])
    >>> built = scene.build()          # built.net, built.simulation, built.material_id
"""

from .build import BuiltScene, build_scene
from .scene import DEFAULT_SCENE, Scene, load_scene, scene_from_text
from .reference import all_key_paths, reference
from .schema import SCHEMA
from .source import SceneError, parse_override

__all__ = ["Scene", "BuiltScene", "SceneError", "load_scene", "scene_from_text", "build_scene",
           "DEFAULT_SCENE", "SCHEMA", "reference", "all_key_paths", "parse_override"]
