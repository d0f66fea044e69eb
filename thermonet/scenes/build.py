"""Turning a validated :class:`~thermonet.scenes.scene.Scene` into the objects the Python API
takes: a :class:`~thermonet.net.Net`, model parameters, an initial state, a Simulation."""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..builders import chain, from_meshio, lattice, read_meshio, triangle
from ..errors import InputError
from ..heat.setup import Bath, Source
from ..loads.scene import scene_loads
from ..materials.continuum import CONTINUUM_KEYS, apply_regions
from ..models import get_model
from ..net import Net
from ..simulation import Simulation, integrator_option_problem

if TYPE_CHECKING:  # annotations only: scene.py builds through this module
    from .scene import Scene

#: integrator keys of a scene that go to the integrator (and its stepper) as options
INTEGRATOR_OPTIONS = ("alpha", "tolerance", "max_iterations", "retry", "linear_solver", "newton_path")


@dataclass
class BuiltScene:
    """What a scene builds: the net, the simulation, and per-spring material ids (m,) int32
    (the index of the [materials.*] table that set each spring; -1: model defaults)."""

    scene: Scene
    net: Net
    simulation: object
    material_id: np.ndarray
    material_names: list
    mesh: object = None
    # --- continuum materials: what the rule made (None: no continuum region), the parameters ---
    continuum: object = None
    parameters: dict | None = None


def build_scene(scene: Scene) -> BuiltScene:
    d = scene.data
    net, mesh = build_net(scene)
    model = get_model(next((r["model"] for r in d["materials"].values() if "model" in r), "hencky"))
    parameters, material_id, names = material_parameters(scene, net, model)
    # --- continuum materials (docs/continuum.md) ---
    net, continuum = continuum_materials(scene, net, model, parameters)
    # --- end continuum materials ---
    integ = d["integrator"]
    options = {k: integ[k] for k in INTEGRATOR_OPTIONS if integ.get(k) is not None}
    for key in integ.get("options") or {}:  # a typo at its line, with what it may have meant
        problem = integrator_option_problem([key])
        if problem is not None:
            raise scene.error(f"integrator.options.{key}", problem)
    options.update(integ.get("options") or {})
    init = d["initial"]
    kind = "momentum" if init["momentum"] is not None else "velocity"
    motion = node_vectors(scene, net, mesh, kind)
    loads = scene_loads(scene, net)  # loads
    try:
        sim = Simulation(
            net,
            model=model,
            parameters=parameters,
            temperatures=initial_temperatures(scene, net, model, parameters) if d["effects"]["thermal"] else None,
            momenta=motion if kind == "momentum" else None,
            velocities=motion if kind == "velocity" else None,
            integrator=integ["name"],
            h=integ["h"],
            gravity=d["effects"]["gravity"],
            thermal=d["effects"]["thermal"],
            threads=integ.get("threads"),
            parallel=None if integ["parallel"] == "auto" else integ["parallel"],
            renumber=integ["renumber"],
            integrator_options=options,
            backend=integ["backend"],
            stretch_bounds=tuple(integ["stretch_bounds"]),
            energy_tolerance=integ["energy_tolerance"] or None,
            stability_guard="stop" if integ["check_step"] else "warn",
            conduction=d["effects"]["conduction"],
            conduction_every=d["effects"]["conduction_every"],
            conduction_sweeps=d["effects"].get("conduction_sweeps"),
            thermal_waves=d["effects"]["thermal_waves"],
            baths={name: Bath(b["group"], b["temperature"]) for name, b in d["baths"].items()},
            sources={name: Source(b["group"], b["power"]) for name, b in d["sources"].items()},
            loads=loads,
        )
    except InputError as exc:
        message = str(exc)
        if message.startswith(("baths.", "sources.")) and ": " in message:  # point at the key's line
            key, _, rest = message.partition(": ")
            raise scene.error(key, rest) from None
        raise scene.error("", message) from None
    except TypeError as exc:  # an option the integrator does not take
        raise scene.error("integrator", f"integrator {integ['name']!r} does not accept these options: {exc}") from None
    return BuiltScene(scene, net, sim, material_id, names, mesh, continuum, parameters)


# ----------------------------------------------------------------------------------------------
# net


def build_net(scene: Scene) -> tuple[Net, object]:
    """The net with the scene's masses, anchors and rest lengths, and the meshio mesh (or None)."""
    d = scene.data
    spec, init = d["net"], d["initial"]
    mass = init["mass"] or {}
    mesh = None
    if spec.get("mesh") is not None:
        path = scene.mesh_path()
        if os.path.isdir(path):
            raise scene.error("net.mesh", f"{path} is a folder, not a mesh file")
        if not os.path.isfile(path):
            raise scene.error("net.mesh", f"mesh file {path} does not exist")
        try:
            mesh = read_meshio(path)
        except InputError as exc:  # meshio raises many kinds (or exits); say which file and why
            raise scene.error("net.mesh", str(exc)) from None
        mass_arg = mass.get("uniform") if mass.get("uniform") is not None else mass.get("point_data")
        if mass.get("point_data") is not None and mass["point_data"] not in mesh.point_data:
            raise scene.error("initial.mass.point_data", _no_field(mass["point_data"], mesh))
        try:
            net = from_meshio(mesh, cell_types=spec.get("cells"), mass=mass_arg, density=mass.get("density"), source=path)
        except InputError as exc:
            raise scene.error("net.mesh", str(exc)) from None
    else:
        gen = spec["generator"]
        if gen == "lattice":
            p = spec.get("lattice") or {"shape": [10, 10, 10], "spacing": 1.0, "neighbours": 6, "jitter": 0.0, "seed": 0}
            if len(p["shape"]) != 3 or max(p["shape"]) < 1:
                raise scene.error("net.lattice.shape", f"must be 3 cell counts, at least one > 0, got {p['shape']}")
            net = lattice(tuple(p["shape"]), p["spacing"], p["neighbours"], p["jitter"], p["seed"])
            net.node_groups.update(_lattice_faces(net.positions, p["spacing"]))
        else:
            net = chain() if gen == "chain" else triangle()
        if mass.get("uniform") is not None:
            net.masses = np.full(net.n_nodes, mass["uniform"])

    masses = net.masses.copy()
    for group, value in (mass.get("regions") or {}).items():
        masses[_node_group(scene, net, group, f"initial.mass.regions.{group}")] = value
    anchored = net.anchored.copy()
    if d["effects"].get("anchors") is not None:
        anchored[:] = False
        for i, item in enumerate(d["effects"]["anchors"]):
            anchored[_node_group(scene, net, item if isinstance(item, str) else [item], "effects.anchors")] = True
    rest = net.rest_lengths if spec["rest_lengths"] == "initial" else np.full(net.n_springs, spec["rest_lengths"])
    try:
        net = dataclasses.replace(net, masses=masses, anchored=anchored, rest_lengths=rest)
    except InputError as exc:
        raise scene.error("net", str(exc)) from None
    return net, mesh


def _lattice_faces(x: np.ndarray, spacing: float) -> dict[str, np.ndarray]:
    groups = {}
    for axis, name in enumerate("xyz"):
        lo, hi = x[:, axis].min(), x[:, axis].max()
        tol = 0.5 * spacing
        groups[f"{name}min"] = np.flatnonzero(x[:, axis] <= lo + tol)
        groups[f"{name}max"] = np.flatnonzero(x[:, axis] >= hi - tol)
    return groups


def _net_name(net) -> str:
    """The net's source in a message that already names the scene file: the mesh's file name."""
    source = str(net.source)
    return f"the mesh {os.path.basename(source)}" if os.path.sep in source or "." in source else source


def _node_group(scene, net, name, key) -> np.ndarray:
    return _group(scene, key, net.nodes, name, _net_name(net))


def _spring_group(scene, net, name, key) -> np.ndarray:
    return _group(scene, key, net.springs, name, _net_name(net))


def _group(scene, key, resolve, name, named) -> np.ndarray:
    """``resolve(name, key, named)`` (:meth:`Net.nodes` or :meth:`Net.springs`; a region may be
    empty), its error at the key's line."""
    try:
        return resolve(name, key, named, empty=True)
    except InputError as exc:
        raise scene.error(key, str(exc).removeprefix(f"{key}: ")) from None


def _no_field(name, mesh) -> str:
    return f"no point-data field {name!r} in the mesh; fields: {', '.join(mesh.point_data) or 'none'}"


# ----------------------------------------------------------------------------------------------
# materials and initial state


def material_parameters(scene: Scene, net: Net, model) -> tuple[dict, np.ndarray, list]:
    """Per-spring parameter arrays (name -> (m,)), material ids (m,) and region names."""
    m = net.n_springs
    values = {p: np.full(m, float(model.defaults.get(p, np.nan))) for p in model.parameters}
    material_id = np.full(m, -1, dtype=np.int32)
    names = list(scene.data["materials"])
    for i, (region, params) in enumerate(scene.data["materials"].items()):
        springs = _spring_group(scene, net, region, f"materials.{region}")
        material_id[springs] = i
        for k, v in params.items():
            if k != "model" and k not in CONTINUUM_KEYS:
                values.setdefault(k, np.zeros(m))[springs] = v  # transport parameters default to 0
    for p, arr in values.items():
        if np.isnan(arr).any():
            e = int(np.flatnonzero(np.isnan(arr))[0])
            raise scene.error("materials", f"spring {e} has no value for parameter {p!r} of model {model.name!r} "
                              "(it has no default): set it in [materials.all] or in a region covering that spring")
    return values, material_id, names


# --- continuum materials (docs/continuum.md) ---


def continuum_materials(scene: Scene, net: Net, model, values: dict):
    """The scene's material regions, in file order, through
    :func:`thermonet.materials.continuum.apply_regions` (the rule's one place): regions that
    give continuum properties set their springs' stiffness, beta, C0, g, g_star in ``values``
    and node masses come from their densities. Returns the net (with those masses) and a
    :class:`~thermonet.materials.ContinuumMap`, or (net, None); errors at the region's line (a
    net that is a mechanism at net.mesh)."""
    regions = [(f"materials.{region}", _spring_group(scene, net, region, f"materials.{region}"), params)
               for region, params in scene.data["materials"].items()]
    try:
        return apply_regions(net, model, values, regions, "materials")
    except InputError as exc:
        key, _, rest = str(exc).partition(": ")
        raise scene.error("net.mesh" if key == "materials" else key, rest) from None


# --- end continuum materials ---


def initial_temperatures(scene: Scene, net: Net, model, parameters) -> np.ndarray | None:
    """(m,) θ(0): uniform (default: each spring's reference temperature), then regions, then
    the seeded perturbation."""
    spec = scene.data["initial"]["temperature"]
    if spec is None:
        return None
    theta = np.array(parameters[model.reference_temperature], dtype=np.float64)
    if spec.get("uniform") is not None:
        theta[:] = spec["uniform"]
    for group, value in spec["regions"].items():
        theta[_spring_group(scene, net, group, f"initial.temperature.regions.{group}")] = value
    if spec["perturbation"] > 0:
        rng = np.random.default_rng(spec["seed"])
        theta = theta + rng.uniform(-spec["perturbation"], spec["perturbation"], net.n_springs)
        if (theta <= 0).any():
            e = int(np.flatnonzero(theta <= 0)[0])
            raise scene.error("initial.temperature.perturbation",
                              f"makes spring {e}'s temperature {theta[e]:g} <= 0; use a smaller perturbation")
    return theta


def node_vectors(scene: Scene, net: Net, mesh, kind: str) -> np.ndarray | None:
    """(n, 3) initial velocities or momenta (``kind``): the sum of the parts the scene gives;
    anchored nodes at rest."""
    spec = scene.data["initial"][kind]
    if spec is None:
        return None
    key = f"initial.{kind}"
    x = net.positions
    v = np.zeros((net.n_nodes, 3))
    if spec.get("uniform") is not None:
        v += np.asarray(spec["uniform"])
    for group, value in spec["regions"].items():
        v[_node_group(scene, net, group, f"{key}.regions.{group}")] += np.asarray(value)
    if spec.get("rotation") is not None:
        r = spec["rotation"]
        axis = np.asarray(r["axis"])
        norm = np.linalg.norm(axis)
        if norm == 0:
            raise scene.error(f"{key}.rotation.axis", "must not be the zero vector")
        v += np.cross(r["omega"] * axis / norm, x - np.asarray(r["origin"]))
    if spec.get("gradient") is not None:
        g = spec["gradient"]
        v += (x - np.asarray(g["origin"])) @ np.asarray(g["matrix"]).T
    if spec.get("point_data") is not None:
        name = spec["point_data"]
        if name not in mesh.point_data:
            raise scene.error(f"{key}.point_data", _no_field(name, mesh))
        data = np.asarray(mesh.point_data[name], dtype=np.float64)
        if data.ndim != 2 or data.shape[1] not in (2, 3):
            raise scene.error(f"{key}.point_data", f"field {name!r} must have 2 or 3 components per point, got shape {data.shape}")
        data = data[net.point_ids]
        v[:, : data.shape[1]] += data
    if spec.get("random") is not None:
        r = spec["random"]
        v += np.random.default_rng(r["seed"]).uniform(-r["amplitude"], r["amplitude"], v.shape)
    v[net.anchored] = 0.0
    return v

