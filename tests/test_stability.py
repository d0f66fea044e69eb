"""Stable step estimates: intervals from the coefficients, checked by running a linear spring."""

import numpy as np
import pytest

import thermonet as tn
from thermonet.explicit.splitting import CO2, CO4, CO6, F10, GTR0, GTR1, NM2
from thermonet.stability import max_frequency, stability_interval, stable_step


def test_central_difference_family_has_interval_two():
    for integ in (GTR0, GTR1, CO2, F10, NM2):
        assert stability_interval(integ) == pytest.approx(2.0, abs=1e-9)


def linear_spring():
    """One linear spring (quadratic model, no coupling) with one end anchored: ω² = E/(l0 m)."""
    net = tn.Net([[0, 0, 0], [1, 0, 0]], [[0, 1]], masses=[1.0, 2.0], anchored=[0], rest_lengths=[1.0])
    return net, np.sqrt(100.0 / 2.0)


def energy_growth(integ, h, steps=4000):
    net, _ = linear_spring()
    sim = tn.Simulation(net, model="quadratic", parameters=dict(E=100.0, beta=0.0),
                        momenta=[[0, 0, 0], [0.01, 0, 0]], integrator=integ, h=h,
                        stability_guard="off", energy_tolerance=None)  # unguarded: measuring the limit itself
    try:
        with np.errstate(all="ignore"):
            e = sim.run(steps=steps, diagnostics_every=10).energy
    except tn.SimulationError:  # the run stopped on a non-finite state: unbounded
        return np.inf
    if not np.isfinite(e).all():
        return np.inf
    half = len(e) // 2
    return np.max(np.abs(e[half:] - e[0])) / max(np.max(np.abs(e[1:half] - e[0])), 1e-300)


@pytest.mark.parametrize("integ", [GTR0, CO2, F10, CO4, CO6], ids=lambda i: i.name)
def test_interval_is_the_measured_limit(integ):
    """Just inside the interval the energy error does not grow; just outside it explodes."""
    _, omega = linear_spring()
    c = stability_interval(integ)
    assert energy_growth(integ, 0.98 * c / omega) < 1.5
    grown = energy_growth(integ, 1.02 * c / omega)
    assert not np.isfinite(grown) or grown > 1e6


def test_frequency_estimate_matches_the_linear_spring():
    net, omega = linear_spring()
    sim = tn.Simulation(net, model="quadratic", parameters=dict(E=100.0, beta=0.0))
    est = max_frequency(sim.system, sim._state.positions, sim._state.entropy)
    assert est.omega_max == pytest.approx(omega, rel=1e-12)
    assert est.gershgorin_bound >= est.omega_max * (1 - 1e-12)


def test_lanczos_agrees_with_dense_on_a_lattice():
    net = tn.lattice((7, 7, 7), jitter=0.1)  # > 200 free dofs: Lanczos path
    sim = tn.Simulation(net, parameters=dict(c=1e4), temperatures=500.0)
    from thermonet.stability import stiffness_matrix

    s = sim._state
    K = stiffness_matrix(sim.system, s.positions, s.entropy).toarray()
    w = 1 / np.sqrt(np.repeat(sim.system.masses, 3))
    dense = np.sqrt(np.linalg.eigvalsh(w[:, None] * K * w[None, :]).max())
    est = stable_step(sim)
    assert est["method"].startswith("Lanczos")
    assert est["omega_max"] == pytest.approx(dense, rel=1e-3)
    assert est["h_max"] == pytest.approx(2.0 / dense, rel=1e-3)


def test_stiffness_is_the_hessian_of_the_energy():
    """K from the model's second derivatives equals a finite difference of the forces (η fixed)."""
    net = tn.lattice((1, 1, 1), neighbours=26, jitter=0.2, seed=3)
    rng = np.random.default_rng(0)
    sim = tn.Simulation(net, parameters=dict(c=50.0, beta=2.0), temperatures=rng.uniform(200, 600, net.n_springs))
    from thermonet.diagnostics import measure
    from thermonet.stability import stiffness_matrix

    s = sim._state
    x0 = s.positions.copy()
    x0 += rng.normal(scale=0.05, size=x0.shape)
    K = stiffness_matrix(sim.system, x0, s.entropy).toarray()

    def energy(x):
        s.positions = x
        return measure(sim.system, s)["internal"]

    eps = 1e-4
    n3 = x0.size
    H = np.empty((n3, n3))
    flat = x0.ravel()
    for i in range(n3):
        for j in range(i, n3):
            def E(di, dj):
                y = flat.copy()
                y[i] += di
                y[j] += dj
                return energy(y.reshape(-1, 3))
            H[i, j] = H[j, i] = (E(eps, eps) - E(eps, -eps) - E(-eps, eps) + E(-eps, -eps)) / (4 * eps * eps)
    assert np.max(np.abs(H - K)) < 1e-5 * np.max(np.abs(K))
