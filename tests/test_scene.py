"""Scene files: the schema, overrides, building the same objects as the Python API, effects that
are off cost nothing (no thermal arrays, no gravity term), and the error catalogue."""

import glob
import os
import re

import numpy as np
import pytest

import thermonet as tn
from thermonet.errors import InputError
from thermonet.scenes import DEFAULT_SCENE, SceneError, all_key_paths, load_scene, parse_override, scene_from_text

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BAD = sorted(glob.glob(os.path.join(ROOT, "tests", "scenes_bad", "*.toml")))
EXAMPLES = sorted(glob.glob(os.path.join(ROOT, "scenes", "*.toml")))

CHAIN = """
[net]
generator = "chain"
[materials.all]
c = 100.0
beta = 0.2
C0 = 5.0
theta0 = 300.0
[initial.temperature]
uniform = 500.0
[initial.velocity]
uniform = [1.0, 2.0, 0.5]
[integrator]
h = 0.01
steps = 20
"""


@pytest.mark.parametrize("path", EXAMPLES, ids=os.path.basename)
def test_every_example_scene_builds(path):
    built = load_scene(path).build()
    assert built.net.n_springs == built.simulation.net.n_springs > 0
    assert built.material_id.shape == (built.net.n_springs,)


def test_default_scene_is_a_3d_thermal_mesh_with_a_hot_region():
    scene = load_scene()
    assert os.path.samefile(scene.file, DEFAULT_SCENE)
    built = scene.build()
    sim = built.simulation
    assert scene.mesh_path().endswith(os.path.join("thermonet", "data", "truss_block.msh"))
    assert np.ptp(built.net.positions, axis=0).min() > 0  # really 3D
    theta = sim.temperatures()
    hot = built.net.spring_groups["hot"]
    assert theta[hot].min() > 2 * np.delete(theta, hot).max()
    assert built.net.anchored.sum() == len(built.net.node_groups["clamp"])
    assert set(np.unique(built.material_id)) == {0, 1}


def test_chain_scene_is_the_papers_chain_bit_for_bit():
    sim = load_scene(os.path.join(ROOT, "scenes", "chain.toml"), ["integrator.steps=200"]).build().simulation
    ref = tn.chain_simulation("co2", h=0.01)
    sim.run(steps=200, diagnostics_every=50)
    ref.run(steps=200, diagnostics_every=50)
    assert sim.diagnostics.energy[0] == pytest.approx(7983.333333333333, abs=1e-9)
    np.testing.assert_array_equal(sim.state.positions, ref.state.positions)
    np.testing.assert_array_equal(sim.temperatures(), ref.temperatures())


def test_triangle_scene_matches_the_papers_triangle():
    built = load_scene(os.path.join(ROOT, "scenes", "triangle.toml")).build()
    sim, net = built.simulation, built.net
    ref = tn.triangle_simulation("co2", h=1e-3)
    theta = sim.temperatures()
    spring2 = net.spring_groups["spring2"]
    assert theta[spring2] == pytest.approx([1000.0]) and sorted(theta) == pytest.approx([500.0, 500.0, 1000.0])
    sim.run(steps=300, diagnostics_every=100)
    ref.run(steps=300, diagnostics_every=100)
    assert sim.diagnostics.energy == pytest.approx(ref.diagnostics.energy, rel=1e-12)
    assert sim.diagnostics.py[-1] == pytest.approx(5.0, abs=1e-12)


def test_set_overrides_are_toml_typed_and_replace_the_end_condition():
    assert parse_override("integrator.h=1e-4") == (("integrator", "h"), 1e-4)
    assert parse_override("effects.gravity=[0, 0, -1]") == (("effects", "gravity"), [0, 0, -1])
    assert parse_override("effects.thermal=false") == (("effects", "thermal"), False)
    assert parse_override("integrator.name=gtr-0") == (("integrator", "name"), "gtr-0")
    scene = scene_from_text(CHAIN, overrides=["integrator.t_end=0.5", "integrator.name=gtr-1"])
    assert scene.total_steps() == 50 and scene["integrator"]["name"] == "gtr-1"
    with pytest.raises(SceneError, match=r"^--set integrator\.hh: integrator\.hh: unknown key"):
        scene_from_text(CHAIN, overrides=["integrator.hh=1"])


def test_initial_motion_kinds():
    text = CHAIN.replace("uniform = [1.0, 2.0, 0.5]", "rotation = { axis = [0, 0, 2], omega = 3.0 }")
    sim = scene_from_text(text).build().simulation
    net = sim.net
    v = sim.velocities()
    expected = np.cross([0.0, 0.0, 3.0], net.positions)
    expected[net.anchored] = 0.0
    np.testing.assert_allclose(v, expected, atol=1e-14)
    text = CHAIN.replace("uniform = [1.0, 2.0, 0.5]", "random = { amplitude = 0.5, seed = 4 }")
    a = scene_from_text(text).build().simulation.velocities()
    b = scene_from_text(text).build().simulation.velocities()
    np.testing.assert_array_equal(a, b)
    assert np.abs(a).max() <= 0.5 and np.abs(a[1:]).min() > 0 and not a[0].any()


def test_temperature_perturbation_is_seeded_and_bounded():
    text = CHAIN.replace("uniform = 500.0", "uniform = 500.0\nperturbation = 10.0\nseed = 2")
    t1 = scene_from_text(text).build().simulation.temperatures()
    t2 = scene_from_text(text).build().simulation.temperatures()
    np.testing.assert_array_equal(t1, t2)
    assert np.all(np.abs(t1 - 500.0) <= 10.0) and np.ptp(t1) > 0


def test_lumped_masses_from_density_and_regions():
    base = os.path.join(ROOT, "scenes", "default.toml")
    built = load_scene(base, ["initial.mass={density = 2.0, regions = {tip = 5.0}}"]).build()
    net = built.net
    tip = net.node_groups["tip"]
    assert np.all(net.masses[tip] == 5.0)
    others = np.setdiff1d(np.arange(net.n_nodes), tip)
    # density 2 over the 4×1×1 block: the lumped masses of all nodes sum to 8
    lumped = tn.read_mesh(load_scene(base).mesh_path(), density=2.0).masses
    assert lumped.sum() == pytest.approx(8.0, rel=1e-12)
    np.testing.assert_array_equal(net.masses[others], lumped[others])


# ----------------------------------------------------------------------------------------------
# effects: what is off is not computed


def _velocity_verlet(net, c, h, steps, v0):
    """Plain NumPy velocity Verlet for hencky springs at their reference temperature."""
    x = net.positions.copy()
    m = net.masses[:, None]
    free = ~net.anchored[:, None]
    p = v0 * m

    def force(x):
        d = x[net.edges[:, 1]] - x[net.edges[:, 0]]
        l = np.linalg.norm(d, axis=1)
        s = (c * np.log(l / net.rest_lengths) / l / l)[:, None] * d
        f = np.zeros_like(x)
        np.add.at(f, net.edges[:, 0], s)
        np.add.at(f, net.edges[:, 1], -s)
        return f * free

    f = force(x)
    for _ in range(steps):
        p = p + 0.5 * h * f
        x = x + h * p / m * free
        f = force(x)
        p = p + 0.5 * h * f
    return x, p


def test_thermal_off_is_pure_mechanics_with_no_thermal_arrays(tmp_path):
    mech_text = CHAIN.replace("[initial.temperature]\nuniform = 500.0\n", "") + "[effects]\nthermal = false\n"
    mech = scene_from_text(mech_text).build().simulation
    assert mech.system.thermal is False
    assert mech._state.entropy is None and mech._state.thermal_displacement is None
    assert mech.state.entropy is None and mech.state.thermal_displacement is None
    # decoupled thermal run (beta = 0): the same mechanics through the thermal kernel
    decoupled = scene_from_text(CHAIN.replace("beta = 0.2", "beta = 0.0")).build().simulation
    mech.run(steps=500, diagnostics_every=100)
    decoupled.run(steps=500, diagnostics_every=100)
    np.testing.assert_array_equal(mech.state.positions, decoupled.state.positions)
    np.testing.assert_array_equal(mech.state.momenta, decoupled.state.momenta)
    assert "entropy" not in mech.diagnostics.columns and "theta_min" not in mech.diagnostics.columns
    # and an independent NumPy velocity Verlet of the same springs
    net = mech.net
    x, p = _velocity_verlet(net, 100.0, 0.01, 500, np.where(net.anchored[:, None], 0.0, [1.0, 2.0, 0.5]))
    np.testing.assert_allclose(mech.state.positions, x, rtol=0, atol=1e-10)
    np.testing.assert_allclose(mech.state.momenta, p, rtol=0, atol=1e-9)


def test_gravity_is_off_unless_asked_and_energy_includes_its_potential():
    sim = scene_from_text(CHAIN).build().simulation
    assert sim.system.gravity is None
    sim.run(steps=20, diagnostics_every=10)
    assert np.all(sim.diagnostics.potential == 0.0)
    g = scene_from_text(CHAIN, ["effects.gravity=[0, 0, -9.81]", "integrator.steps=2000"]).build().simulation
    assert g.system.gravity.tolist() == [0.0, 0.0, -9.81]
    g.run(steps=2000, diagnostics_every=10)
    assert np.ptp(g.diagnostics.potential) > 1.0  # the chain really falls and swings
    assert np.ptp(g.diagnostics.energy) < 1e-3 * abs(g.diagnostics.energy[0])


# ----------------------------------------------------------------------------------------------
# the error catalogue


def _expected(path):
    with open(path, encoding="utf-8") as f:
        text = f.read()
    message = re.search(r"^# error: (.*)$", text, re.M).group(1)
    line = re.search(r"^# line: (\d+)$", text, re.M)
    return message, int(line.group(1)) if line else None


@pytest.mark.parametrize("path", BAD, ids=os.path.basename)
def test_bad_scene_gives_its_documented_message(path):
    message, line = _expected(path)
    with pytest.raises(InputError) as info:
        load_scene(path).build()
    text = str(info.value)
    assert message in text
    assert "\n" not in text
    assert text.startswith(path + (f":{line}:" if line else ":"))


def test_error_catalogue_is_documented():
    docs = open(os.path.join(ROOT, "docs", "scenes.md")).read()
    for path in BAD:
        message, _ = _expected(path)
        assert os.path.basename(path) in docs and message in docs, os.path.basename(path)


def test_every_schema_key_is_in_the_reference():
    docs = open(os.path.join(ROOT, "docs", "scenes.md")).read()
    missing = [k for k in all_key_paths() if f"`{k}`" not in docs and f"`[{k}]`" not in docs]
    assert not missing


def test_the_annotated_scene_in_the_docs_is_valid():
    docs = open(os.path.join(ROOT, "docs", "scenes.md")).read()
    text = docs.split("```toml")[1].split("```")[0]
    built = scene_from_text(text, file="docs/scenes.md", base_dir=os.path.join(ROOT, "scenes")).build()
    assert built.net.n_springs == 2492 and built.simulation.system.gravity is not None
