"""The scene schema: every key, its type, default and meaning, and validation against it.

The schema is data (:class:`Table`, :class:`Named`, :class:`Key`); :func:`validate` walks a
parsed TOML document along it and returns a normalized copy (defaults filled in), raising
:class:`Invalid` with the key path of the first problem. :mod:`thermonet.scenes.reference`
writes the key reference that ``docs/scenes.md`` contains.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from typing import Any, Callable

from ..builders import CELL_EDGES
from ..integrators import available_integrators
from ..models import available_models
from ..implicit.core.newton import NEWTON_PATHS

NO_DEFAULT = object()


class Invalid(Exception):
    """A value that does not fit the schema; ``path`` is the key path from the document root."""

    def __init__(self, message: str, path: tuple[str, ...] = ()):
        super().__init__(message)
        self.message, self.path = message, tuple(path)


@dataclass(frozen=True)
class Key:
    """A leaf key: ``check(value)`` returns the normalized value or raises :class:`Invalid`."""

    check: Callable[[Any], Any]
    type: str
    doc: str
    default: Any = NO_DEFAULT
    required: bool = False


@dataclass(frozen=True)
class Table:
    """A table with fixed keys. optional: absent -> None (else absent -> all defaults).
    shorthand: turns a non-table value into a table (e.g. ``temperature = 500.0``)."""

    keys: dict[str, "Key | Table | Named"]
    doc: str
    optional: bool = False
    shorthand: Callable[[Any], dict] | None = None
    shorthand_doc: str = ""


@dataclass(frozen=True)
class Named:
    """A table whose keys the user names (regions, groups); every value follows ``entry``."""

    entry: "Key | Table"
    doc: str
    placeholder: str = "<name>"
    default: Any = field(default_factory=dict)


# ----------------------------------------------------------------------------------------------
# value checks


def _type_name(v) -> str:
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string",
            list: "an array", dict: "a table"}.get(type(v), type(v).__name__)


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def number(lo: float | None = None, *, above: float | None = None, hi: float | None = None):
    def check(v):
        if not _is_number(v):
            raise Invalid(f"must be a number, got {_type_name(v)} {v!r}")
        v = float(v)
        if not math.isfinite(v):
            raise Invalid(f"must be finite, got {v}")
        if lo is not None and v < lo:
            raise Invalid(f"must be >= {lo:g}, got {v:g}")
        if above is not None and v <= above:
            raise Invalid(f"must be > {above:g}, got {v:g}")
        if hi is not None and v > hi:
            raise Invalid(f"must be <= {hi:g}, got {v:g}")
        return v
    return check


def integer(lo: int | None = None):
    def check(v):
        if isinstance(v, bool) or not isinstance(v, int):
            raise Invalid(f"must be an integer, got {_type_name(v)} {v!r}")
        if lo is not None and v < lo:
            raise Invalid(f"must be >= {lo}, got {v}")
        return v
    return check


def boolean(v):
    if not isinstance(v, bool):
        raise Invalid(f"must be true or false, got {_type_name(v)} {v!r}")
    return v


def choice(choices):
    """A string out of ``choices`` (a tuple, or a function returning one, for registries)."""
    def check(v):
        valid = tuple(choices() if callable(choices) else choices)
        if not isinstance(v, str) or v.lower() not in valid:
            raise Invalid(f"must be one of {', '.join(valid)}; got {v!r}{_hint(v, valid)}")
        return v.lower()
    return check


def string(v):
    if not isinstance(v, str) or not v:
        raise Invalid(f"must be a non-empty string, got {_type_name(v)} {v!r}")
    return v


def vector(n: int = 3):
    def check(v):
        if not isinstance(v, list) or len(v) != n or not all(_is_number(x) for x in v):
            raise Invalid(f"must be an array of {n} numbers, got {v!r}")
        out = [float(x) for x in v]
        if not all(math.isfinite(x) for x in out):
            raise Invalid(f"must be finite, got {v!r}")
        return out
    return check


def matrix3(v):
    if not isinstance(v, list) or len(v) != 3:
        raise Invalid(f"must be a 3×3 array of numbers (three rows), got {v!r}")
    return [vector(3)(row) for row in v]


def list_of(item, what: str):
    def check(v):
        if not isinstance(v, list):
            raise Invalid(f"must be an array of {what}, got {_type_name(v)} {v!r}")
        out = []
        for i, x in enumerate(v):
            try:
                out.append(item(x))
            except Invalid as exc:
                raise Invalid(f"item {i}: {exc.message}") from None
        return out
    return check


def group_or_index(v):
    if isinstance(v, str) and v:
        return v
    if isinstance(v, int) and not isinstance(v, bool) and v >= 0:
        return v
    raise Invalid(f"must be a group name or a node index >= 0, got {v!r}")


def cadence(v):
    if v == "auto":
        return v
    if isinstance(v, bool) or not isinstance(v, int) or v < 0:
        raise Invalid(f'must be a number of steps >= 0 (0: never) or "auto", got {v!r}')
    return v


def gravity(v):
    if v is False:
        return None
    if v is True:
        raise Invalid("must be false (off) or an acceleration vector such as [0, 0, -9.81], got true")
    return vector(3)(v)


def rest_lengths(v):
    if v == "initial":
        return v
    return number(above=0)(v) if _is_number(v) else _fail(f'must be "initial" or a length > 0, got {v!r}')


def auto_or_bool(v):
    if v == "auto" or isinstance(v, bool):
        return v
    raise Invalid(f'must be true, false or "auto", got {v!r}')


def auto_or_steps(v):
    if v == "auto" or (isinstance(v, int) and not isinstance(v, bool) and v >= 1):
        return v
    raise Invalid(f'must be "auto" or a whole number of steps >= 1, got {_type_name(v)} {v!r}')


def retry(v):
    if isinstance(v, bool) or (isinstance(v, int) and v >= 0):
        return v
    raise Invalid(f"must be true, false or a number of retries >= 0, got {v!r}")


def energy_tolerance(v):
    if v is False:
        return v
    if v is True:
        raise Invalid("must be a relative tolerance > 0 or false (no energy guard), got true")
    return number(above=0)(v)


def any_table(v):
    if not isinstance(v, dict):
        raise Invalid(f"must be a table, got {_type_name(v)} {v!r}")
    return dict(v)


def material(v):
    """A material region: ``model`` plus parameter values; parameters are checked against the
    model in :func:`check_materials` (they depend on which model is named)."""
    if not isinstance(v, dict):
        raise Invalid(f"must be a table (model = ..., parameters = numbers), got {_type_name(v)} {v!r}")
    out = {}
    for k, x in v.items():
        if k == "model":
            out[k] = choice(_models)(x) if isinstance(x, str) else _fail(f"must be a model name, got {x!r}", (k,))
        elif _is_number(x) and math.isfinite(float(x)):
            out[k] = float(x)
        elif _is_number(x):
            raise Invalid(f"must be a finite number, got {x!r}", (k,))
        else:
            raise Invalid(f"must be a number, got {_type_name(x)} {x!r}", (k,))
    return out


def _fail(message, path=()):
    raise Invalid(message, path)


def _hint(v, valid) -> str:
    close = difflib.get_close_matches(str(v), list(valid), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _models():
    return available_models()


def _integrators():
    return available_integrators()


def _newton_paths():
    return NEWTON_PATHS


def _backends():
    return BACKENDS


#: compute backends a scene may name ("cuda": explicit integrators on a GPU, see thermonet.explicit.cuda)
BACKENDS = ("cpu", "cuda")

GENERATORS = ("chain", "triangle", "lattice")
FIELD_NAMES = ("displacement", "velocity", "momentum", "anchored", "node_temperature", "temperature",
               "entropy", "strain", "tension", "thermal_displacement", "material", "heat_rate")


# ----------------------------------------------------------------------------------------------
# the schema

_VELOCITY_KEYS = {
    "uniform": Key(vector(3), "[x, y, z]", "the same value at every free node"),
    "regions": Named(Key(vector(3), "[x, y, z]", "value at the nodes of node group <group>"),
                     "per node group (added to the rest)", "<group>"),
    "rotation": Table({
        "axis": Key(vector(3), "[x, y, z]", "rotation axis (normalized)", required=True),
        "omega": Key(number(), "number", "angular speed (rad per time unit)", required=True),
        "origin": Key(vector(3), "[x, y, z]", "a point on the axis", [0.0, 0.0, 0.0]),
    }, "rigid rotation v = omega axis × (x − origin)", optional=True),
    "gradient": Table({
        "matrix": Key(matrix3, "3×3 array", "velocity gradient G", required=True),
        "origin": Key(vector(3), "[x, y, z]", "where v = 0", [0.0, 0.0, 0.0]),
    }, "linear field v = G (x − origin), e.g. a uniform stretch", optional=True),
    "point_data": Key(string, "string", "name of a (n, 3) point-data field of the mesh"),
    "random": Table({
        "amplitude": Key(number(above=0), "number > 0", "each component uniform in [−amplitude, amplitude]", required=True),
        "seed": Key(integer(0), "integer >= 0", "random seed", 0),
    }, "seeded random values", optional=True),
}


# --- loads and probes (thermonet.loads); time functions also for baths and sources ---
def time_function_value(v):
    """A number or a table of a time function's keys; its keys are checked when the load is
    built (:func:`thermonet.timefunctions.time_function`), with the key's line."""
    if _is_number(v) or isinstance(v, dict):
        return v
    raise Invalid(f"must be a number or a time function table ({{rate = ...}}, {{end = ..., duration = ...}}, "
                  f"{{amplitude = ..., frequency = ...}}, {{table = [[t, v], ...]}}), got {_type_name(v)} {v!r}")


def node_group_or_indices(v):
    if isinstance(v, str) and v:
        return v
    return list_of(integer(0), "node indices")(v)


LOAD_TYPES = ("drive", "force")
PROBE_QUANTITIES = ("temperature", "strain", "tension", "displacement")

LOADS_SCHEMA = Named(Table({
    "type": Key(choice(LOAD_TYPES), "drive | force", "drive: the group's positions follow X + u(t) − u(0); "
                "force: a force f(t) on each of its nodes", required=True),
    "group": Key(node_group_or_indices, "string | array", "node group name or node indices", required=True),
    "velocity": Key(vector(3), "[vx, vy, vz]", "drive: constant velocity (u = v t); an axis of velocity 0 is not set (see free)"),
    "displacement": Key(time_function_value, "number | table", "drive: u as one function along direction, or a "
                        "table {x = f, y = g, z = h} of per-axis time functions (axes not given: see free)"),
    "force": Key(time_function_value, "number | table", "force: f as one function along direction, or per axis "
                 "{x = f, y = g, z = h}"),
    "direction": Key(vector(3), "[x, y, z]", "the direction of a displacement or force given as one function"),
    "free": Key(boolean, "boolean", "drive: the axes u does not set are free (true) or held (false)", False),
    "total": Key(boolean, "boolean", "force: f is the group's total, spread over its nodes by mass", False),
}, "a load"), "driven node groups and forces (docs/loads.md)", "<name>")

PROBES_SCHEMA = Named(Table({
    "group": Key(string, "string", "a node group (displacement) or spring group (the rest); "
                 "for springs also a node group: the springs between its nodes", required=True),
    "quantity": Key(choice(PROBE_QUANTITIES), " | ".join(PROBE_QUANTITIES), "what is measured", required=True),
    "every": Key(integer(1), "integer >= 1", "steps between rows (default: the diagnostics cadence)"),
}, "a probe"), "per-group time series (mean, min, max) in probe_<name>.csv beside diagnostics.csv", "<name>")
# --- end loads and probes ---


def _temperature_shorthand(v):
    return {"uniform": v}


SCHEMA = Table({
    "name": Key(string, "string", "file stem of the outputs (default: the scene file's stem)"),
    "description": Key(lambda v: v if isinstance(v, str) else _fail("must be a string"), "string", "free text", ""),
    "net": Table({
        "mesh": Key(string, "path", "mesh file meshio reads (.msh, .vtu, ...), relative to the scene file"),
        "generator": Key(choice(GENERATORS), " | ".join(GENERATORS), "built-in net instead of a mesh"),
        "cells": Key(list_of(choice(tuple(CELL_EDGES)), "cell types"), "array of cell types",
                     "mesh cell types whose edges become springs (default: all of " + ", ".join(CELL_EDGES) + ")"),
        "rest_lengths": Key(rest_lengths, '"initial" | number > 0',
                            "spring rest lengths l0: the initial lengths, or one value for all springs", "initial"),
        "lattice": Table({
            "shape": Key(list_of(integer(0), "integers"), "[nx, ny, nz]", "cells per axis (0 on an axis: a 2D lattice)", [10, 10, 10]),
            "spacing": Key(number(above=0), "number > 0", "node spacing", 1.0),
            "neighbours": Key(lambda v: v if v in (6, 18, 26) else _fail(f"must be 6, 18 or 26, got {v!r}"),
                              "6 | 18 | 26", "cube edges (6), + face diagonals (18), + body diagonals (26)", 6),
            "jitter": Key(number(0, hi=0.49), "number in [0, 0.49]", "random node displacement, fraction of spacing", 0.0),
            "seed": Key(integer(0), "integer >= 0", "seed of the jitter", 0),
        }, "parameters of the lattice generator (node groups xmin, xmax, ymin, ymax, zmin, zmax)", optional=True),
    }, "the spring net: exactly one of mesh or generator"),
    "materials": Named(Key(material, "table", "model = name (default hencky), then parameter = value (the heat-flow ones "
                           "too: g, g_star); or continuum properties (youngs_modulus, density, heat_capacity, thermal_expansion, "
                           "conductivity, ...: docs/continuum.md)"),
                       "material regions, applied in file order (later regions win where they overlap). "
                       "<region> is all (every spring) or a spring group of the mesh. One model per run; "
                       "parameters not given take the model's defaults", "<region>"),
    "initial": Table({
        "temperature": Table({
            "uniform": Key(number(above=0), "number > 0", "θ(0) of every spring (default: each spring's theta0)"),
            "regions": Named(Key(number(above=0), "number > 0", "θ(0) of the springs of group <group>"),
                             "per spring group (overrides uniform; file order)", "<group>"),
            "perturbation": Key(number(0), "number >= 0", "add a seeded uniform random value in [−p, p]", 0.0),
            "seed": Key(integer(0), "integer >= 0", "seed of the perturbation", 0),
        }, "initial spring temperatures (needs effects.thermal)", optional=True,
            shorthand=_temperature_shorthand, shorthand_doc="a number: uniform"),
        "velocity": Table(_VELOCITY_KEYS, "initial velocities: the sum of the parts given; "
                          "anchored nodes are set to rest", optional=True),
        "momentum": Table(_VELOCITY_KEYS, "initial momenta instead of velocities (same keys)", optional=True),
        "mass": Table({
            "uniform": Key(number(above=0), "number > 0", "mass of every node"),
            "density": Key(number(above=0), "number > 0",
                           "lumped masses: density × measure of the highest-dimensional cells, shared by their vertices"),
            "point_data": Key(string, "string", "name of a point-data field of the mesh"),
            "regions": Named(Key(number(above=0), "number > 0", "mass of each node of group <group>"),
                             "per node group (overrides the rest; file order)", "<group>"),
        }, "node masses: at most one of uniform, density, point_data (default: the net's own, 1 for meshes)",
            optional=True),
    }, "initial state"),
    "effects": Table({
        "thermal": Key(boolean, "boolean", "thermal coupling; false: a purely mechanical run, every spring held "
                       "at its reference temperature, no thermal arrays at all", True),
        "anchors": Key(list_of(group_or_index, "group names or node indices"), "array",
                       "node groups and/or node indices fixed in space (default: the net's own; [] for none)"),
        "gravity": Key(gravity, "false | [gx, gy, gz]",
                       "uniform acceleration, an added potential −Σ m g·x (energy stays conserved); false: off", None),
        "conduction": Key(boolean, "boolean", "Fourier heat conduction between springs through their conductance "
                          "g (a material parameter); needs thermal", False),
        "conduction_every": Key(auto_or_steps, '"auto" | integer ≥ 1', "conduction every k steps, sweeps over k h: "
                                "\"auto\" picks k (and its sub-sweeps) from the conduction's fastest rate "
                                "(docs/heat.md)", "auto"),
        "conduction_sweeps": Key(integer(1), "integer ≥ 1", "with an integer conduction_every: each conduction "
                                 "cycle's boundary swept j times, as 2j half sweeps over k h / (2 j) (default 1; "
                                 "\"auto\" chooses j)", None),
        "thermal_waves": Key(boolean, "boolean", "Green–Naghdi type II thermal waves through g_star (a material "
                             "parameter); explicit splittings only; needs thermal", False),
    }, "the physics the scene switches on; what is off is not computed"),
    "baths": Named(Table({
        "group": Key(string, "string", "node group held at the bath temperature", required=True),
        "temperature": Key(time_function_value, "number > 0 | time function",
                           "θ_b(t): a number, {start, end, duration} (ramp), {start, rate}, "
                           "{amplitude, frequency, phase, offset} or {table = [[t, θ], ...]}", required=True),
    }, "a heat bath"), "heat baths (need effects.conduction): every spring touching the group's nodes exchanges "
        "heat with the bath through its g; the heat each bath gives is a diagnostics column", "<bath>"),
    "sources": Named(Table({
        "group": Key(string, "string", "spring group (a material region of the mesh) receiving the power",
                     required=True),
        "power": Key(time_function_value, "number | time function", "P(t) per spring (negative: a sink), "
                     "same forms as a bath temperature", required=True),
    }, "a heat source"), "heat sources (need effects.conduction); the heat each gives is a diagnostics column",
        "<source>"),
    "integrator": Table({
        "name": Key(choice(_integrators), "string", "integrator (thermonet.available_integrators())", "co2"),
        "h": Key(number(above=0), "number > 0", "time step", required=True),
        "t_end": Key(number(above=0), "number > 0", "final time, a whole number of steps of h (or give steps)"),
        "steps": Key(integer(0), "integer >= 0", "number of steps (or give t_end)"),
        "backend": Key(choice(_backends), "string", "compute backend: cpu, or cuda (explicit integrators on a GPU)", "cpu"),
        "threads": Key(integer(1), "integer >= 1", "threads of the parallel kernels (default: all cores)"),
        "parallel": Key(auto_or_bool, 'true | false | "auto"', "multi-threaded kernels; auto: by net size", "auto"),
        "renumber": Key(boolean, "boolean", "reorder nodes/springs internally for memory locality", True),
        "alpha": Key(number(0, hi=1), "number in [0, 1]", "α of the gtr family"),
        "tolerance": Key(number(above=0), "number > 0", "Newton tolerance (implicit integrators)"),
        "max_iterations": Key(integer(1), "integer >= 1", "Newton iterations per step (implicit)"),
        "retry": Key(retry, "boolean | integer", "retry a failed Newton step with smaller sub-steps (implicit)"),
        "linear_solver": Key(string, "string", "sparse linear solver of the Newton steps (implicit)"),
        "newton_path": Key(choice(_newton_paths), "string", "Newton's path (implicit): auto, compiled (whole steps "
                           "in one compiled call), compiled-dense, or sparse"),
        "options": Key(any_table, "table", "any further options, passed to the integrator as they are"),
        "check_step": Key(boolean, "boolean", "refuse a step far above the stability limit (h > 1.5 h_max at the "
                          "initial state) and stop a run whose step goes above 1.5 h_max re-estimated while it "
                          "runs (docs/robustness.md); false: warn only (--allow-unstable-step)", True),
        "energy_tolerance": Key(energy_tolerance, "number > 0 | false", "energy guard: stop the run when "
                                "|H − H(0)|/|H(0)| exceeds this (checked at the diagnostics cadence; the state is "
                                "rewound to the previous stop); false: no guard", 0.1),
        "stretch_bounds": Key(list_of(number(above=0), "two numbers"), "array of 2 numbers",
                              "admissible stretches l/l0 (lo < 1 < hi); the kernel stops a run at the first step "
                              "in which a spring leaves them", [1e-4, 1e4]),
    }, "time integration"),
    "loads": LOADS_SCHEMA,  # loads
    "probes": PROBES_SCHEMA,  # probes
    "output": Table({
        "folder": Key(string, "path", "output folder, relative to the working directory "
                      "(default thermonet-out/<name>; <folder>-2, -3, ... when it holds a previous run; "
                      "the CLI's --out overrides it)"),
        "frames_every": Key(cadence, 'integer >= 0 | "auto"', "a VTU frame every k steps (0: none; auto: about 100)", "auto"),
        "diagnostics_every": Key(cadence, 'integer >= 1 | "auto"', "a diagnostics row every k steps (auto: about 1000)", "auto"),
        "checkpoint_every": Key(cadence, 'integer >= 0 | "auto"', "a checkpoint every k steps (0: none; auto: about 10)", "auto"),
        "fields": Key(list_of(choice(FIELD_NAMES), "field names"), "array",
                      "fields written to the frames (default: all that exist; thermal ones need effects.thermal)"),
    }, "what is written, and how often"),
}, "a scene")


# ----------------------------------------------------------------------------------------------
# validation


def validate(value, spec=SCHEMA, path: tuple[str, ...] = ()):
    """``value`` normalized along ``spec``; raises :class:`Invalid` with the full key path."""
    if isinstance(spec, Key):
        try:
            return spec.check(value)
        except Invalid as exc:
            raise Invalid(exc.message, path + exc.path) from None
    if isinstance(spec, Named):
        if not isinstance(value, dict):
            raise Invalid(f"must be a table of {spec.placeholder} = ..., got {_type_name(value)} {value!r}", path)
        return {name: validate(v, spec.entry, path + (name,)) for name, v in value.items()}
    if not isinstance(value, dict):
        if spec.shorthand is not None and not isinstance(value, list):
            value = spec.shorthand(value)
        else:
            raise Invalid(f"must be a table, got {_type_name(value)} {value!r}", path)
    unknown = [k for k in value if k not in spec.keys]
    if unknown:
        k = unknown[0]
        raise Invalid(f"unknown key{_hint(k, spec.keys)}; valid keys: {', '.join(spec.keys)}", path + (k,))
    out = {}
    for name, sub in spec.keys.items():
        if name in value:
            out[name] = validate(value[name], sub, path + (name,))
        elif isinstance(sub, Key):
            if sub.default is not NO_DEFAULT:
                out[name] = sub.default
        elif isinstance(sub, Named):
            out[name] = dict(sub.default)
        elif sub.optional:
            out[name] = None
        else:
            out[name] = validate({}, sub, path + (name,))
    missing = [n for n, s in spec.keys.items() if isinstance(s, Key) and s.required and n not in value]
    if missing:
        raise Invalid("required key is missing", path + (missing[0],))
    return out
