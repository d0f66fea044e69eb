"""Convergence orders of the implicit integrators on the paper's chain (docs/theory.md §2.6, §4).

Errors at t = 1 in positions, momenta and temperatures against Hamilton's equations integrated by
SciPy's DOP853 at rtol = atol = 1e-13 (good to a few 1e-13; see test_explicit_orders.py).
Steps h = 0.1·2⁻ⁱ, i = 3…7: there the local slopes of all three methods have settled (HO4 is
still pre-asymptotic at i ≤ 2: local slopes 1.8–5.1), and HO4's smallest error (≈ 2e-8) stays far
above the reference's.
"""

import numpy as np
import pytest

import thermonet as tn

T_END = 1.0
TOLERANCE = 0.15
STEPS = np.array([0.1 * 2.0**-i for i in range(3, 8)])


def errors(integrator, options, h, reference):
    sim = tn.chain_simulation(integrator, h=h, integrator_options=options)
    sim.run(t_end=T_END, diagnostics_every=10**9)
    assert sim.time == pytest.approx(T_END, abs=1e-12)
    x, p, theta = reference
    s = sim.state
    return np.abs(s.positions - x).max(), np.abs(s.momenta - p).max(), np.abs(sim.temperatures() - theta).max()


@pytest.mark.parametrize("integrator, options, order", [
    ("gtr-1/2", {}, 2),
    ("ho4", {}, 4),
    ("gtr-alpha", {"alpha": 0.3}, 1),
    ("gtr-alpha", {"alpha": 0.8}, 1),
])
def test_order_on_the_chain(integrator, options, order, chain_reference):
    assert tn.get_integrator(integrator, **options).order == order
    errs = np.array([errors(integrator, options, h, chain_reference) for h in STEPS])
    assert errs.min() > 1e-9  # far above the reference's own error
    for k, quantity in enumerate(("positions", "momenta", "temperatures")):
        slope = np.polyfit(np.log(STEPS), np.log(errs[:, k]), 1)[0]
        assert abs(slope - order) <= TOLERANCE, f"{integrator} {options}: slope {slope:.3f} in {quantity}"


@pytest.mark.parametrize("alpha, explicit", [(0.0, "gtr-0"), (1.0, "gtr-1")])
def test_gtr_alpha_at_0_and_1_is_the_explicit_method(alpha, explicit):
    implicit = tn.chain_simulation("gtr-alpha", h=0.01, integrator_options={"alpha": alpha})
    reference = tn.chain_simulation(explicit, h=0.01)
    for sim in (implicit, reference):
        sim.run(steps=100, diagnostics_every=10**9)
    a, b = implicit.state, reference.state
    # round-off: 100 steps of a chaotic system amplify ulps to a few 1e-16 … 1e-15 here
    assert np.abs(a.positions - b.positions).max() <= 1e-13 * np.abs(b.positions).max()
    assert np.abs(a.momenta - b.momenta).max() <= 1e-13 * np.abs(b.momenta).max()
    assert np.abs(a.thermal_displacement - b.thermal_displacement).max() <= 1e-13 * np.abs(b.thermal_displacement).max()
    assert np.abs(implicit.temperatures() - reference.temperatures()).max() <= 1e-13 * reference.temperatures().max()
    # and it is not the second-order method: GTR-1/2 differs from both at the size of their errors
    half = tn.chain_simulation("gtr-1/2", h=0.01)
    half.run(steps=100, diagnostics_every=10**9)
    assert np.abs(half.state.positions - b.positions).max() > 1e-3
