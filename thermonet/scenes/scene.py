"""A scene: a validated TOML description of one run, and where each of its keys came from."""

from __future__ import annotations

import copy
import hashlib
import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError
from ..heat.multirate import SWEEPS_WITH_AUTO
from ..heat.parameters import TRANSPORT_PARAMETERS
from ..materials.continuum import CONTINUUM_KEYS, region_problem
from ..models import get_model
from ..step_policy import whole_steps
from .build import build_scene
from .schema import FIELD_NAMES, Invalid, validate
from .source import SceneError, apply_overrides, key_lines, parse_toml

#: the scene ``thermonet run`` runs when given none (a 3D truss block): package data beside its
#: mesh, so an installed wheel has it; scenes/default.toml is the same scene in the source tree
DEFAULT_SCENE = Path(__file__).resolve().parents[1] / "data" / "default.toml"

#: integrator keys a resumed run may change: where the run ends, its guards, and how each step's
#: equations are solved (threads, the Newton path and linear solver, iteration caps), which
#: change at most the last bits of a step, never which trajectory it follows
FREE_ON_RESUME = ("t_end", "steps", "check_step", "energy_tolerance", "threads", "parallel", "linear_solver",
                  "newton_path", "max_iterations", "retry")

THERMAL_OUTPUTS = ("temperature", "node_temperature", "entropy", "thermal_displacement", "heat_rate")


@dataclass
class Scene:
    """A validated scene.

    data: the normalized scene (every key of the schema, defaults filled in).
    file: the scene file (for messages). base_dir: folder that relative paths start from.
    text: the TOML text. overrides: the ``KEY=VALUE`` strings applied on top of it.
    """

    data: dict
    file: str
    base_dir: str
    text: str
    overrides: tuple[str, ...] = ()
    _lines: dict = field(default_factory=dict, repr=False)
    _overridden: set = field(default_factory=set, repr=False)

    # ------------------------------------------------------------------------------------------
    def error(self, path, message: str) -> SceneError:
        """A :class:`SceneError` for key ``path`` (tuple or dotted string), with its line."""
        if isinstance(path, str):
            path = tuple(path.split(".")) if path else ()
        key = ".".join(path) or None
        for i in range(len(path), 0, -1):
            if path[:i] in self._overridden:
                return SceneError(message, file=f"--set {'.'.join(path[:i])}", key=key)
        below = sorted(k for k in self._overridden if path and k[:len(path)] == path)
        if below:  # e.g. --set materials.sof.c=3 made the table materials.sof
            return SceneError(message, file=f"--set {'.'.join(below[0])}", key=key)
        line = None
        for i in range(len(path), 0, -1):
            if path[:i] in self._lines:
                line = self._lines[path[:i]]
                break
        return SceneError(message, file=self.file, line=line, key=key)

    def __getitem__(self, key: str):
        return self.data[key]

    @property
    def name(self) -> str:
        name = self.data.get("name") or Path(self.file).stem
        return re.sub(r"[^A-Za-z0-9_.-]+", "_", name) or "scene"

    def mesh_path(self) -> str | None:
        mesh = self.data["net"].get("mesh")
        return None if mesh is None else os.path.normpath(os.path.join(self.base_dir, mesh))

    def trajectory(self) -> dict:
        """The keys that define the trajectory: net, materials, initial state, effects, loads,
        heat flow and integrator, without :data:`FREE_ON_RESUME` (the end, the guards, how the
        steps are computed) and the outputs."""
        physics = {k: v for k, v in self.data.items() if k not in ("output", "name", "description", "probes")}
        physics["integrator"] = {k: v for k, v in physics["integrator"].items() if k not in FREE_ON_RESUME}
        return physics

    @property
    def hash(self) -> str:
        """SHA-256 of what determines the trajectory (:meth:`trajectory`) and the mesh file's bytes."""
        h = hashlib.sha256(json.dumps(self.trajectory(), sort_keys=True, default=str).encode())
        mesh = self.mesh_path()
        if mesh is not None and os.path.isfile(mesh):
            with open(mesh, "rb") as f:
                h.update(hashlib.sha256(f.read()).digest())
        return h.hexdigest()

    def total_steps(self) -> int:
        """Steps from t = 0 to the scene's end (t_end must be a whole number of steps; checked
        when the scene is loaded)."""
        integ = self.data["integrator"]
        if integ.get("steps") is not None:
            return int(integ["steps"])
        return whole_steps(integ["t_end"], integ["h"])

    def cadence(self, key: str, total: int) -> int:
        """output.<key> in steps ("auto" resolved against ``total`` steps)."""
        value = self.data["output"][key]
        if value != "auto":
            return int(value)
        per = {"frames_every": 100, "diagnostics_every": 1000, "checkpoint_every": 10}[key]
        return max(1, total // per)

    def output_fields(self) -> list[str]:
        fields = self.data["output"].get("fields")
        if fields is None:
            effects = self.data["effects"]
            fields = [f for f in FIELD_NAMES if (effects["thermal"] or f not in THERMAL_OUTPUTS)
                      and (effects["conduction"] or f != "heat_rate")]
        return fields

    def describe(self) -> dict:
        """What a checkpoint stores to rebuild this scene."""
        return {"name": self.name, "hash": self.hash, "file": os.path.abspath(self.file) if os.path.exists(self.file) else self.file,
                "base_dir": os.path.abspath(self.base_dir), "text": self.text, "overrides": list(self.overrides)}

    def as_run(self) -> str:
        """The scene as it runs, as TOML: its file with the ``--set`` overrides applied and the
        mesh path made absolute (so the copy runs from anywhere); what ``thermonet run`` writes
        beside its output as ``scene-as-run.toml``."""
        raw = parse_toml(self.text, self.file)
        _override(raw, self.overrides)
        net = raw.get("net")
        if isinstance(net, dict) and isinstance(net.get("mesh"), str):
            net["mesh"] = os.path.normpath(os.path.join(self.base_dir, net["mesh"]))
        head = [f"# the scene as run: {self.file}"
                + (f", with {' '.join('--set ' + o for o in self.overrides)}" if self.overrides else ""),
                "# (overrides applied, the mesh path made absolute; comments of the original are not kept)"]
        return "\n".join(head + [""] + to_toml(raw)) + "\n"

    def build(self):
        """The :class:`~thermonet.scenes.build.BuiltScene` (net, simulation, material ids)."""
        return build_scene(self)


def trajectory_changes(before: Scene, after: Scene) -> list[str]:
    """``key: old → new`` for each key of :meth:`Scene.trajectory` that differs, dotted, sorted."""
    def flat(d, prefix=()):
        out = {}
        for k, v in d.items():
            if isinstance(v, dict) and v:
                out.update(flat(v, prefix + (k,)))
            else:
                out[".".join(prefix + (k,))] = v
        return out

    a, b = flat(before.trajectory()), flat(after.trajectory())
    missing = object()
    shown = lambda v: "(absent)" if v is missing else json.dumps(v, default=str)  # noqa: E731
    return [f"{k}: {shown(a.get(k, missing))} → {shown(b.get(k, missing))}" for k in sorted(set(a) | set(b))
            if a.get(k, missing) != b.get(k, missing)]


# ----------------------------------------------------------------------------------------------


def load_scene(path=None, overrides=()) -> Scene:
    """Read and validate a scene file (default: the built-in default scene)."""
    path = os.fspath(path) if path is not None else str(DEFAULT_SCENE)
    if os.path.isdir(path):
        raise SceneError("is a folder, not a scene file (.toml)", file=path)
    if not os.path.isfile(path):
        where = "the built-in default scene" if path == str(DEFAULT_SCENE) else "scene file"
        raise SceneError(f"{where} {path} does not exist")
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"cannot read it: {getattr(exc, 'strerror', None) or exc}", file=path) from None
    return scene_from_text(text, file=path, base_dir=os.path.dirname(os.path.abspath(path)), overrides=overrides)


def scene_from_text(text: str, overrides=(), *, file: str = "<scene>", base_dir: str = ".") -> Scene:
    """Parse, override and validate a scene given as TOML text."""
    raw = parse_toml(text, file)
    overridden = _override(raw, overrides)
    scene = Scene({}, file, base_dir, text, tuple(overrides), key_lines(text), overridden)
    try:
        scene.data = validate(copy.deepcopy(raw))
    except Invalid as exc:
        raise scene.error(exc.path, exc.message) from None
    check(scene)
    return scene


def _override(raw: dict, overrides) -> set:
    """Apply ``KEY=VALUE`` overrides to a parsed scene in place; returns the paths set."""
    overridden = apply_overrides(raw, overrides)
    for given, other in ((("integrator", "t_end"), "steps"), (("integrator", "steps"), "t_end")):
        if given in overridden and ("integrator", other) not in overridden:
            raw.get("integrator", {}).pop(other, None)  # setting one end condition replaces the other
    return overridden


def to_toml(data: dict) -> list[str]:
    """Lines of a TOML document holding ``data`` (tables, arrays, inline tables in arrays,
    strings, numbers, booleans, dates), as :func:`tomllib.loads` reads it back."""
    bare = re.compile(r"[A-Za-z0-9_-]+")

    def key(k) -> str:
        return k if bare.fullmatch(k) else json.dumps(k, ensure_ascii=False)

    def value(v) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, int):
            return str(v)
        if isinstance(v, float):
            return "nan" if v != v else "inf" if v == math.inf else "-inf" if v == -math.inf else repr(v)
        if isinstance(v, str):
            return json.dumps(v, ensure_ascii=False)
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(value(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{key(k)} = {value(x)}" for k, x in v.items()) + " }"
        return v.isoformat()  # dates and times

    lines: list[str] = []

    def table(path, d: dict) -> None:
        plain = [(k, v) for k, v in d.items() if not isinstance(v, dict)]
        tables = [(k, v) for k, v in d.items() if isinstance(v, dict)]
        if path and (plain or not tables):
            lines.extend(["", f"[{'.'.join(key(p) for p in path)}]"] if lines else [f"[{'.'.join(key(p) for p in path)}]"])
        lines.extend(f"{key(k)} = {value(v)}" for k, v in plain)
        for k, v in tables:
            table(path + (k,), v)

    table((), data)
    return lines


def check(scene: Scene) -> None:
    """Rules across keys: one of mesh/generator, one of t_end/steps, and so on."""
    d = scene.data
    net, init, effects, integ, out = d["net"], d["initial"], d["effects"], d["integrator"], d["output"]
    if (net.get("mesh") is None) == (net.get("generator") is None):
        raise scene.error("net", "give exactly one of net.mesh (a mesh file) or net.generator (chain, triangle, lattice)")
    if net.get("lattice") is not None and net.get("generator") != "lattice":
        raise scene.error("net.lattice", 'parameters for the lattice generator, but net.generator is not "lattice"')
    if net.get("cells") is not None and net.get("mesh") is None:
        raise scene.error("net.cells", "selects mesh cell blocks, but the scene has no net.mesh")
    if (integ.get("t_end") is None) == (integ.get("steps") is None):
        raise scene.error("integrator", "give exactly one of integrator.t_end or integrator.steps")
    if integ.get("t_end") is not None:
        try:
            whole_steps(integ["t_end"], integ["h"])
        except InputError as exc:
            raise scene.error("integrator.t_end", f"{exc} (integrator.steps)") from None
    if init["velocity"] is not None and init["momentum"] is not None:
        raise scene.error("initial.momentum", "give initial.velocity or initial.momentum, not both")
    mass = init["mass"]
    if mass is not None:
        given = [k for k in ("uniform", "density", "point_data") if mass.get(k) is not None]
        if len(given) > 1:
            raise scene.error(f"initial.mass.{given[1]}", f"give at most one of initial.mass.uniform, density, point_data (got {', '.join(given)})")
        for k in ("density", "point_data"):
            if mass.get(k) is not None and net.get("mesh") is None:
                raise scene.error(f"initial.mass.{k}", "needs a mesh (net.mesh)")
    for kind in ("velocity", "momentum"):
        if init[kind] is not None and init[kind].get("point_data") is not None and net.get("mesh") is None:
            raise scene.error(f"initial.{kind}.point_data", "needs a mesh (net.mesh)")
    if not effects["thermal"]:
        if init["temperature"] is not None:
            raise scene.error("initial.temperature", "initial temperatures given but effects.thermal is false "
                              "(a purely mechanical run has no temperatures)")
        for f in out.get("fields") or ():
            if f in THERMAL_OUTPUTS:
                raise scene.error("output.fields", f"field {f!r} needs effects.thermal = true")
    for key in ("conduction", "thermal_waves"):
        if effects[key] and not effects["thermal"]:
            raise scene.error(f"effects.{key}", f"effects.{key} needs effects.thermal = true (heat flows between "
                              "springs' temperatures)")
    if "heat_rate" in (out.get("fields") or ()) and not effects["conduction"]:
        raise scene.error("output.fields", "field 'heat_rate' needs effects.conduction = true")
    for table in ("baths", "sources"):
        if d[table] and not effects["conduction"]:
            name = next(iter(d[table]))
            raise scene.error(f"{table}.{name}", f"{table} need effects.conduction = true")
    if out["diagnostics_every"] == 0:
        raise scene.error("output.diagnostics_every", 'must be >= 1 or "auto" (diagnostics cannot be switched off)')
    every = effects["conduction_every"]
    if effects.get("conduction_sweeps") is not None and every == "auto":
        raise scene.error("effects.conduction_sweeps", SWEEPS_WITH_AUTO)
    if effects["conduction"] and every != "auto":
        total = scene.total_steps()
        cadences = [scene.cadence(k, total) for k in ("frames_every", "diagnostics_every", "checkpoint_every")]
        bad = [c for c in cadences + [total] if c > 0 and c % every]
        if bad:
            raise scene.error("effects.conduction_every", f"{every} does not divide the output cadences (frames, "
                              f"diagnostics, checkpoints every {', '.join(map(str, cadences))} steps) and the run's "
                              f"{total} steps ({bad[0]} is not a multiple of {every}): an output inside a conduction "
                              'cycle is only first order; give a divisor or "auto"')
    models = {r.get("model", "hencky"): region for region, r in d["materials"].items()}
    if len(models) > 1:
        listing = ", ".join(f"{m} in materials.{r}" for m, r in models.items())
        second = list(models.values())[1]
        raise scene.error(f"materials.{second}.model",
                          f"a run uses one model, but the scene names several ({listing}); "
                          "per-region materials are per-region parameter values of one model")
    model = get_model(next(iter(models), "hencky"))
    # --- continuum materials (docs/continuum.md) ---
    known = ["model", *model.parameters, *TRANSPORT_PARAMETERS, *CONTINUUM_KEYS]
    for region, params in d["materials"].items():  # a typo, before what it leaves missing
        for k in params:
            if k not in known:
                import difflib

                close = difflib.get_close_matches(k, known, n=1)
                raise scene.error(f"materials.{region}.{k}",
                                  f"model {model.name!r} has no parameter {k!r}"
                                  + (f" (did you mean {close[0]!r}?)" if close else "")
                                  + f"; its parameters: {', '.join(model.parameters)} (and the heat-flow ones: "
                                  f"{', '.join(TRANSPORT_PARAMETERS)}; or continuum properties: "
                                  f"{', '.join(CONTINUUM_KEYS)})")

    for region, params in d["materials"].items():
        problem = region_problem(model, params)
        if problem is not None:
            raise scene.error(f"materials.{region}.{problem[0]}", problem[1])
        if any(k in CONTINUUM_KEYS for k in params) and net.get("mesh") is None:
            raise scene.error(f"materials.{region}", "continuum properties need a mesh (net.mesh): the rule uses "
                              "each spring's share of the cells' volume")
    continuum = [r for r, params in d["materials"].items() if any(k in CONTINUUM_KEYS for k in params)]
    if continuum and init["mass"] is not None:
        raise scene.error("initial.mass", f"node masses come from the density of the continuum material "
                          f"materials.{continuum[0]}; remove initial.mass")
    # --- end continuum materials ---
    for region, params in d["materials"].items():
        for k, v in params.items():
            if k == "model" or k in CONTINUUM_KEYS:
                continue
            if k in TRANSPORT_PARAMETERS:
                if not v >= 0:
                    raise scene.error(f"materials.{region}.{k}", f"must be ≥ 0, got {v:g}")
                continue
            if k not in model.parameters:
                raise scene.error(f"materials.{region}.{k}",
                                  f"model {model.name!r} has no parameter {k!r}; its parameters: {', '.join(model.parameters)} "
                                  f"(and the heat-flow ones: {', '.join(TRANSPORT_PARAMETERS)}; or continuum "
                                  f"properties: {', '.join(CONTINUUM_KEYS)})")
            if k in model.positive and not v > 0:
                raise scene.error(f"materials.{region}.{k}", f"must be > 0, got {v:g}")
