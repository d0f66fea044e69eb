"""``thermonet info MESH|SCENE``: what a mesh or scene holds (nodes, springs, cell types,
groups, materials), the memory a run of it needs, and the explicit integrators' stable step."""

from __future__ import annotations

import os

import numpy as np

from ..blowup import UNLIMITED
from ..builders import from_meshio, read_meshio
from ..errors import InputError
from ..heat.exchange import BATH
from ..heat.graph import pairs_per_spring
from ..heat.multirate import ConductionCycle, choose_cycle
from ..materials.homogenize import boundary_nodes, box_boundary
from ..materials.report import describe, measure
from ..materials.rigidity import floppy_modes
from ..scenes import load_scene
from ..simulation import Simulation
from ..stability import stability_interval, stable_step

HELP = "describe a mesh or a scene: nodes, springs, cell types, groups, materials, memory, stable step"


def add_args(p) -> None:
    p.add_argument("target", metavar="MESH|SCENE", help="a mesh file (.msh, .vtu, ...) or a scene (.toml)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                   help="override a scene key (scenes only)")


def engine_bytes(n_nodes: int, n_springs: int, n_parameters: int, thermal: bool) -> int:
    """Bytes the engine holds for a run: per node positions (two buffers), momenta, masses,
    inverse masses, anchored flag, incidence pointer; per spring edges, rest length, parameters,
    force scratch, two incidence entries, and Φ, η when thermal."""
    per_node = 3 * 8 * 3 + 8 + 8 + 1 + 8
    per_spring = 8 + 8 + 8 * n_parameters + 8 + 2 * 8 + (16 if thermal else 0)
    return n_nodes * per_node + n_springs * per_spring


def _mb(b: float) -> str:
    return f"{b / 2**20:.3g} MiB"


def handle(args) -> int:
    target = args.target
    if os.path.isdir(target):
        raise InputError(f"{target}: is a folder; give a mesh file or a scene (.toml)")
    if not os.path.exists(target):
        raise InputError(f"{target}: no such file")
    lines = describe_scene(target, args.overrides) if target.endswith(".toml") else describe_mesh(target)
    print("\n".join(lines))
    return 0


def describe_mesh(path: str) -> list[str]:
    mesh = read_meshio(path)
    net = from_meshio(mesh, source=path)
    cells = {}
    for block in mesh.cells:
        cells[block.type] = cells.get(block.type, 0) + len(block.data)
    out = [f"{path}: mesh with {len(mesh.points)} points",
           "  cells: " + ", ".join(f"{n} {t}" for t, n in cells.items()),
           f"  spring net: {net.n_nodes} nodes, {net.n_springs} springs "
           f"(lengths {net.lengths().min():.4g} .. {net.lengths().max():.4g})"]
    if net.pieces_note():
        out.append(f"  pieces: {net.pieces_note()}")
    out += _groups(net)
    if mesh.point_data:
        out.append("  point data: " + ", ".join(f"{k} {np.shape(v)}" for k, v in mesh.point_data.items()))
    out.append(f"  memory of a run: about {_mb(engine_bytes(net.n_nodes, net.n_springs, 4, True))} "
               f"(hencky, thermal; {_mb(engine_bytes(net.n_nodes, net.n_springs, 4, False))} purely mechanical)")
    sim = Simulation(net, model="hencky", integrator="co2", h=1.0)
    out.append(_stable_step(sim, "hencky default parameters, unit masses, at rest"))
    return out


def describe_scene(path: str, overrides) -> list[str]:
    scene = load_scene(path, overrides)
    built = scene.build()
    net, sim = built.net, built.simulation
    d = scene.data
    source = scene.mesh_path() or f"generator {d['net']['generator']}"
    total = scene.total_steps()
    out = [f"{path}: scene {scene.name!r} (hash {scene.hash[:12]})",
           f"  net: {net.n_nodes} nodes ({int(net.anchored.sum())} anchored), {net.n_springs} springs, "
           f"{_mass(net)}, from {source}"]
    if net.pieces_note():
        out.append(f"  pieces: {net.pieces_note()}")
    if scene.mesh_path():
        mesh = built.mesh if built.mesh is not None else read_meshio(scene.mesh_path())
        cells = {}
        for block in mesh.cells:
            cells[block.type] = cells.get(block.type, 0) + len(block.data)
        out.append("  cells: " + ", ".join(f"{n} {t}" for t, n in cells.items()))
    out += _groups(net)
    out.append(f"  model {sim.model.name}; materials (id: region, springs, parameters):")
    for i, region in enumerate(built.material_names):
        count = int((built.material_id == i).sum())
        params = ", ".join(f"{k}={v:g}" for k, v in d["materials"][region].items() if k != "model")
        out.append(f"    {i}: {region}, {count} springs, {params or 'model defaults'}")
    if (built.material_id < 0).any():
        out.append(f"    -1: (no region), {int((built.material_id < 0).sum())} springs, model defaults")
    if built.continuum is not None:
        out += _continuum(built)
    e = d["effects"]
    out.append(f"  effects: thermal {'on' if e['thermal'] else 'off'}, gravity {e['gravity'] or 'off'}, "
               f"{int(net.anchored.sum())} anchored nodes")
    cadences = [scene.cadence(key, total) for key in ("frames_every", "diagnostics_every", "checkpoint_every")]
    out += _heat_flow(sim, {**(d.get('baths') or {}), **(d.get('sources') or {})}, cadences + [total])
    if sim.loads is not None:  # loads
        out.append(f"  loads ({len(sim.loads.set)}):")
        out += [f"    {name}: {sim.loads.set.describe(i)}" for i, name in enumerate(sim.loads.set.names)]
    out.append(f"  integrator {sim.integrator.name} (order {sim.integrator.order}), h = {sim.h:g}, {total} steps "
               f"to t = {total * sim.h:g}")
    out.append(f"  output every {scene.cadence('frames_every', total)} steps (frames), "
               f"{scene.cadence('diagnostics_every', total)} (diagnostics), "
               f"{scene.cadence('checkpoint_every', total)} (checkpoints); fields {', '.join(scene.output_fields())}")
    memory = engine_bytes(net.n_nodes, net.n_springs, len(sim.model.parameters), e['thermal'])
    heat = sim.system.heat
    extra = heat_bytes(net.n_springs, heat.graph.n_pairs, net.n_nodes) if heat is not None else 0
    out.append(f"  memory of the run: about {_mb(memory + extra)}"
               + (f" ({_mb(extra)} of it for heat flow)" if extra else ""))
    out.append(_stable_step(sim, "initial state"))
    return out


def _mass(net) -> str:
    """The net's mass, saying which nodes it counts: the free nodes' mass (what moves), and the
    whole mass where anchored nodes carry some."""
    free = float(net.masses[~net.anchored].sum())
    if not net.anchored.any():
        return f"total mass {free:.6g}"
    return (f"mass {free:.6g} on the {int((~net.anchored).sum())} free nodes "
            f"({float(net.masses.sum()):.6g} with the anchored ones)")


def heat_bytes(n_springs: int, n_pairs: int, n_nodes: int = 0) -> int:
    """Bytes heat flow adds to a run: per thermal-wave pair its two springs, κ and k*; per
    spring g, g*, C, 1/C, the sweep's two factors, the entropy production log and the sweeps'
    temperatures, lengths and forces; per node its place in the sweep order."""
    return n_pairs * (8 + 8 + 16) + n_springs * 11 * 8 + n_nodes * 16


def _heat_flow(sim, specs: dict, cadences=()) -> list[str]:
    """The heat-flow lines: conduction and thermal waves, the pair graph, baths, sources (specs:
    the scene's bath and source tables by name)."""
    heat = sim.system.heat
    if heat is None:
        return ["  heat flow: off (adiabatic springs; effects.conduction, effects.thermal_waves)"]
    m = sim.net.n_springs
    parts = []
    for on, name, values in ((heat.conduction, "conduction", heat.conductance),
                             (heat.waves, "thermal waves", heat.wave_conductance)):
        key = "g" if name == "conduction" else "g_star"
        parts.append(f"{name} {'on' if on else 'off'}" + (f" ({key} {_span(values)})" if on else ""))
    g = heat.graph
    out = [f"  heat flow: {', '.join(parts)}"]
    if heat.conduction:
        order = heat.star_order(sim.backend)
        out.append(f"    conduction swept over {len(order.node)} junctions in {order.n_blocks} blocks, "
                   f"{order.n_colours} colours ({sim.backend}); {conduction_line(sim, cadences)}")
    if heat.waves:
        out.append(f"    thermal waves: {g.n_pairs} spring pairs ({pairs_per_spring(g, m):.3g} per spring, "
                   f"{g.n_colours} colours)")
    for i, name in enumerate(heat.names):
        mine = heat.entry_fn == i
        if i < heat.n_baths:
            group = specs.get(name, {}).get("group", "?")
            nodes = int(np.sum(heat.bath_nodes == i))
            ends = int(np.sum(mine & (heat.entry_kind == BATH)))
            out.append(f"    bath {name}: node group {group!r} ({nodes} nodes, {ends} spring ends), "
                       f"θ_b(t) = {heat.functions[i].describe()}")
        else:
            group = specs.get(name, {}).get("group", "?")
            out.append(f"    source {name}: spring group {group!r} ({int(np.sum(mine))} springs), P(t) = {heat.functions[i].describe()} "
                       "per spring")
    if not heat.names:
        out.append("    no baths or sources (an isolated net: heat only moves inside)")
    return out


def conduction_line(sim, cadences=()) -> str:
    """Which conduction cycle a run with output ``cadences`` (steps) takes, and why."""
    try:
        k, sweeps, why = choose_cycle(sim.conduction_every, sim.system.heat.fastest_rate(), sim.h, cadences,
                                      sweeps=sim.conduction_sweeps)
    except InputError as exc:  # (run refuses it the same way)
        return f"conduction_every: {exc}"
    return ConductionCycle(k, why, sweeps).describe()


def _span(values) -> str:
    lo, hi = float(np.min(values)), float(np.max(values))
    return f"{lo:g}" if lo == hi else f"{lo:g} .. {hi:g}"


def _continuum(built) -> list[str]:
    """The effective properties the net has, measured on it (docs/continuum.md)."""
    net, cmap = built.net, built.continuum
    boundary = boundary_nodes(built.mesh, net) if built.mesh is not None else box_boundary(net.positions)
    eff = measure(net, built.simulation.model, built.parameters, cmap.volume, boundary, cmap.dimension)
    inside = np.isfinite(cmap.volume)
    V = cmap.volume[inside]
    given = {k: float(np.sum(v[inside] * V) / V.sum()) for k, v in cmap.properties.items()}
    rigid = floppy_modes(net)
    out = describe(eff, given, cmap.dimension, cmap.junction_factor)
    out.append(f"    rigid: no zero-frequency modes beyond the {rigid.rigid} rigid-body ones ({rigid.method})")
    return out


def _groups(net) -> list[str]:
    out = []
    if net.node_groups:
        out.append("  node groups: " + ", ".join(f"{k} ({len(v)})" for k, v in sorted(net.node_groups.items())))
    if net.spring_groups:
        out.append("  spring groups: " + ", ".join(f"{k} ({len(v)})" for k, v in sorted(net.spring_groups.items())))
    if not out:
        out.append("  groups: none")
    return out


def _stable_step(sim, where: str) -> str:
    import math

    if getattr(sim.integrator, "unconditionally_stable", False):
        return (f"  stable step: none, {sim.integrator.name} has no stability limit (energy exact at any step; "
                f"steps far above the explicit limit lose accuracy in the fast modes, not stability)")
    if not math.isfinite(stability_interval(sim.integrator)):
        return f"  stable step: not estimated for the implicit integrator {sim.integrator.name}"
    s = stable_step(sim)
    text = (f"  stable step of {s['integrator']}: h_max ≈ {s['h_max']:.4g} (ω_max {s['omega_max']:.4g}, "
            f"{s['method']}; {where})")
    if sim.h > s["h_max"] and sim.h != 1.0:
        text += (f"\n  warning: h = {sim.h:g} exceeds the estimated limit; the run will blow up: use h ≤ "
                 f"{0.9 * s['h_max']:.3g}, or the integrator {UNLIMITED}, which has no stability limit")
    return text
