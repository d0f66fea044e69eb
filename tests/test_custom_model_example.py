"""examples/custom_model.py: a model defined in the user's own module runs in the kernels,
keeps every spring's entropy exactly, and keeps energy bounded; its functions are consistent."""

import contextlib
import io
import runpy
from pathlib import Path

import numpy as np
import pytest

import thermonet as tn
from thermonet.kernels.springs import map_springs

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "custom_model.py"


@pytest.fixture(scope="module")
def example():
    """The script's globals after running it as a script, plus what it printed."""
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        scope = runpy.run_path(str(EXAMPLE), run_name="__main__")
    return {**scope, "printed": printed.getvalue()}


def test_example_runs_and_conserves(example):
    sim = example["sim"]
    assert sim.model.name == "softening-hencky" and sim.model.name not in tn.available_models()
    assert sim.time == pytest.approx(10.0)
    eta0 = example["build_simulation"]().state.entropy
    assert np.array_equal(sim.state.entropy, eta0)
    diag = sim.diagnostics
    assert np.all(diag.entropy == diag.entropy[0])
    summary = sim.conservation_summary()
    # measured: 1.1e-6 relative with h = 2e-3 over 5000 steps; CO2's error is O(h²)
    assert summary["energy"]["relative"] < 1e-5
    for q in ("px", "py", "pz", "Lx", "Ly", "Lz"):
        assert summary[q]["relative"] < 1e-12
    # the heat really matters: the stiffness c(θ) = c (1 − 0.05 (θ − θ0)/θ0) varies by more than 5 %
    theta = sim.temperatures()
    assert (theta.max() - theta.min()) / 300.0 > 1.0


def test_example_prints_the_summary(example):
    for word in ("energy", "entropy", "Lz", "softening-hencky"):
        assert word in example["printed"]


def derivative(f, x, dx):
    return (-f(x + 2 * dx) + 8 * f(x + dx) - 8 * f(x - dx) + f(x - 2 * dx)) / (12 * dx)


def test_the_custom_model_is_thermodynamically_consistent(example):
    model = example["SOFTENING_HENCKY"]
    rng = np.random.default_rng(0)
    k = 300
    l0 = rng.uniform(0.5, 2, k)
    l = l0 * np.exp(rng.uniform(-0.6, 0.6, k))
    theta = rng.uniform(100, 2000, k)
    P = np.array([rng.uniform(50, 200, k), rng.uniform(0, 0.1, k), rng.uniform(0, 0.4, k),
                  rng.uniform(2, 8, k), np.full(k, 300.0)])

    def f(name, ll, s):
        out = np.empty(k)
        map_springs(model, name)(ll, s, l0, P, out)
        return out

    eta = f("entropy", l, theta)
    np.testing.assert_allclose(f("temperature", l, eta), theta, rtol=1e-12)
    dl, dth = 1e-3 * l, 1e-3 * theta
    tol = dict(rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(derivative(lambda x: f("free_energy", x, theta), l, dl), f("tension", l, theta), **tol)
    np.testing.assert_allclose(-derivative(lambda x: f("free_energy", l, x), theta, dth), eta, **tol)
    np.testing.assert_allclose(derivative(lambda x: f("internal_energy", x, eta), l, dl), f("tension", l, theta), **tol)
    np.testing.assert_allclose(derivative(lambda x: f("internal_energy", l, x), eta, 1e-3), theta, rtol=1e-8)
    np.testing.assert_allclose(derivative(lambda x: f("tension", x, theta), l, dl), f("d2F_dl2", l, theta), **tol)
    np.testing.assert_allclose(derivative(lambda x: f("tension", l, x), theta, dth), f("d2F_dl_dtheta", l, theta), **tol)
    np.testing.assert_allclose(-derivative(lambda x: f("entropy", l, x), theta, dth), f("d2F_dtheta2", l, theta), **tol)
