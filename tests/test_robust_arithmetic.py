"""Robust arithmetic over extreme but valid states: the "hencky" model's functions,
through the kernels' fast exp/log, against a 40-digit mpmath evaluation of the same formulas.

Ranges: stretch λ = l/l0 in [1e-3, 1e3], θ/θ0 in [1e-3, 1e3], c in [1e-2, 1e8], β in {0, 0.2, 50}.
Errors are in units of ε = 2⁻⁵², relative to the sum of the magnitudes of each formula's terms
(its own condition: a difference of large terms cannot be resolved better). Measured worst cases:
θ 12.6 ε (exp amplifies the rounding of its argument, |arg| ≤ ~7 here), T 1.3 ε, η 1.4 ε, U 10.7 ε.
"""

import mpmath as mp
import numpy as np
import pytest
from numba import njit

import thermonet as tn
from thermonet.models.hencky import entropy, internal_energy, temperature, tension

EPS = 2.0**-52


@njit
def _hencky(l, eta, th, l0, P):
    return temperature(l, eta, l0, P, 0), tension(l, th, l0, P, 0), entropy(l, th, l0, P, 0), internal_energy(l, eta, l0, P, 0)


def test_hencky_is_accurate_over_the_extreme_ranges():
    mp.mp.dps = 40
    C0, th0, l0 = 5.0, 300.0, 1.0
    worst = np.zeros(4)
    for lam in np.geomspace(1e-3, 1e3, 9):
        for ratio in np.geomspace(1e-3, 1e3, 9):
            for c in (1e-2, 1.0, 1e4, 1e8):
                for beta in (0.0, 0.2, 50.0):
                    P = np.array([[c], [beta], [C0], [th0]])
                    l, th = lam * l0, ratio * th0
                    L = mp.log(mp.mpf(l) / l0)
                    eta_x = beta * L + C0 * mp.log(mp.mpf(th) / th0)
                    eta = float(eta_x)
                    got = _hencky(l, eta, th, l0, P)
                    assert np.isfinite(got).all()
                    theta_x = th0 * mp.exp((mp.mpf(eta) - beta * L) / C0)
                    T_x = (c * L - beta * (mp.mpf(th) - th0)) / l
                    U_x = c / 2 * L * L + beta * th0 * L + C0 * (theta_x - th0)
                    scales = (theta_x, (abs(c * L) + abs(beta * (mp.mpf(th) - th0))) / l,
                              abs(beta * L) + abs(C0 * mp.log(mp.mpf(th) / th0)) + C0 * EPS,
                              c / 2 * L * L + abs(beta * th0 * L) + C0 * (theta_x + th0))
                    exact = (theta_x, T_x, eta_x, U_x)
                    for i in range(4):
                        if scales[i]:
                            worst[i] = max(worst[i], float(abs(got[i] - exact[i]) / scales[i]) / EPS)
    assert worst[0] < 20 and worst[1] < 3 and worst[2] < 3 and worst[3] < 16, worst


@pytest.mark.parametrize("delta", [1e-15, 1e-12, 1e-9, 1e-6, -1e-9])
def test_near_rest_strain_error_is_that_of_the_length_itself(delta):
    """ln(l/l0) near rest: the quotient's rounding (≤ ε/2 of 1) is the only error, the same size as
    the rounding of l; so T = c L / l is off by at most ~c ε / l absolutely, never relatively
    amplified beyond what the positions carry."""
    mp.mp.dps = 40
    l0 = 1.7
    l = l0 * (1 + delta)
    P = np.array([[1.0], [0.0], [5.0], [300.0]])
    T = _hencky(l, 0.0, 300.0, l0, P)[1]
    exact = float(mp.log(mp.mpf(l) / mp.mpf(l0)) / l)
    assert abs(T - exact) <= 1.5 * EPS / l


def mixed_masses(factor):
    """A jittered 3×3×1 lattice with node masses 10^U(−3, 3) (1e-3 and 1e3 side by side), run to
    t = 1e4 h_max at h = factor · h_max."""
    from thermonet.stability import stable_step

    net = tn.lattice((3, 3, 1), jitter=0.1, seed=7)
    rng = np.random.default_rng(8)
    net.masses = 10.0 ** rng.uniform(-3, 3, net.n_nodes)
    net.masses[0], net.masses[1] = 1e-3, 1e3
    momenta = rng.normal(scale=0.1, size=(net.n_nodes, 3))
    sim = tn.Simulation(net, parameters=dict(c=1e3), temperatures=600.0, momenta=momenta, h=1.0)
    h_max = stable_step(sim)["h_max"]
    sim.h = factor * h_max
    return sim.run(t_end=1e4 * h_max, diagnostics_every=int(round(200 / factor)))


def test_masses_over_six_orders_of_magnitude_in_one_net():
    d = mixed_masses(0.5)
    e = d.energy
    err = np.abs(e - e[0]).max() / e[0]
    assert err < 1.2e-4  # measured 4.0e-5
    assert np.abs(d.entropy - d.entropy[0]).max() == 0.0
    for q in (d.px, d.py, d.pz):
        assert np.abs(q - q[0]).max() < 1e-10  # measured 1.4e-12
    d2 = mixed_masses(0.25)  # an O(h²) oscillation, not a drift: measured ratio 5.0
    assert 3.0 < err / (np.abs(d2.energy - d2.energy[0]).max() / d2.energy[0]) < 6.5
