"""The per-spring thermal solves of the implicit integrators: the vectorized solve (a fixed
number of Newton corrections, used in the residual kernels' vectorized loop) agrees with the
scalar one (iterated to convergence) to round-off, flags what it cannot solve, and the residual
kernels' scalar fallback for flagged springs gives the same residual as a clean solve."""

import dataclasses

import numpy as np
import pytest

import thermonet as tn
from thermonet.implicit.core.schemes import implicit_kernels
from thermonet.models import get_model

PARAMS = {"hencky": dict(c=100.0, beta=2.0, C0=5.0, theta0=300.0),
          "quadratic": dict(E=100.0, beta=0.2, C0=5.0, theta0=300.0, eta0=0.1)}


def iterated(model):
    """The model without its closed-form HO4 solve (Newton corrections, as for any model)."""
    return dataclasses.replace(model, name=f"{model.name}_iterated", entropy_log_affine=False)


def spring_states(model_name, count=200, seed=0):
    model = get_model(model_name)
    rng = np.random.default_rng(seed)
    P = np.array([[PARAMS[model_name][k]] for k in model.parameters])
    l0 = 1.0
    la, lh, lb = (rng.uniform(0.9, 1.1, count) for _ in range(3))
    theta = rng.uniform(250.0, 600.0, count)
    entropy = np.array([model.entropy(l, t, l0, P, 0) for l, t in zip(la, theta)])
    return model, P, l0, la, lh, lb, entropy


@pytest.mark.parametrize("model_name", ["hencky", "hencky_iterated", "quadratic"])
def test_vectorized_ho4_solve_is_the_scalar_one(model_name):
    """hencky: the closed form against the scalar Newton solve."""
    model, P, l0, la, lh, lb, eta = spring_states(model_name.removesuffix("_iterated"))
    if model_name.endswith("_iterated"):
        model = iterated(model)
    k = implicit_kernels(model, "ho4")
    for i in range(len(la)):
        for guess, warm in ((0.0, False), (eta[i] + 1e-3, True)):
            a = np.array(k.thermal(la[i], lh[i], lb[i], eta[i], l0, P, 0, guess, warm))
            b = np.array(k.thermal_vector(la[i], lh[i], lb[i], eta[i], l0, P, 0, guess, warm))
            assert a[-1] == 1 and b[-1] == 1
            assert np.allclose(a[1:3], b[1:3], rtol=4e-15, atol=0.0), (a, b)  # θ⁰, θ¹
            assert np.allclose(a[3:7], b[3:7], rtol=1e-12, atol=1e-15 * np.abs(a[3:7]).max()), (a, b)


@pytest.mark.parametrize("model_name", ["hencky", "quadratic"])
@pytest.mark.parametrize("alpha", [0.5, 0.3])
def test_vectorized_gtr_solve_is_the_scalar_one(model_name, alpha):
    model, P, l0, la, lh, lb, eta = spring_states(model_name, seed=1)
    k = implicit_kernels(model, "gtr")
    for i in range(len(la)):
        solution = k.thermal(la[i], lb[i], eta[i], l0, P, 0, alpha, -1.0)[0]
        for guess in (-1.0, (1.0 + 1e-5) * solution):  # cold, warm (a Newton iterate's seed is closer)
            a = np.array(k.thermal(la[i], lb[i], eta[i], l0, P, 0, alpha, guess))
            b = np.array(k.thermal_vector(la[i], lb[i], eta[i], l0, P, 0, alpha, guess))
            assert a[-1] == 1 and b[-1] == 1
            assert abs(a[0] - b[0]) <= 4e-15 * a[0], (a, b)
            assert abs(a[1] - b[1]) <= 1e-12 * abs(a[1]) + 1e-300, (a, b)


def test_vectorized_solves_flag_a_start_they_cannot_finish():
    """From a guess whose first ln θ step exceeds the bound (20) two corrections cannot converge:
    the vectorized solve says so; the scalar one iterates on and finds the answer."""
    model, P, l0, la, lh, lb, eta = spring_states("hencky", count=5)
    k = implicit_kernels(iterated(model), "ho4")
    wild = eta[0] + 500.0  # ln θ off by 100
    assert k.thermal_vector(la[0], lh[0], lb[0], eta[0], l0, P, 0, wild, True)[-1] == 0
    assert k.thermal(la[0], lh[0], lb[0], eta[0], l0, P, 0, wild, True)[-1] == 1
    model, P, l0, la, lh, lb, eta = spring_states("hencky", count=5)
    k = implicit_kernels(model, "ho4")  # closed form: no seed, nothing to flag
    wild = eta[0] + 500.0  # ln θ off by 100
    exact = k.thermal_vector(la[0], lh[0], lb[0], eta[0], l0, P, 0, wild, True)
    assert exact == k.thermal_vector(la[0], lh[0], lb[0], eta[0], l0, P, 0, 0.0, False) and exact[-1] == 1
    g = implicit_kernels(model, "gtr")
    assert g.thermal_vector(la[0], lb[0], eta[0], l0, P, 0, 0.5, 1e-40)[-1] == 0
    assert g.thermal(la[0], lb[0], eta[0], l0, P, 0, 0.5, 1e-40)[-1] == 1


@pytest.mark.parametrize("integrator", ["ho4", "gtr-1/2"])
@pytest.mark.parametrize("parallel", [False, True])
def test_residual_falls_back_to_the_scalar_solve_for_flagged_springs(integrator, parallel):
    """Warm seeds spoiled for a third of the springs (across several blocks of 512) send those
    springs to the scalar fallback; the residual equals the one from a clean cold solve. (HO4
    with "hencky" solves in closed form, without seeds: the quadratic model here.)"""
    net = tn.lattice((8, 8, 8), jitter=0.1, seed=2)
    rng = np.random.default_rng(0)
    model = "quadratic" if integrator == "ho4" else "hencky"
    sim = tn.Simulation(net, model=model, parameters=PARAMS[model],
                        temperatures=rng.uniform(300.0, 600.0, net.n_springs),
                        momenta=rng.normal(0.0, 1.0, (net.n_nodes, 3)), integrator=integrator, h=0.01,
                        parallel=parallel, integrator_options=dict(linear_solver="matfree"))
    st, s = sim.stepper, sim._state
    if integrator == "ho4":  # (no local Jacobi step here: begin() need not compile one)
        st._subset_compiled = True
    assert net.n_springs > 3 * 512
    st.begin(s.positions, s.momenta, s.entropy, sim.h)
    st.predict(st.u)
    assert st.residual(st.u) == (0, -1)
    clean = st.R.copy()
    spoiled = rng.random(net.n_springs) < 1 / 3
    if integrator == "ho4":
        st.work.gs[spoiled] += 500.0
        assert not sim.model.entropy_log_affine
    else:
        st.work.theta[spoiled] = 1e-40
    st.warm = True
    assert st.residual(st.u) == (0, -1)
    assert np.abs(st.R - clean).max() <= 1e-12 * np.abs(st.Rabs).max()
    assert st.norms[0] == np.abs(st.R).max() and st.norms[1] == st.Rabs.max()


def test_closed_form_residual_from_the_start_kernel_is_the_iterated_one():
    """HO4 with "hencky" solves each spring's thermal equations in closed form from what the
    start kernel kept of the step's start (θ(l⁰, η), T and F_lθ at l⁰, the coefficient C), and
    takes the force at x⁰ as T(l⁰, θ(l⁰, η)) + F_lθ (θ⁰ − θ(l⁰, η)). The same model solved by
    Newton corrections from the lengths alone gives the same temperatures and residual to
    round-off, at the predictor and after a Newton iteration. (Serial kernels: the threaded ones
    give the same bits, test_threaded_kernels_give_the_serial_numbers, and compiling them for a
    second model would cost minutes of a cold run.)"""
    net = tn.lattice((8, 8, 8), jitter=0.1, seed=2)
    rng = np.random.default_rng(0)
    temperatures = rng.uniform(300.0, 600.0, net.n_springs)
    momenta = rng.normal(0.0, 1.0, (net.n_nodes, 3))
    out = []
    state = None
    for model in (get_model("hencky"), iterated(get_model("hencky"))):
        sim = tn.Simulation(net, model=model, parameters=PARAMS["hencky"], temperatures=temperatures,
                            momenta=momenta, integrator="ho4", h=0.01, parallel=False,
                            integrator_options=dict(linear_solver="matfree"))
        st = sim.stepper
        # (this test takes no local Jacobi step: begin() need not compile one, which with its
        # subset residual is half a minute of a cold run for the iterated model)
        st._subset_compiled = True
        assert st.kernels.keep_start == model.entropy_log_affine
        assert st.work.start.keep.shape == (4, net.n_springs if model.entropy_log_affine else 0)
        if state is None:  # strained and heated: θ⁰, θ¹ differ; both start from these bits
            sim.run(steps=3, diagnostics_every=10**9)
            state = sim._state
        st.work.start.history[0] = 0.0  # the series predictor for both (the second has no last step)
        st.begin(state.positions, state.momenta, state.entropy, sim.h)
        st.predict(st.u)
        rows = []
        for _ in range(2):
            assert st.residual(st.u) == (0, -1)
            rows.append([a.copy() for a in (st.R, st.Rabs, st.work.th0, st.work.th1)])
            st.linearize()
            st.u -= st.solver.solve(st.R, 1e-3 * st.norms[0])
        out.append(rows)
    for closed, newton in zip(*out):
        R, Rabs, th0, th1 = closed
        assert np.abs(R - newton[0]).max() <= 1e-14 * Rabs.max()
        assert np.allclose(th0, newton[2], rtol=1e-14, atol=0.0) and np.allclose(th1, newton[3], rtol=1e-14, atol=0.0)
        assert not np.array_equal(th0, th1)
