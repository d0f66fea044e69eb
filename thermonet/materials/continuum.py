"""Continuum materials: a region's E, α, ρ, c_v, k (and k*) turned into spring parameters.

The isotropic rule (docs/continuum.md). Each spring e of a net read from a mesh has a volume share
V_e (``Net.spring_volumes``: every cell of the highest dimension split equally over its edges;
times a thickness for 2D cells, a cross-section area for 1D ones). For a net of dimension d:

    stiffness   c_e = d(d+1)/2 E V_e        (6 E V in 3D, 3 E V in 2D, E A l in 1D)
    expansion   β_e = α c_e                 (free thermal strain α Δθ, no stress)
    capacity    C0_e = c_v V_e,             masses: ρ V_e shared by the spring's two ends
    conduction  g_e = 2d k V_e / l_e²       (6 k V / l² in 3D, 4 k V / l² in 2D, 2 k A / l in 1D)
    GN-II       g*_e = 2d k* V_e / l_e²

and in 2D and 3D the conductances times the net's junction factor f ≥ 1 (:func:`junction_factor`:
what eliminating the junction nodes costs a uniform gradient, restored; f → 1 under refinement).

``c`` is the hencky model's stiffness; the quadratic model's ``E`` is the same spring stiffness
as c / l0. A central-force net has a fixed Poisson's ratio (1/4 in 3D, 1/3 in 2D).
"""

from __future__ import annotations

import dataclasses
from typing import Mapping, NamedTuple

import numpy as np

from ..errors import InputError
from .rigidity import net_dimension, require_rigid, span_dimension

#: continuum properties a material region (or the API's ``parameters``) may give, SI units
CONTINUUM_KEYS = {
    "youngs_modulus": "Young's modulus E (Pa)",
    "thermal_expansion": "linear thermal expansion coefficient α (1/K)",
    "density": "mass density ρ (kg/m³)",
    "heat_capacity": "volumetric heat capacity c_v (J/(m³ K))",
    "conductivity": "thermal conductivity k (W/(m K))",
    "gn2_constant": "Green–Naghdi type II constant k* (W/(m K² s)): thermal-wave energy ∫ k*/2 |∇Φ|² dV",
    "thickness": "thickness of a 2D (triangle, quad) net (m)",
    "area": "cross-section area of a 1D (line) net (m²)",
}
#: properties that must be given (the others default to 0: no expansion, no conduction, no waves)
REQUIRED = ("youngs_modulus", "density", "heat_capacity")
#: properties that may be 0 (thermal_expansion may also be negative)
NON_NEGATIVE = ("conductivity", "gn2_constant")
#: the spring-stiffness parameter of each model the rule knows
STIFFNESS = {"hencky": "c", "quadratic": "E"}
#: spring parameters the rule sets: giving them beside continuum properties is an error
DERIVED = ("beta", "C0", "g", "g_star")


class ContinuumMap(NamedTuple):
    """What the rule made of a net: volume (m,) per spring (with thickness or area; NaN for
    springs set by spring parameters), the dimension the net is elastic in (its cells', or the
    span of a net of line cells), the per-spring properties used, and the junction factor the
    conductances were scaled by (:func:`junction_factor`; 1 for line nets)."""

    volume: np.ndarray
    dimension: int
    properties: dict
    junction_factor: float = 1.0


def correct_conductances(net, values: dict, springs: np.ndarray) -> float:
    """Scale ``values``' g and g_star (m,) on ``springs`` by :func:`junction_factor` of those
    springs' conductances (2D and 3D nets; line nets conduct along their springs exactly)."""
    if net.cell_dimension < 2:
        return 1.0
    key = "g" if "g" in values else "g_star" if "g_star" in values else None
    if key is None:
        return 1.0
    own = np.zeros(net.n_springs)
    own[springs] = values[key][springs]
    f = junction_factor(net, own)
    for name in ("g", "g_star"):
        if name in values:
            values[name][springs] *= f
    return f


def is_continuum(parameters: Mapping | None) -> bool:
    """Whether ``parameters`` gives any continuum property."""
    return any(k in CONTINUUM_KEYS for k in (parameters or {}))


def derived_parameters(model) -> tuple[str, ...]:
    """The spring parameters the rule sets for ``model`` (stiffness, beta, C0, g, g_star)."""
    return (stiffness_name(model),) + DERIVED


def stiffness_name(model) -> str:
    if model.name not in STIFFNESS:
        raise InputError(f"continuum properties need the hencky or quadratic model (the rule knows their "
                         f"stiffness parameter); model {model.name!r} takes spring parameters only")
    return STIFFNESS[model.name]


def check_properties(properties: Mapping, where: str, n_springs: int | None = None) -> dict:
    """Continuum properties checked (finite; E, ρ, c_v, thickness, area > 0; k, k* ≥ 0; the
    required ones present): name -> float or (m,) array. Errors name ``where`` and the key."""
    unknown = [k for k in properties if k not in CONTINUUM_KEYS]
    if unknown:
        raise InputError(f"{where}: {unknown[0]!r} is not a continuum property; they are {', '.join(CONTINUUM_KEYS)}")
    missing = [k for k in REQUIRED if k not in properties]
    if missing:
        raise InputError(f"{where}: continuum material without {missing[0]!r} ({CONTINUUM_KEYS[missing[0]]}); "
                         f"a continuum material gives {', '.join(REQUIRED)}")
    return {key: check_value(key, value, where, n_springs) for key, value in properties.items()}


def check_value(key: str, value, where: str, n_springs: int | None = None):
    """One continuum property checked: a float, or a (m,) array when ``n_springs`` is given."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{where}: {key} must be a number, got {value!r}") from None
    if arr.ndim and (n_springs is None or arr.shape != (n_springs,)):
        raise InputError(f"{where}: {key} must be a number or one value per spring ({n_springs}), got shape {arr.shape}")
    flat = arr.ravel()
    if key == "thermal_expansion":
        bad, rule = ~np.isfinite(flat), "finite"
    elif key in NON_NEGATIVE:
        bad, rule = ~(np.isfinite(flat) & (flat >= 0)), "finite and ≥ 0"
    else:
        bad, rule = ~(np.isfinite(flat) & (flat > 0)), "finite and > 0"
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        at = f" (spring {i})" if arr.ndim else ""
        raise InputError(f"{where}: {key} must be {rule}, got {flat[i]:g}{at}")
    return float(arr) if arr.ndim == 0 else arr


def spring_volumes(net, properties: Mapping, springs: np.ndarray, where: str) -> tuple[np.ndarray, int]:
    """(len(springs),) volume V_e of the listed springs: the mesh share times thickness (2D) or
    area (1D); and the net's dimension d."""
    if net.spring_volumes is None or not net.cell_dimension:
        raise InputError(f"{where}: continuum properties need a net read from a mesh (read_mesh, from_meshio), "
                         f"which knows each spring's share of the cells' volume; {net.source} does not")
    d = int(net.cell_dimension)
    if d == 2:
        if span_dimension(net.positions) == 3:
            raise InputError(f"{where}: the triangles or quads of {net.source} do not lie in a plane; the rule "
                             "knows flat 2D nets (membranes in their plane), not shells")
    extra = {2: "thickness", 1: "area"}.get(d)
    for key in ("thickness", "area"):
        if key in properties and key != extra:
            raise InputError(f"{where}: {key} is for {'2D' if key == 'thickness' else '1D'} nets; "
                             f"this net's cells are {d}D")
    if extra is not None and extra not in properties:
        raise InputError(f"{where}: a {d}D net needs {extra!r} ({CONTINUUM_KEYS[extra]}) to turn its cells' "
                         f"{'areas' if d == 2 else 'lengths'} into volumes")
    share = net.spring_volumes[springs]
    empty = share <= 0
    if empty.any():
        e = int(springs[np.flatnonzero(empty)[0]])
        raise InputError(f"{where}: spring {e} (nodes {net.edges[e].tolist()}) belongs to no {d}D cell, so it has "
                         "no volume share; give its region spring parameters instead")
    scale = _per_spring(properties.get(extra, 1.0), springs)
    return share * scale, d


def spring_parameters(net, model, properties: Mapping, springs: np.ndarray, where: str) -> tuple[dict, np.ndarray]:
    """The rule for the listed springs: {parameter: (len(springs),)} for the stiffness, beta,
    C0 of ``model`` (and g, g_star where conductivity, gn2_constant are given), and the springs'
    volumes V_e. ``properties`` are checked ones
    (:func:`check_properties`), each a float or a (m,) array in the net's spring numbering."""
    springs = np.asarray(springs, dtype=np.int64)
    name = stiffness_name(model)
    V, d = spring_volumes(net, properties, springs, where)
    l0 = net.rest_lengths[springs]
    E = _per_spring(properties["youngs_modulus"], springs)
    c = 0.5 * d * (d + 1) * E * V
    stiffness = c if name == "c" else c / l0
    alpha = _per_spring(properties.get("thermal_expansion", 0.0), springs)
    out = {
        name: stiffness,
        "beta": alpha * stiffness,
        "C0": _per_spring(properties["heat_capacity"], springs) * V,
    }
    for key, name in (("conductivity", "g"), ("gn2_constant", "g_star")):
        if key in properties:  # only then: a given g switches its flow on
            out[name] = 2.0 * d * _per_spring(properties[key], springs) * V / l0**2
    return out, V


def junction_factor(net, g: np.ndarray) -> float:
    """The factor f by which conductances g (m,) (0 where a spring takes no part) are scaled so
    that the net conducts a uniform gradient, averaged over its directions, at the rate the rule
    intends, with the junction nodes eliminated as the conduction graph eliminates them.

    Spring temperatures θ_e = G·x_e (x_e the spring's middle) exchange heat through junction i
    at the rate Σ_s g_s (θ_s − T_i)², T_i = Σ_s g_s θ_s / G_i the junction's temperature,
    G_i = Σ_s g_s. Averaged over the directions of G in the net's dimension d this is
    (A_i − |b_i|²/(d G_i)) |G|², with d_s the spring from node i, A_i = Σ_s g_s |d_s|²/(4d) and
    b_i = Σ_s g_s d_s / 2; the rule's g makes Σ_i A_i = k V. A star of springs not balanced
    around its node (at surfaces above all) loses |b_i|²/(d G_i), so
    f = Σ A_i / Σ (A_i − |b_i|²/(d G_i)) ≥ 1; it tends to 1 as a mesh is refined.
    g: (m,) conductances, 0 for springs that take no part.
    """
    g = np.asarray(g, dtype=np.float64)
    x, e = net.positions, net.edges
    d = x[e[:, 1]] - x[e[:, 0]]
    l2 = np.einsum("ij,ij->i", d, d)
    dim = net_dimension(net)
    n = net.n_nodes
    b = np.zeros((n, 3))
    G = np.zeros(n)
    np.add.at(b, e[:, 0], 0.5 * g[:, None] * d)
    np.add.at(b, e[:, 1], -0.5 * g[:, None] * d)
    np.add.at(G, e[:, 0], g)
    np.add.at(G, e[:, 1], g)
    A = float(np.sum(g * l2)) * 2.0 / (4.0 * dim)
    has = G > 0
    loss = float(np.sum(np.einsum("ij,ij->i", b[has], b[has]) / (dim * G[has])))
    if not A > 0:
        return 1.0
    return A / (A - loss)


def lumped_masses(net, density: np.ndarray, volume: np.ndarray) -> np.ndarray:
    """(n,) node masses: each spring's ρ V shared equally by its two ends (for tetrahedra,
    triangles, lines and hexahedra the same as sharing each cell's mass among its vertices).
    density, volume: (m,), NaN for springs outside continuum regions (they add nothing)."""
    mass = np.where(np.isfinite(density) & np.isfinite(volume), density * volume, 0.0)
    out = np.zeros(net.n_nodes)
    np.add.at(out, net.edges[:, 0], 0.5 * mass)
    np.add.at(out, net.edges[:, 1], 0.5 * mass)
    return out


def with_masses(net, masses: np.ndarray):
    """``net`` with node masses from the continuum where it gives any (> 0); other nodes keep theirs."""
    merged = np.where(masses > 0, masses, net.masses)
    return dataclasses.replace(net, masses=merged)


def apply_continuum(net, model, parameters: Mapping | None):
    """The API's path: ``parameters`` with continuum properties (scalars or (m,) arrays) turned
    into spring parameters for every spring, and the net with masses lumped from ρ.
    Returns (net, parameters, ContinuumMap or None); parameters without continuum keys pass."""
    parameters = dict(parameters or {})
    if not is_continuum(parameters):
        return net, parameters, None
    where = "parameters"
    derived = [k for k in derived_parameters(model) if k in parameters]
    if derived:
        raise InputError(f"{where}: give either continuum properties ({', '.join(k for k in parameters if k in CONTINUUM_KEYS)}) "
                         f"or spring parameters ({', '.join(derived)}), not both: the rule computes "
                         f"{', '.join(derived_parameters(model))} from the continuum")
    properties = check_properties({k: parameters.pop(k) for k in list(parameters) if k in CONTINUUM_KEYS},
                                  where, net.n_springs)
    net, continuum = apply_regions(net, model, parameters, [(where, np.arange(net.n_springs), properties)], where)
    return net, parameters, continuum


def apply_regions(net, model, values: dict, regions, rigid_where: str = "materials"):
    """The rule applied to material regions in order, the one place it is applied (the API's
    ``parameters`` are one region of every spring, a scene's ``[materials.*]`` tables one region
    each, later regions winning). regions: (where, springs, params) with params a region's
    spring parameters, or its continuum properties (scalars or (m,) arrays). Sets ``values``
    (name -> (m,)) in place: spring parameters as given, and where continuum properties are
    given the model's stiffness, beta, C0 (and g, g_star where conductivity, gn2_constant are),
    the conductances times the junction factor of the continuum springs. Returns the net with
    masses lumped from ρ and a :class:`ContinuumMap` — or (net, None) when no region gives
    continuum properties. A net that is then a mechanism is an error at ``rigid_where``."""
    if not any(region_properties(params) for _, _, params in regions):
        return net, None
    m = net.n_springs
    derived_names = derived_parameters(model)
    volume = np.full(m, np.nan)  # V_e of the springs whose parameters come from a continuum
    conducting = np.zeros(m, dtype=bool)  # springs whose g, g_star come from a continuum
    properties: dict = {}
    for where, springs, params in regions:
        given = region_properties(params)
        if not given:  # a spring-parameter region: applied in its place, so that region order holds
            for k, v in params.items():
                if k != "model":
                    values.setdefault(k, np.zeros(m))[springs] = v
            if any(k in derived_names[:3] for k in params):
                volume[springs] = np.nan
            if any(k in ("g", "g_star") for k in params):
                conducting[springs] = False
            continue
        derived, V = spring_parameters(net, model, given, springs, where)
        for k, v in derived.items():
            values.setdefault(k, np.zeros(m))[springs] = v
        volume[springs] = V
        conducting[springs] = "g" in derived or "g_star" in derived
        for k, v in given.items():
            properties.setdefault(k, np.full(m, np.nan))[springs] = v
    factor = correct_conductances(net, values, np.flatnonzero(conducting))
    for k, v in properties.items():
        v[np.isnan(volume)] = np.nan
    net = with_masses(net, lumped_masses(net, properties["density"], volume))
    require_rigid(net, rigid_where)
    return net, ContinuumMap(volume, net_dimension(net), properties, factor)


def _per_spring(value, springs: np.ndarray) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    return np.full(len(springs), float(arr)) if arr.ndim == 0 else arr[springs]


def region_problem(model, params: Mapping) -> tuple[str, str] | None:
    """The first problem of a scene's material region that gives continuum properties, as (key,
    message), or None: spring parameters beside them, a property out of range, a missing one."""
    given = [k for k in params if k in CONTINUUM_KEYS]
    if not given:
        return None
    try:
        name = stiffness_name(model)
    except InputError as exc:
        return given[0], str(exc)
    derived = [k for k in (name,) + DERIVED if k in params]
    if derived:
        return derived[0], (f"a region gives either continuum properties ({', '.join(given)}) or spring parameters "
                            f"({', '.join(derived)}), not both: the continuum rule computes "
                            f"{', '.join((name,) + DERIVED)} (docs/continuum.md)")
    for key in given:
        try:
            check_value(key, params[key], "")
        except InputError as exc:
            return key, str(exc).removeprefix(": ")
    missing = [k for k in REQUIRED if k not in params]
    if missing:
        return missing[0], (f"required: a continuum material gives {', '.join(REQUIRED)} "
                            f"({CONTINUUM_KEYS[missing[0]]} is missing)")
    return None


def region_properties(params: Mapping) -> dict:
    """The continuum properties of a scene's material region (none: not a continuum region)."""
    return {k: v for k, v in params.items() if k in CONTINUUM_KEYS}
