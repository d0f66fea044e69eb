"""Continuum materials on meshes (docs/continuum.md, docs/theory.md §8): the isotropic rule checked by
refinement on gmsh bars (free expansion, wave speed, Fourier decay, totals), the effective
properties measured on a net, the rigidity check, and bad input."""

from __future__ import annotations

import os

import meshio
import numpy as np
import pytest

from thermonet import Simulation
from thermonet.builders import from_meshio, lattice
from thermonet.errors import InputError
from thermonet.materials import checks
from thermonet.materials.homogenize import box_boundary, elastic_tensor
from thermonet.materials.rigidity import floppy_modes
from thermonet.scenes import scene_from_text
from thermonet.scenes.source import SceneError

gmsh = pytest.importorskip("gmsh")

SCENES = os.path.join(os.path.dirname(__file__), os.pardir, "scenes")


@pytest.fixture(scope="module")
def bars(tmp_path_factory):
    folder = str(tmp_path_factory.mktemp("bars"))
    return [checks.bar_net(size, folder) for size in checks.SIZES]


def _report(name, values, sizes=True):
    where = f" at mesh sizes {', '.join(f'{s:g}' for s in checks.SIZES)}" if sizes else ""
    print(f"\n{name}{where}: " + ", ".join(f"{v:.6g}" for v in values))


# ----------------------------------------------------------------------------------------------
# the three figures at three refinements


def test_a_free_block_heated_by_dtheta_expands_by_alpha_dtheta_in_every_direction(bars):
    found = [checks.free_expansion(net) for net in bars]
    _report("equilibrium residual of the block scaled by exp(α Δθ)", [f["residual"] for f in found])
    for f in found:
        _report("measured strain / α Δθ along x, y, z", f["strain"], sizes=False)
        assert f["residual"] < 1e-12
        np.testing.assert_allclose(f["strain"], 1.0, rtol=1e-12)


def test_total_mass_and_heat_capacity_are_rho_v_and_cv_v(bars):
    found = [checks.totals(net) for net in bars]
    _report("mass / ρV", [f["mass"] for f in found])
    _report("heat capacity / c_v V", [f["heat_capacity"] for f in found])
    for f in found:
        assert abs(f["mass"] - 1.0) < 1e-12 and abs(f["heat_capacity"] - 1.0) < 1e-12


def test_the_longitudinal_wave_speed_converges_to_sqrt_e_over_rho(bars):
    speed = [checks.wave_speed(net) for net in bars]
    _report("longitudinal wave speed / √(E/ρ)", speed)
    assert abs(speed[-1] - 1.0) < 0.05
    assert abs(speed[2] - speed[1]) < abs(speed[1] - speed[0])  # successive refinements agree more


def test_a_fourier_temperature_mode_decays_at_k_q2_over_cv(bars):
    rate = [checks.fourier_decay(net) for net in bars]
    _report("decay rate of cos(π x/L) / (k q²/c_v)", rate)
    assert abs(rate[-1] - 1.0) < 0.03
    assert abs(rate[-1] - 1.0) < min(abs(rate[0] - 1.0), abs(rate[1] - 1.0))


def test_the_junction_factor_makes_a_uniform_gradient_conduct_at_k_and_tends_to_one(bars):
    from thermonet.heat.graph import pair_graph
    from thermonet.layout import build_layout

    factors, rates = [], []
    for net in bars:
        sim = Simulation(net, parameters=checks.parameters(), integrator="co2", h=1e-3)
        g = sim.layout.springs_to_user(sim.system.heat.conductance)
        graph = pair_graph(build_layout(net, renumber=False), g[None, :])
        middle = 0.5 * (net.positions[net.edges[:, 0]] + net.positions[net.edges[:, 1]])
        diff = middle[graph.first] - middle[graph.second]
        trace = np.sum(graph.kappa[:, 0, None] * diff**2)  # Σ over unit gradients along x, y, z
        factors.append(sim.continuum.junction_factor)
        rates.append(trace / (3 * checks.MATERIAL["conductivity"] * sim.continuum.volume.sum()))
    _report("junction factor", factors)
    _report("direction-averaged conduction of a uniform gradient / k", rates)
    np.testing.assert_allclose(rates, 1.0, rtol=1e-12)
    assert factors[0] > factors[1] > factors[2] > 1.0


def test_the_rule_gives_a_central_force_net_poissons_ratio_one_quarter(bars):
    net = bars[1]
    sim = Simulation(net, parameters=checks.parameters(), integrator="co2", h=1e-3)
    k = sim.continuum.volume * 6 * checks.MATERIAL["youngs_modulus"] / net.rest_lengths**2
    affine = elastic_tensor(net.positions, net.edges, k, sim.continuum.volume.sum(), np.ones(net.n_nodes, bool), 3)
    relaxed = elastic_tensor(net.positions, net.edges, k, sim.continuum.volume.sum(), box_boundary(net.positions), 3)
    _report("mesh 0.0625: affine E/E, ν; relaxed E/E, ν", [affine.E / 2.0, affine.nu, relaxed.E / 2.0, relaxed.nu],
            sizes=False)
    # a central-force tensor has the Cauchy symmetry C12 = C44 (λ = μ: ν = 1/4 when isotropic)
    C = affine.C
    np.testing.assert_allclose([C[0, 1], C[0, 2], C[1, 2]], [C[5, 5], C[4, 4], C[3, 3]], rtol=1e-12)
    assert abs(affine.nu - 0.25) < 0.02 and abs(affine.E / 2.0 - 1.0) < 0.05
    assert relaxed.E <= affine.E * (1 + 1e-12)  # relaxing the interior only lowers the energy


# ----------------------------------------------------------------------------------------------
# 2D and 1D nets


def _square_triangles(n=4):
    x, y = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    pts = np.column_stack([x.ravel(), y.ravel()])
    idx = np.arange(len(pts)).reshape(n + 1, n + 1)
    tri = []
    for j in range(n):
        for i in range(n):
            a, b, c, d = idx[j, i], idx[j, i + 1], idx[j + 1, i + 1], idx[j + 1, i]
            tri += [[a, b, c], [a, c, d]] if (i + j) % 2 else [[a, b, d], [b, c, d]]
    return meshio.Mesh(pts, [("triangle", np.array(tri))])


def test_a_2d_net_uses_area_times_thickness_and_has_poissons_ratio_one_third():
    net = from_meshio(_square_triangles(), source="square")
    params = {"youngs_modulus": 3.0, "density": 2.0, "heat_capacity": 1.0, "thickness": 0.1, "theta0": 300.0}
    sim = Simulation(net, parameters=params, integrator="co2", h=1e-3)
    assert sim.continuum.dimension == 2
    np.testing.assert_allclose(sim.net.masses.sum(), 2.0 * 1.0 * 0.1, rtol=1e-12)
    k = 3 * 3.0 * sim.continuum.volume / net.rest_lengths**2
    el = elastic_tensor(net.positions, net.edges, k, sim.continuum.volume.sum(), np.ones(net.n_nodes, bool), 2)
    _report("2D affine E/E, ν (plane stress)", [el.E / 3.0, el.nu], sizes=False)
    assert abs(el.nu - 1 / 3) < 0.05
    with pytest.raises(InputError, match="thickness"):
        Simulation(net, parameters={k: v for k, v in params.items() if k != "thickness"}, h=1e-3)


def test_a_1d_net_gets_c_equal_e_a_l_and_g_equal_2_k_a_over_l():
    pts = np.column_stack([np.linspace(0, 2, 5), np.zeros(5), np.zeros(5)])
    mesh = meshio.Mesh(pts, [("line", np.column_stack([np.arange(4), np.arange(1, 5)]))])
    net = from_meshio(mesh, source="rod")
    params = {"youngs_modulus": 7.0, "density": 3.0, "heat_capacity": 2.0, "conductivity": 5.0, "area": 0.01,
              "thermal_expansion": 1e-3, "gn2_constant": 0.5, "theta0": 300.0}
    sim = Simulation(net, parameters=params, integrator="co2", h=1e-3)
    P = sim.layout.springs_to_user(sim.system.parameters.T).T
    l = 0.5
    np.testing.assert_allclose(P[0], 7.0 * 0.01 * l, rtol=1e-12)  # c = E A l
    np.testing.assert_allclose(P[1], 1e-3 * 7.0 * 0.01 * l, rtol=1e-12)  # beta = α c
    np.testing.assert_allclose(P[2], 2.0 * 0.01 * l, rtol=1e-12)  # C0 = c_v A l
    g = sim.layout.springs_to_user(sim.system.heat.conductance)
    np.testing.assert_allclose(g, 2 * 5.0 * 0.01 / l, rtol=1e-12)  # g = 2 k A / l
    g_star = sim.layout.springs_to_user(sim.system.heat.wave_conductance)
    np.testing.assert_allclose(g_star, 2 * 0.5 * 0.01 / l, rtol=1e-12)  # g* = 2 k* A / l
    np.testing.assert_allclose(sim.net.masses, 3.0 * 0.01 * l * np.array([0.5, 1, 1, 1, 0.5]), rtol=1e-12)


def test_the_quadratic_model_gets_the_same_spring_stiffness_and_expands_by_alpha_dtheta(bars):
    import dataclasses

    net, dtheta = bars[0], 40.0
    alpha = checks.MATERIAL["thermal_expansion"]
    params = {k: v for k, v in checks.parameters().items() if k != "conductivity"}
    hencky = Simulation(net, parameters=params, thermal=False, h=1e-3)
    P_h = hencky.layout.springs_to_user(hencky.system.parameters.T).T
    heated = dataclasses.replace(net, positions=net.positions * (1 + alpha * dtheta), rest_lengths=net.rest_lengths)
    quad = Simulation(heated, model="quadratic", parameters=params, temperatures=checks.THETA0 + dtheta, h=1e-3)
    P_q = quad.layout.springs_to_user(quad.system.parameters.T).T
    np.testing.assert_allclose(P_q[0], P_h[0] / net.rest_lengths, rtol=1e-12)  # E = c / l0
    np.testing.assert_allclose(P_q[1], alpha * P_q[0], rtol=1e-12)  # beta = α E
    scale = P_q[0] * alpha * dtheta
    assert np.max(np.abs(quad.tensions())) < 1e-12 * np.max(scale)  # l = l0 (1 + α Δθ): no stress


def test_a_curved_2d_net_is_refused():
    mesh = _square_triangles()
    pts = mesh.points.copy()
    mesh.points = np.column_stack([pts, 0.3 * pts[:, 0] ** 2])
    net = from_meshio(mesh, source="bent")
    with pytest.raises(InputError, match="do not lie in a plane"):
        Simulation(net, parameters={"youngs_modulus": 1.0, "density": 1.0, "heat_capacity": 1.0,
                                    "thickness": 0.1}, h=1e-3)


# ----------------------------------------------------------------------------------------------
# mechanisms


def test_a_space_chain_of_line_cells_is_a_mechanism_and_a_straight_bar_is_not():
    from thermonet.builders import read_mesh

    chain = read_mesh(os.path.join(SCENES, os.pardir, "meshes", "chain.msh"))
    found = floppy_modes(chain)
    assert found.dimension == 3 and found.count == 3 * chain.n_nodes - 6 - chain.n_springs
    pts = np.column_stack([np.linspace(0, 1, 4), np.zeros(4), np.zeros(4)])
    bar = from_meshio(meshio.Mesh(pts, [("line", np.array([[0, 1], [1, 2], [2, 3]]))]))
    assert floppy_modes(bar) == (0, True, 1, 1, "eigenvalues")


def _hexahedra(n=2):
    g = np.arange(n + 1, dtype=float)
    z, y, x = np.meshgrid(g, g, g, indexing="ij")
    pts = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    idx = np.arange(len(pts)).reshape(n + 1, n + 1, n + 1)
    hexes = [[idx[k, j, i], idx[k, j, i + 1], idx[k, j + 1, i + 1], idx[k, j + 1, i],
              idx[k + 1, j, i], idx[k + 1, j, i + 1], idx[k + 1, j + 1, i + 1], idx[k + 1, j + 1, i]]
             for k in range(n) for j in range(n) for i in range(n)]
    return meshio.Mesh(pts, [("hexahedron", np.array(hexes))])


def test_hexahedra_without_diagonals_are_a_mechanism_with_their_floppy_modes_counted():
    net = from_meshio(_hexahedra(), source="hexes.msh")
    found = floppy_modes(net)
    print(f"\nfloppy modes of 2×2×2 hexahedra: {found.count} ({found.method}); Maxwell's count "
          f"{3 * net.n_nodes - 6 - net.n_springs}")
    assert found.exact and found.count >= 3 * net.n_nodes - 6 - net.n_springs > 0
    with pytest.raises(InputError, match=rf"mechanism: {found.count} zero-frequency"):
        Simulation(net, parameters=checks.parameters(), h=1e-3)


def test_a_tetrahedral_bar_is_rigid(bars):
    for net in bars:
        found = floppy_modes(net)
        assert found.exact and found.count == 0 and found.rigid == 6


# ----------------------------------------------------------------------------------------------
# bad input


@pytest.mark.parametrize("key, value, words", [
    ("youngs_modulus", 0.0, "youngs_modulus must be finite and > 0"),
    ("density", -1.0, "density must be finite and > 0"),
    ("heat_capacity", float("nan"), "heat_capacity must be finite and > 0"),
    ("conductivity", -0.5, "conductivity must be finite and ≥ 0"),
    ("thermal_expansion", float("inf"), "thermal_expansion must be finite"),
])
def test_bad_properties_are_errors_naming_the_key(bars, key, value, words):
    with pytest.raises(InputError, match=words):
        Simulation(bars[0], parameters=checks.parameters(**{key: value}), h=1e-3)


def test_spring_parameters_beside_continuum_properties_are_an_error(bars):
    with pytest.raises(InputError, match="not both"):
        Simulation(bars[0], parameters=checks.parameters(c=5.0), h=1e-3)
    with pytest.raises(InputError, match="'density'"):
        Simulation(bars[0], parameters={"youngs_modulus": 1.0, "heat_capacity": 1.0}, h=1e-3)


def test_a_net_not_from_a_mesh_has_no_volumes_to_share():
    with pytest.raises(InputError, match="need a net read from a mesh"):
        Simulation(lattice((2, 2, 2), neighbours=18), parameters=checks.parameters(), h=1e-3)


def _scene(mesh_path, materials):
    return scene_from_text(f'[net]\nmesh = "{mesh_path}"\n{materials}\n[integrator]\nh = 1e-3\nsteps = 1\n',
                           file="s.toml")


def test_a_scene_region_mixing_both_kinds_is_an_error_naming_the_region(tmp_path):
    path = checks.bar_mesh(str(tmp_path / "bar.msh"), 0.25)
    with pytest.raises(SceneError, match=r"materials\.bar\.c.*not both"):
        _scene(path, "[materials.bar]\nyoungs_modulus = 2.0\ndensity = 1.0\nheat_capacity = 1.0\nc = 3.0\n")
    with pytest.raises(SceneError, match=r"materials\.bar\.density"):
        _scene(path, "[materials.bar]\nyoungs_modulus = 2.0\ndensity = -1.0\nheat_capacity = 1.0\n")
    with pytest.raises(SceneError, match=r"materials\.bar\.heat_capacity"):
        _scene(path, "[materials.bar]\nyoungs_modulus = 2.0\ndensity = 1.0\n")


def test_a_scene_on_a_mechanism_is_an_error_with_the_count(tmp_path):
    path = str(tmp_path / "hexes.vtu")
    _hexahedra().write(path)
    scene = _scene(path, "[materials.all]\nyoungs_modulus = 2.0\ndensity = 1.0\nheat_capacity = 1.0\n")
    with pytest.raises(SceneError, match=r"net\.mesh.*mechanism: \d+ zero-frequency mode"):
        scene.build()


def test_a_continuum_scene_builds_with_the_rule_and_info_reports_effective_properties(capsys):
    from thermonet.cli.info import describe_scene

    lines = describe_scene(os.path.join(SCENES, "bracket.toml"), [])
    text = "\n".join(lines)
    print(text)
    assert "Poisson's ratio 0.2" in text and "conductivity" in text and "rigid: no zero-frequency modes" in text
    mass = [ln for ln in lines if ln.strip().startswith("mass ")][0]
    shown, expected = mass.split("mass ")[1].split(" ")[0], mass.split("ρ V = ")[1].split(")")[0]
    assert shown == expected


def test_a_scene_and_the_api_give_the_same_springs_and_masses(tmp_path):
    from thermonet.builders import read_mesh

    path = checks.bar_mesh(str(tmp_path / "bar.msh"), 0.25)
    materials = "".join(f"{k} = {v!r}\n" for k, v in checks.parameters().items())
    built = _scene(path, "[effects]\nconduction = true\n[materials.bar]\n" + materials).build()
    api = Simulation(read_mesh(path), parameters=checks.parameters(), h=1e-3)
    np.testing.assert_array_equal(built.simulation.system.parameters, api.system.parameters)
    np.testing.assert_array_equal(built.net.masses, api.net.masses)
    np.testing.assert_array_equal(built.simulation.system.heat.conductance, api.system.heat.conductance)
    assert built.continuum.junction_factor == api.continuum.junction_factor


def test_a_later_spring_parameter_region_wins_and_initial_masses_are_refused(tmp_path):
    path = checks.bar_mesh(str(tmp_path / "bar.msh"), 0.25)
    continuum = "[materials.all]\nyoungs_modulus = 2.0\ndensity = 1.0\nheat_capacity = 1.0\n"
    built = _scene(path, continuum + "[materials.bar]\nc = 3.0\nbeta = 0.0\nC0 = 1.0\n").build()
    P = built.simulation.system.parameters
    assert np.all(P[0] == 3.0) and np.all(P[1] == 0.0)
    assert np.isnan(built.continuum.volume[built.net.spring_groups["bar"]]).all()  # no longer continuum springs
    assert np.all(built.net.masses == 1.0)  # so no node gets a mass from the density: the net's own
    with pytest.raises(SceneError, match=r"initial\.mass: node masses come from the density"):
        _scene(path, continuum + "[initial.mass]\nuniform = 2.0\n")
