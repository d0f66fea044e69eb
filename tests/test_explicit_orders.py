"""Convergence orders of the explicit integrators on the paper's chain (docs/theory.md §4, §2.6).

The error at t = 1 of the Numba kernels (through the public Simulation API) is measured against
Hamilton's equations (spec (18)) integrated by SciPy's DOP853 at rtol = atol = 1e-13 on the NumPy
reference right-hand side. That reference differs from one at rtol = atol = 3e-14 by ≈ 5e-14 in
positions and ≈ 2e-13 in momenta and temperatures, so it is good to a few 1e-13.

Step sizes are the paper's h = 0.1·2⁻ⁱ. Each integrator is fitted over the range of i where
(a) h is small enough that the error is asymptotic (local slopes settle: at i ≤ 2 the
first-order and second-order methods still show slopes of 1.2–1.9) and (b) the smallest error
stays about 100× above the reference error or more (CO6 reaches ≈ 5e-11 at i = 6 and hits
the reference's floor at i = 7, so its range stops at 6; CO4 reaches ≈ 2e-8 at i = 7).
"""

import numpy as np
import pytest

import thermonet as tn

T_END = 1.0
TOLERANCE = 0.15

# integrator -> (expected order, range of i in h = 0.1·2⁻ⁱ used for the fit)
CASES = {
    "gtr-0": (1, range(4, 10)),
    "gtr-1": (1, range(4, 10)),
    "co2": (2, range(3, 9)),
    "f01": (2, range(3, 9)),
    "f10": (2, range(3, 9)),
    "nm2": (2, range(3, 9)),
    "co4": (4, range(3, 8)),
    "co6": (6, range(2, 7)),
}


def errors_at_t1(name, h, reference):
    """Max-norm errors (positions, momenta, temperatures) of a run of ``name`` to t = 1."""
    sim = tn.chain_simulation(name, h=h)
    sim.run(t_end=T_END, diagnostics_every=10**9)
    assert sim.time == pytest.approx(T_END, abs=1e-12)
    x, p, theta = reference
    state = sim.state
    return (np.abs(state.positions - x).max(), np.abs(state.momenta - p).max(),
            np.abs(sim.temperatures() - theta).max())


def fitted_slope(h, err):
    return np.polyfit(np.log(h), np.log(err), 1)[0]


@pytest.mark.parametrize("name", list(CASES))
def test_order_on_the_chain(name, chain_reference):
    order, exponents = CASES[name]
    assert tn.get_integrator(name).order == order
    h = np.array([0.1 * 2.0**-i for i in exponents])
    errs = np.array([errors_at_t1(name, hi, chain_reference) for hi in h])
    # the smallest error must sit well above the reference's own error (a few 1e-13)
    assert errs.min() > 2e-11
    for k, quantity in enumerate(("positions", "momenta", "temperatures")):
        slope = fitted_slope(h, errs[:, k])
        assert abs(slope - order) <= TOLERANCE, f"{name}: slope {slope:.3f} in {quantity}, expected {order}"


def test_nm2_and_co2_give_the_same_positions_and_momenta():
    runs = {}
    for name in ("co2", "nm2"):
        sim = tn.chain_simulation(name, h=0.01)
        sim.run(steps=1000, diagnostics_every=10**9)
        runs[name] = sim
    a, b = runs["co2"].state, runs["nm2"].state
    np.testing.assert_allclose(b.positions, a.positions, rtol=0, atol=1e-13 * np.abs(a.positions).max())
    np.testing.assert_allclose(b.momenta, a.momenta, rtol=0, atol=1e-13 * np.abs(a.momenta).max())
    # NM2 treats η as a parameter and does not integrate Φ; CO2 does
    assert np.all(b.thermal_displacement == 0.0)
    assert np.all(a.thermal_displacement > 0.0)


def test_f10_and_f01_are_different_methods(chain_reference):
    states = {}
    for name in ("f01", "f10"):
        sim = tn.chain_simulation(name, h=0.0125)
        sim.run(t_end=T_END, diagnostics_every=10**9)
        states[name] = sim.state
    gap = np.abs(states["f01"].positions - states["f10"].positions).max()
    error = np.abs(states["f01"].positions - chain_reference[0]).max()
    # they differ by an amount of the size of their (second-order) errors, not by round-off
    assert gap > 0.1 * error > 1e-4
