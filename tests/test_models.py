"""The constitutive models (docs/theory.md §1.2–1.3): the engine's compiled scalar functions against the
NumPy formulas of thermonet.reference, and the thermodynamic identities between them
(T = ∂F/∂l = ∂U/∂l, Γ = −∂F/∂θ, θ = ∂U/∂η, Γ(l, θ(l, η)) = η, second derivatives)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import thermonet as tn
from thermonet.kernels.springs import map_springs
from thermonet.reference import LAWS

MODELS = ("hencky", "quadratic")
FUNCTIONS = ("free_energy", "tension", "entropy", "temperature", "internal_energy",
             "d2F_dl2", "d2F_dl_dtheta", "d2F_dtheta2")


def sample(model, k=400, seed=0):
    """Random lengths, rest lengths, temperatures and parameters covering strong stretch and
    compression and temperatures from well below to well above theta0."""
    rng = np.random.default_rng(seed)
    l0 = rng.uniform(0.5, 2.0, k)
    l = l0 * np.exp(rng.uniform(-0.7, 0.7, k))
    theta0 = rng.uniform(100, 500, k)
    theta = theta0 * np.exp(rng.uniform(-1.0, 1.5, k))
    P = {"beta": rng.uniform(0.0, 0.5, k), "C0": rng.uniform(1, 10, k), "theta0": theta0}
    if model == "hencky":
        P["c"] = rng.uniform(10, 500, k)
    else:
        P["E"] = rng.uniform(10, 500, k)
        P["eta0"] = rng.uniform(-2, 2, k)
    return l, l0, theta, P


def engine(model, function, l, s, l0, P):
    """The engine's compiled model function applied to every sample."""
    m = tn.get_model(model)
    Parr = np.array([P[name] for name in m.parameters])
    out = np.empty_like(l)
    map_springs(m, function)(l, s, l0, Parr, out)
    return out


def derivative(f, x, dx):
    """4th-order central difference of f at x with steps dx (arrays)."""
    return (-f(x + 2 * dx) + 8 * f(x + dx) - 8 * f(x - dx) + f(x - 2 * dx)) / (12 * dx)


def test_registry_and_parameter_order():
    assert {"hencky", "quadratic"} <= set(tn.available_models())
    for model in MODELS:
        assert tn.get_model(model).parameters == LAWS[model].parameters


@pytest.mark.parametrize("function", FUNCTIONS)
@pytest.mark.parametrize("model", MODELS)
def test_engine_functions_match_the_spec_formulas(model, function):
    l, l0, theta, P = sample(model)
    law = LAWS[model]
    eta = law.entropy(l, theta, l0, P)
    s = eta if function in ("temperature", "internal_energy") else theta
    expected = getattr(law, function)(l, s, l0, P)
    np.testing.assert_allclose(engine(model, function, l, s, l0, P), expected, rtol=1e-13,
                               atol=1e-13 * np.abs(expected).max())


@pytest.mark.parametrize("model", MODELS)
def test_temperature_inverts_entropy(model):
    l, l0, theta, P = sample(model, seed=1)
    eta = engine(model, "entropy", l, theta, l0, P)
    theta_back = engine(model, "temperature", l, eta, l0, P)
    np.testing.assert_allclose(theta_back, theta, rtol=1e-12)
    np.testing.assert_allclose(engine(model, "entropy", l, theta_back, l0, P), eta, rtol=0,
                               atol=1e-12 * np.abs(eta).max())


@pytest.mark.parametrize("model", MODELS)
def test_first_derivatives(model):
    """T = ∂F/∂l, Γ = −∂F/∂θ, T(l, θ(l, η)) = ∂U/∂l at fixed η, θ = ∂U/∂η (spec (11), (16))."""
    l, l0, theta, P = sample(model, seed=2)
    eta = engine(model, "entropy", l, theta, l0, P)
    F = lambda ll, th: engine(model, "free_energy", ll, th, l0, P)
    U = lambda ll, et: engine(model, "internal_energy", ll, et, l0, P)
    dl, dth, deta = 1e-3 * l, 1e-3 * theta, 1e-3 * np.maximum(np.abs(eta), 1.0)
    T = engine(model, "tension", l, theta, l0, P)
    Gamma = engine(model, "entropy", l, theta, l0, P)
    tol = dict(rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(derivative(lambda x: F(x, theta), l, dl), T, **tol)
    np.testing.assert_allclose(-derivative(lambda x: F(l, x), theta, dth), Gamma, **tol)
    np.testing.assert_allclose(derivative(lambda x: U(x, eta), l, dl), T, **tol)
    np.testing.assert_allclose(derivative(lambda x: U(l, x), eta, deta), theta, rtol=1e-9)
    # U = F + ηθ at θ = θ(l, η) (spec (15))
    np.testing.assert_allclose(U(l, eta), F(l, theta) + eta * theta, rtol=1e-11, atol=1e-9)


@pytest.mark.parametrize("model", MODELS)
def test_second_derivatives(model):
    """The Newton path's ∂²F/∂l², ∂²F/∂l∂θ, ∂²F/∂θ² against differences of T and Γ."""
    l, l0, theta, P = sample(model, seed=3)
    T = lambda ll, th: engine(model, "tension", ll, th, l0, P)
    G = lambda ll, th: engine(model, "entropy", ll, th, l0, P)
    dl, dth = 1e-3 * l, 1e-3 * theta
    tol = dict(rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(derivative(lambda x: T(x, theta), l, dl),
                               engine(model, "d2F_dl2", l, theta, l0, P), **tol)
    np.testing.assert_allclose(derivative(lambda x: T(l, x), theta, dth),
                               engine(model, "d2F_dl_dtheta", l, theta, l0, P), **tol)
    np.testing.assert_allclose(-derivative(lambda x: G(l, x), theta, dth),
                               engine(model, "d2F_dtheta2", l, theta, l0, P), **tol)


def test_the_papers_chain_springs_at_rest_length():
    """At l = l0 the hencky spring's tension is −β(θ − θ0) and U = C0(θ − θ0)."""
    one = np.ones(3)
    P = {"c": 100 * one, "beta": 0.2 * one, "C0": 5 * one, "theta0": 300 * one}
    theta = np.array([800.0, 1200.0, 400.0])
    eta = engine("hencky", "entropy", one, theta, one, P)
    np.testing.assert_allclose(engine("hencky", "tension", one, theta, one, P), -0.2 * (theta - 300), rtol=1e-14)
    np.testing.assert_allclose(engine("hencky", "internal_energy", one, eta, one, P), 5 * (theta - 300), rtol=1e-13)


finite = dict(allow_nan=False, allow_infinity=False)


@settings(max_examples=200, deadline=None)
@given(
    stretch=st.floats(-3.0, 3.0, **finite),
    l0=st.floats(1e-3, 1e3, **finite),
    log_theta=st.floats(-5.0, 5.0, **finite),
    theta0=st.floats(1.0, 1e4, **finite),
    c=st.floats(1e-2, 1e4, **finite),
    beta=st.floats(-10.0, 10.0, **finite),
    C0=st.floats(1e-2, 1e3, **finite),
)
def test_hencky_temperature_is_positive_and_inverts_entropy(stretch, l0, log_theta, theta0, c, beta, C0):
    """Over a wide range of states and parameters (strains ±3, θ/θ0 from e⁻⁵ to e⁵)."""
    one = np.ones(1)
    P = {"c": c * one, "beta": beta * one, "C0": C0 * one, "theta0": theta0 * one}
    l = l0 * np.exp(stretch) * one
    theta = theta0 * np.exp(log_theta) * one
    eta = engine("hencky", "entropy", l, theta, l0 * one, P)
    theta_back = engine("hencky", "temperature", l, eta, l0 * one, P)
    assert theta_back[0] > 0
    # η = β L + C0 ln(θ/θ0): its rounding is ε·(|βL| + |C0 ln θ/θ0|), amplified by θ/C0 in θ
    slack = 4e-16 * (abs(beta * stretch) + abs(C0 * log_theta) + C0) / C0
    assert theta_back[0] == pytest.approx(theta[0], rel=max(1e-13, 4 * slack))


@settings(max_examples=200, deadline=None)
@given(
    d=st.floats(-0.9, 3.0, **finite),
    theta_ratio=st.floats(0.01, 10.0, **finite),
    theta0=st.floats(1.0, 1e4, **finite),
    beta=st.floats(-10.0, 10.0, **finite),
    C0=st.floats(1e-2, 1e3, **finite),
    eta0=st.floats(-100.0, 100.0, **finite),
)
def test_quadratic_temperature_inverts_entropy(d, theta_ratio, theta0, beta, C0, eta0):
    one = np.ones(1)
    P = {"E": one, "beta": beta * one, "C0": C0 * one, "theta0": theta0 * one, "eta0": eta0 * one}
    l = (1.0 + d) * one
    theta = theta0 * theta_ratio * one
    eta = engine("quadratic", "entropy", l, theta, one, P)
    theta_back = engine("quadratic", "temperature", l, eta, one, P)
    # cancellation in η − η0 − β d: rounding of the largest term, scaled by θ0/C0
    slack = 4e-16 * theta0 / C0 * (abs(eta) + abs(eta0) + abs(beta * d) + C0)[0]
    assert abs(theta_back[0] - theta[0]) <= max(1e-12 * theta[0], 4 * slack)
