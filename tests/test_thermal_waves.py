"""Green–Naghdi type II thermal waves (docs/theory.md §6): a Hamiltonian heat flow in the splittings."""

import numpy as np
import pytest

import thermonet as tn
from thermonet.errors import InputError

from test_heat_flow import QUIET, chain_net


def warm_net(seed: int = 3):
    net = tn.lattice((3, 3, 2), neighbours=18, jitter=0.2, seed=seed)
    rng = np.random.default_rng(seed)
    return net, 300.0 * (1 + 0.1 * rng.uniform(-1, 1, net.n_springs))


def test_total_entropy_is_exact_and_energy_bounded_without_drift_over_1e5_steps():
    net, theta = warm_net()
    sim = tn.Simulation(net, parameters=dict(c=100, beta=1.0, C0=1.0, theta0=300, g_star=0.05), temperatures=theta,
                        velocities=np.random.default_rng(2).normal(0, 0.2, (net.n_nodes, 3)), h=0.004, **QUIET)
    assert sim.integrator.name == "co2+waves"
    d = sim.run(steps=100_000, diagnostics_every=100)
    assert np.max(np.abs(d.entropy - d.entropy[0])) < 1e-12 * np.abs(sim.state.entropy).sum()
    assert np.ptp(sim.state.entropy) > 0  # per spring it is not constant: heat moved
    assert d.wave_energy.max() > 1e-3 * abs(d.energy[0])
    e = d.energy
    tenth = len(e) // 10
    oscillation = np.max(np.abs(e - e[0]))
    assert oscillation < 1e-3 * abs(e[0])
    assert abs(e[-tenth:].mean() - e[:tenth].mean()) < 0.2 * oscillation
    assert np.abs(d.linear_momentum - d.linear_momentum[0]).max() < 1e-10


def test_a_thermal_pulse_travels_at_the_wave_speed():
    n, g_star, C, theta0 = 300, 0.02, 1.0, 300.0
    e = np.arange(n)
    centre, width = 100.0, 8.0
    theta = theta0 * (1 + 1e-3 * np.exp(-((e - centre) / width) ** 2))
    sim = tn.Simulation(chain_net(n), parameters=dict(c=100, beta=0.0, C0=C, theta0=theta0, g_star=g_star),
                        temperatures=theta, h=0.02, renumber=False, **QUIET)
    t_end = 60.0
    sim.run(t_end=t_end, diagnostics_every=1000)
    rise = sim.temperatures() - theta0
    right = int(centre) + np.argmax(rise[int(centre):])
    a, b, c = rise[right - 1:right + 2]  # the peak, to a fraction of a spring
    peak = right + 0.5 * (a - c) / (a - 2 * b + c)
    speed = (peak - centre) / t_end
    expected = np.sqrt(g_star / 2 * theta0 / C)  # κ* = g*/2 between neighbours of a uniform chain
    assert speed == pytest.approx(expected, rel=0.02)


def wave_run(integrator: str, h: float):
    net = chain_net(6)
    net.anchored[0] = True
    theta = 300.0 * (1 + 0.05 * np.sin(np.arange(6)))
    v = np.zeros((7, 3))
    v[1:, 1] = 0.3 * np.cos(np.arange(6))
    sim = tn.Simulation(net, parameters=dict(c=10, beta=0.2, C0=1.0, theta0=300, g_star=0.1), temperatures=theta,
                        velocities=v, integrator=integrator, h=h, renumber=False, **QUIET)
    sim.run(t_end=1.0, diagnostics_every=10 ** 6)
    s = sim.state
    return np.concatenate([s.positions.ravel(), s.momenta.ravel(), s.entropy, s.thermal_displacement])


@pytest.mark.parametrize("integrator, order", [("co2", 2), ("co4", 4), ("co6", 6)])
def test_compositions_keep_their_order_with_thermal_waves(integrator, order):
    reference = wave_run("co6", 1 / 1280)
    hs = np.array([1 / 40, 1 / 80, 1 / 160]) if order < 6 else np.array([1 / 20, 1 / 40, 1 / 80])
    errors = np.array([np.abs(wave_run(integrator, h) - reference).max() for h in hs])
    slope = np.polyfit(np.log(hs), np.log(errors), 1)[0]
    assert order - 0.3 < slope < order + 0.6, (errors, slope)


def test_waves_need_phi_and_an_explicit_splitting():
    params = dict(c=10, beta=0.1, C0=1.0, theta0=300, g_star=0.1)
    with pytest.raises(InputError, match="thermal displacement"):
        tn.Simulation(chain_net(3), parameters=params, integrator="nm2")
    with pytest.raises(InputError, match="explicit splittings"):
        tn.Simulation(chain_net(3), parameters=params, integrator="ho4")
    with pytest.raises(InputError, match="no conductance 'g_star'"):
        tn.Simulation(chain_net(3), parameters=dict(c=10), thermal_waves=True)


def test_the_stable_step_includes_the_thermal_waves_limit_and_the_guard_stops_above_it():
    from thermonet.errors import SimulationError
    from thermonet.stability import stable_step, wave_frequency

    net, theta = warm_net(5)
    common = dict(parameters=dict(c=100, beta=1.0, C0=1.0, theta0=300, g_star=20.0), temperatures=theta)
    mechanical = tn.Simulation(net, **{**common, "parameters": dict(c=100, beta=1.0, C0=1.0, theta0=300)})
    waves = tn.Simulation(net, **common)
    without, with_waves = stable_step(mechanical), stable_step(waves)
    assert with_waves["limit"] == "thermal waves" and without["limit"] == "mechanical"
    assert with_waves["h_max"] < 0.5 * without["h_max"]
    omega_w = with_waves["omega_waves"]
    assert omega_w <= wave_frequency(waves, bound_only=True) * (1 + 1e-12)
    # above the waves' limit (and well below the mechanical one) the guard warns, then stops
    from thermonet.step_policy import REFUSE, StepWarning

    h = 1.2 * with_waves["h_max"]
    with pytest.warns(StepWarning, match="thermal waves"):
        tn.Simulation(net, h=h, energy_tolerance=None, **common).run(steps=2, diagnostics_every=1)
    h = 1.1 * REFUSE * with_waves["h_max"]
    assert h < 0.9 * without["h_max"]  # mechanically fine: only the waves' limit is crossed
    with pytest.raises(SimulationError, match="thermal waves"):
        tn.Simulation(net, h=h, energy_tolerance=None, **common).run(steps=200, diagnostics_every=1)
