"""The thermal-shock scene and example (examples/thermal_shock.py): the run's spring temperatures
against the exact solution of the net's linear heat equations (β = 0), agreeing to the
integrator's O(h²) error with the order measured; the example's heat operator against the
star–mesh elimination written out; ``thermonet info`` on a scene with heat flow."""

import importlib.util
import math
import pathlib

import numpy as np
import pytest

import thermonet as tn
from thermonet.cli.main import main as thermonet

ROOT = pathlib.Path(__file__).resolve().parent.parent


def load_example():
    spec = importlib.util.spec_from_file_location("example_thermal_shock", ROOT / "examples" / "thermal_shock.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def star_mesh_operator(net, g, capacity, bath_nodes):
    """C⁻¹ K, K the springs' block of the conduction network after eliminating every junction
    (a Schur complement): spring middles joined to both their end nodes through g_e; bath nodes
    held, every other node eliminated (docs/theory.md §5.1, §5.7). Dense; for small nets."""
    m, n = net.n_springs, net.n_nodes
    B = np.zeros((m, n))
    B[np.arange(m), net.edges[:, 0]] += g
    B[np.arange(m), net.edges[:, 1]] += g
    junction = np.ones(n, dtype=bool)
    junction[bath_nodes] = False
    BJ = B[:, junction]
    K = np.diag(B.sum(axis=1)) - BJ @ np.diag(1.0 / BJ.sum(axis=0)) @ BJ.T
    return K / capacity[:, None]


def test_the_examples_operator_is_the_star_mesh_elimination():
    example = load_example()
    net = tn.read_mesh(ROOT / "meshes" / "thermal_bar.msh", cell_types=["tetra"])
    rng = np.random.default_rng(3)
    g = rng.uniform(0.5, 2.0, net.n_springs)
    capacity = rng.uniform(1.0, 3.0, net.n_springs)
    bath = net.node_groups["hot_end"]
    M = example.heat_operator(net, g, capacity, bath).toarray()
    reference = star_mesh_operator(net, g, capacity, bath)
    assert np.abs(M - reference).max() <= 1e-12 * np.abs(reference).max()


def test_thermal_shock_matches_the_lattice_solution_at_second_order(tmp_path):
    example = load_example()
    numbers = example.main(["--smoke", "--out", str(tmp_path)])
    err_h, err_h2 = np.array(numbers["error_h"]), np.array(numbers["error_h2"])
    # relative to the 600 K shock: the splitting error only (no continuum error on the lattice)
    assert (err_h < 1e-4).all() and (err_h2 < 3e-5).all()
    assert (err_h2 > 1e-7).all()                       # an error to measure, not round-off
    slopes = np.log2(err_h / err_h2)
    assert np.all(np.abs(slopes - 2.0) < 0.05), slopes
    # conduction "auto" at the scene's step: within 1e-3 of the shock
    assert numbers["k_auto"] >= 1 and (np.array(numbers["error_auto"]) <= 1e-3).all(), numbers["error_auto"]
    # the heat has entered: the hottest springs are well above the initial 300 K
    assert numbers["exact"][-1].max() > 800.0
    # beta = 0.002 changes temperatures by the thermo-elastic work, by far less than a kelvin
    assert 0.0 < max(numbers["coupling"]) < 0.05
    assert (tmp_path / "thermal_shock_profiles.png").stat().st_size > 10_000


def test_info_lists_conduction_baths_and_the_conduction_cycle(capsys):
    assert thermonet(["info", str(ROOT / "scenes" / "thermal_shock.toml"),
                      "--set", "sources.s.group=bar", "--set", "sources.s.power=0.5"]) == 0
    text = capsys.readouterr().out
    assert "heat flow: conduction on (g 4), thermal waves off" in text
    net = tn.read_mesh(ROOT / "meshes" / "thermal_bar.msh", cell_types=["tetra"])
    # every junction with two or more springs is swept: every node but the bath's
    bath = np.zeros(net.n_nodes, dtype=bool)
    bath[net.node_groups["hot_end"]] = True
    degree = np.bincount(net.edges.ravel(), minlength=net.n_nodes)
    assert f"conduction swept over {int(np.sum(~bath & (degree >= 2)))} junctions in " in text
    # the scene's outputs every 10 and 50 steps; λ = 8 (g = 4, C0 = 1: 2 g (1 − g/G) + g at a bath end)
    assert "conduction every " in text and "λ k h" in text
    ends = int(np.isin(net.edges, net.node_groups["hot_end"]).sum())
    assert f"bath hot: node group 'hot_end' (12 nodes, {ends} spring ends), θ_b(t) = 900" in text
    assert "source s: spring group 'bar' (673 springs), P(t) = 0.5 per spring" in text
    assert "of it for heat flow" in text and "co2+conduction" in text


def test_info_says_heat_flow_is_off(capsys):
    assert thermonet(["info", str(ROOT / "scenes" / "chain.toml")]) == 0
    assert "heat flow: off" in capsys.readouterr().out


def test_a_run_says_which_conduction_cycle_it_took_and_why(tmp_path, capsys):
    import json

    out = tmp_path / "run"
    # 100 steps, outputs every 10 (diagnostics, checkpoints) and 50 (frames) steps; λ h = 0.08:
    # "auto" conducts every 10 steps, each boundary swept 3 times (as every 10/3 steps for the
    # error), which its cost model finds cheaper than every 2 steps with one sweep
    assert thermonet(["run", str(ROOT / "scenes" / "thermal_shock.toml"), "--out", str(out),
                      "--set", "integrator.t_end=1.0"]) == 0
    printed = capsys.readouterr().out
    assert ("conduction every 10 steps, 3 sub-sweeps (auto: fastest conduction rate λ = 8/time, 3 sub-sweeps per "
            "cycle boundary: λ k h / 3 = 0.267 ≤ 0.3, λ k h = 0.8 ≤ 1; about 0.29 adiabatic steps of conduction per "
            "step against 0.65 with k = 2 and one sweep)") in printed
    summary = json.loads((out / "summary.json").read_text())
    cycle = summary["conduction_every"]
    assert cycle["k"] == 10 and cycle["sweeps"] == 3 and "λ k h / 3 = 0.267" in cycle["why"]
    d = np.genfromtxt(out / "diagnostics.csv", delimiter=",", names=True)
    assert np.all(np.diff(d["entropy_produced"]) >= 0.0) and d["heat_hot"][-1] > 0.0


@pytest.mark.parametrize("value, message", [
    ("3", "effects.conduction_every: 3 does not divide the output cadences"),
    ("0", 'effects.conduction_every: must be "auto" or a whole number of steps >= 1, got'),
    ('"fast"', 'effects.conduction_every: must be "auto" or a whole number of steps >= 1, got a string \'fast\''),
])
def test_a_conduction_cycle_the_outputs_cannot_follow_is_refused_naming_the_key(tmp_path, capsys, value, message):
    scene = tmp_path / "shock.toml"
    text = (ROOT / "scenes" / "thermal_shock.toml").read_text().replace('mesh = "../meshes/', f'mesh = "{ROOT}/meshes/')
    scene.write_text(text.replace("conduction = true", f"conduction = true\nconduction_every = {value}"))
    assert thermonet(["run", str(scene), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert message in err and "shock.toml:" in err  # file:line: key
    assert not (tmp_path / "run").exists()
