"""The Numba-compiled right-hand side of Hamilton's equations (the cost study's SciPy baseline)
equals the NumPy reference's to round-off, on random nets, for both built-in models."""

from __future__ import annotations

import numpy as np
import pytest

import thermonet as tn
from thermonet.reference import HamiltonRHS
from thermonet.studies.compiled_rhs import CompiledHamiltonRHS
from thermonet.studies.ode import hamilton_rhs, solve_hamilton

PARAMETERS = {"hencky": dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0),
              "quadratic": dict(E=100.0, beta=0.5, C0=5.0, theta0=300.0, eta0=0.1)}


def random_simulation(model, seed, anchored=False, gravity=None):
    rng = np.random.default_rng(seed)
    net = tn.lattice((2, 2, 1), neighbours=18, jitter=0.2, seed=seed)
    if anchored:
        net = tn.Net(net.positions, net.edges, masses=rng.uniform(0.5, 2.0, net.n_nodes),
                     anchored=np.arange(net.n_nodes) < 2, rest_lengths=net.rest_lengths)
    m = net.n_springs
    v = rng.normal(0.0, 1.0, (net.n_nodes, 3))
    v[np.asarray(net.anchored, dtype=bool)] = 0.0
    # per-spring parameters, so a mix-up of springs or parameters shows
    params = {k: v * rng.uniform(0.8, 1.2, m) for k, v in PARAMETERS[model].items()}
    return tn.Simulation(net, model=model, parameters=params, temperatures=rng.uniform(250.0, 350.0, m),
                         velocities=v, integrator="co2", h=1e-3,
                         gravity=gravity)


@pytest.mark.parametrize("model", ["hencky", "quadratic"])
@pytest.mark.parametrize("anchored,gravity", [(False, None), (True, [0.0, 0.0, -9.81])])
def test_compiled_equals_numpy_to_round_off(model, anchored, gravity):
    sim = random_simulation(model, 7, anchored, gravity)
    numpy_rhs, y0 = hamilton_rhs(sim)
    compiled_rhs, y0c = hamilton_rhs(sim, compiled=True)
    assert isinstance(compiled_rhs, CompiledHamiltonRHS) and not isinstance(numpy_rhs, CompiledHamiltonRHS)
    assert isinstance(numpy_rhs, HamiltonRHS)
    np.testing.assert_array_equal(y0, y0c)
    rng = np.random.default_rng(11)
    k3 = 3 * numpy_rhs.k
    for _ in range(5):  # y0 and random states around it (stretched springs, moved Φ)
        y = y0 + np.concatenate([rng.normal(0, 0.05, k3), rng.normal(0, 1.0, k3), rng.normal(0, 1.0, len(y0) - 2 * k3)])
        a, b = numpy_rhs(0.0, y), compiled_rhs(0.0, y)
        for part in (slice(0, k3), slice(k3, 2 * k3), slice(2 * k3, None)):
            scale = np.abs(a[part]).max()
            assert np.abs(a[part] - b[part]).max() <= 1e-13 * scale


def test_dop853_on_either_right_hand_side_agrees():
    sim = random_simulation("hencky", 3)
    a = solve_hamilton(sim, 0.5, "DOP853", 1e-10, 1e-10)
    b = solve_hamilton(random_simulation("hencky", 3), 0.5, "DOP853", 1e-10, 1e-10, compiled=True)
    assert np.abs(a.snapshot.positions - b.snapshot.positions).max() < 1e-12


def test_cost_study_times_scipy_on_both_right_hand_sides():
    from thermonet.studies import cost_study

    study = cost_study("chain", ["co2"], dt=0.05, halvings=1, t_end=0.5, repeats=1, scipy={"DOP853": [1e-6]},
                       scipy_rhs="both", check=None)
    rows = {r["solver"]: r for r in study.rows if r["solver"].startswith("scipy")}
    assert set(rows) == {"scipy-DOP853", "scipy-DOP853-numpy"}
    # the same ODE, tolerance and steps: the same error up to round-off
    assert rows["scipy-DOP853"]["work"] == rows["scipy-DOP853-numpy"]["work"]
    assert rows["scipy-DOP853"]["position"] == pytest.approx(rows["scipy-DOP853-numpy"]["position"], rel=1e-6)
    assert "Numba-compiled, and NumPy" in study.summary()


def test_lattice_scene_is_the_cost_studys_net():
    from thermonet.studies.scenes import make_simulation

    sim = make_simulation("lattice", "bm4", 0.01)
    assert (sim.net.n_nodes, sim.net.n_springs) == (729, 1944)
    theta = sim.temperatures()
    assert 250.0 <= theta.min() and theta.max() <= 350.0


@pytest.mark.parametrize("model", ["hencky", "quadratic"])
def test_a_mechanical_run_has_the_isothermal_right_hand_side(model):
    """Thermal coupling off: every spring stays at θ0, so ṗ = −∇ Σ U(l) with the springs'
    isothermal energies (½ c ln²(l/l0), or E (l − l0)² / 2 l0) and Φ̇ = θ0, on both right-hand sides."""
    rng = np.random.default_rng(5)
    net = tn.lattice((2, 2, 1), neighbours=18, jitter=0.2, seed=5)
    m = net.n_springs
    params = {k: v * rng.uniform(0.8, 1.2, m) for k, v in PARAMETERS[model].items()}
    sim = tn.Simulation(net, model=model, parameters=params, thermal=False,
                        velocities=rng.normal(0.0, 1.0, (net.n_nodes, 3)), integrator="co2", h=1e-3)
    stiffness, l0 = params["c" if model == "hencky" else "E"], np.asarray(net.rest_lengths)

    def energy(x):
        l = np.linalg.norm(x[net.edges[:, 1]] - x[net.edges[:, 0]], axis=1)
        return float(np.sum(0.5 * stiffness * np.log(l / l0) ** 2 if model == "hencky"
                            else 0.5 * stiffness * (l - l0) ** 2 / l0))

    for compiled in (False, True):
        rhs, y0 = hamilton_rhs(sim, compiled=compiled)
        k3 = 3 * rhs.k
        y = y0 + np.concatenate([rng.normal(0, 0.05, k3), np.zeros(len(y0) - k3)])
        dy = rhs(0.0, y)
        grad = np.empty(k3)
        for i in range(k3):
            step = np.zeros(k3)
            step[i] = 1e-6
            grad[i] = (energy((y[:k3] + step).reshape(-1, 3)) - energy((y[:k3] - step).reshape(-1, 3))) / 2e-6
        np.testing.assert_allclose(dy[k3:2 * k3], -grad, rtol=0, atol=1e-7 * np.abs(grad).max())
        np.testing.assert_array_equal(dy[2 * k3:], params["theta0"])
