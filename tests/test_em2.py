"""EM2, the energy–momentum integrator (docs/theory.md §3): the models' closed-form discrete gradients
against 60-digit arithmetic, the generic one's two forms agreeing at their switch, exact Jacobian,
energy, momenta and entropy kept exactly, order 2, and no stability limit (a stiff net far above
the explicit step, where the explicit integrators are refused or stopped)."""

import dataclasses
import math
import warnings

import numpy as np
import pytest

import thermonet as tn
from numba import njit

from thermonet.implicit.em2 import kernels as em2_kernels
from thermonet.implicit.core.schemes import implicit_kernels
from thermonet.stability import stable_step
from thermonet.step_policy import UnstableStepError, check_step

#: Newton to its round-off floor: the residual enters the energy and angular momentum balances
TIGHT = dict(tolerance=1e-15, rtol=1e-12)


def relative_drift(series) -> float:
    s = np.asarray(series, dtype=float)
    return float(np.max(np.abs(s - s[0])) / np.max(np.abs(s[0])))


def vector_drift(d, names) -> float:
    v = np.column_stack([getattr(d, n) for n in names])
    return float(np.max(np.linalg.norm(v - v[0], axis=1)) / max(np.linalg.norm(v[0]), 1e-300))


def test_em2_is_registered():
    assert "em2" in tn.available_integrators()
    integ = tn.get_integrator("em2")
    assert integ.order == 2 and not integ.explicit and math.isinf(integ.stability_interval)


# ---------------------------------------------------------------------------------------------
# the discrete gradient of one spring


HENCKY = dict(c=100.0, beta=2.0, C0=1.0, theta0=300.0)
QUADRATIC = dict(E=100.0, beta=0.2, C0=5.0, theta0=300.0, eta0=0.0)
MODELS = [("hencky", HENCKY), ("quadratic", QUADRATIC)]
#: "hencky" without its energy_quotient: EM2's generic discrete gradient (the quotient of two U
#: values, the Gauss–Lobatto rule within SWITCH), what a user's model without one runs on
GENERIC = dataclasses.replace(tn.get_model("hencky"), name="hencky_generic", energy_quotient=None)
PARAMETERS = dict(MODELS, hencky_generic=HENCKY)


def get_model(name):
    return GENERIC if name == "hencky_generic" else tn.get_model(name)


def spring_functions(model_name, params):
    model = get_model(model_name)
    P = model.parameter_array(params, 1)
    kernels = implicit_kernels(model, "em2")
    return model, P, kernels


def internal_energy_60_digits(model_name, params):
    """U(l, η) of the model in mpmath (rest length 1)."""
    import mpmath as mp

    if model_name == "quadratic":
        E, b, cv, th0, eta0 = (mp.mpf(params[k]) for k in ("E", "beta", "C0", "theta0", "eta0"))

        def U(l, eta):
            d = l - 1
            r = eta - eta0 - b * d
            return E / 2 * d * d + th0 / (2 * cv) * r * r + eta * th0
    else:
        c, b, cv, th0 = (mp.mpf(params[k]) for k in ("c", "beta", "C0", "theta0"))

        def U(l, eta):
            L = mp.log(l)
            return c / 2 * L * L + b * th0 * L + cv * (th0 * mp.exp((eta - b * L) / cv) - th0)
    return U


@pytest.mark.parametrize("model_name, params", [("hencky", HENCKY), ("hencky", dict(c=100.0, beta=0.2, C0=5.0)),
                                                 ("quadratic", QUADRATIC)])
def test_closed_form_energy_quotients_against_60_digit_arithmetic(model_name, params):
    """Model.energy_quotient: Q = ΔU/δ and ∂Q/∂l¹ within a few ulps of the tension's terms for
    every l¹, from l¹ = l (Q = T, ∂Q/∂l¹ = half the adiabatic stiffness) through l¹ − l of one
    ulp, 1e-8 l, the generic form's switch, to l¹ = 3 l and l/3 (the quotient of two U values
    loses all digits as l¹ → l: measured 2e-3 relative at l¹ − l = 1e-12 l)."""
    import mpmath as mp

    mp.mp.dps = 60
    model = tn.get_model(model_name)
    P = model.parameter_array(params, 1)
    quotient = model.energy_quotient

    @njit(error_model="numpy")
    def closed_form(l, l1, eta, theta, T, out):
        for i in range(l.shape[0]):
            out[0, i], out[1, i] = quotient(l[i], l1[i], eta[i], theta[i], T[i], 1.0, P, 0)

    rng = np.random.default_rng(5)
    n = 300
    l = rng.uniform(0.4, 2.5, n)
    rel = np.concatenate([[0.0, 2.2e-16, -2.2e-16, 1e-8, -1e-8, 0.03, -0.03, 2.0, -2.0 / 3.0],
                          np.ldexp(rng.uniform(-1.0, 1.0, n - 9), rng.integers(-52, 0, n - 9))])
    l1 = l * (1.0 + rel)
    theta = rng.uniform(150.0, 900.0, n)
    eta = np.array([model.entropy(a, t, 1.0, P, 0) for a, t in zip(l, theta)])
    T = np.array([model.tension(a, t, 1.0, P, 0) for a, t in zip(l, theta)])
    out = np.empty((2, n))
    closed_form(l, l1, eta, theta, T, out)
    U = internal_energy_60_digits(model_name, {**model.defaults, **params})
    worst = np.zeros(2)
    for i in range(n):
        a, b, et = mp.mpf(l[i]), mp.mpf(l1[i]), mp.mpf(eta[i])
        if a == b:
            Q, dQ = mp.diff(lambda x: U(x, et), a), mp.diff(lambda x: U(x, et), a, 2) / 2
        else:
            Q = (U(b, et) - U(a, et)) / (b - a)
            dQ = mp.diff(lambda x: (U(x, et) - U(a, et)) / (x - a), b)
        # the size of the terms Q and ∂Q/∂l¹ sum (their rounding's scale): the tension's, the
        # stiffness' and, in ∂Q/∂l¹, the tension over the length
        F_lt = model.d2F_dl_dtheta(l[i], theta[i], 1.0, P, 0)
        F_ll = model.d2F_dl2(l[i], theta[i], 1.0, P, 0)
        scale = abs(T[i]) + abs(F_lt * theta[i]) + abs(F_ll) * l[i]
        stiffness = abs(T[i]) / l[i] + abs(F_ll) + abs(F_lt**2 / model.d2F_dtheta2(l[i], theta[i], 1.0, P, 0))
        worst = np.maximum(worst, [abs(out[0, i] - float(Q)) / scale, abs(out[1, i] - float(dQ)) / stiffness])
    eps = np.finfo(float).eps
    # measured: 1.2 and 3.5 ulps (hencky, β = 2, C0 = 1), 1.0 and 2.4 (β = 0.2, C0 = 5), 0.5 and 0 (quadratic)
    assert worst[0] <= 8 * eps and worst[1] <= 8 * eps, worst / eps


@pytest.mark.parametrize("model_name, params", MODELS)
def test_the_two_forms_of_the_discrete_gradient_agree_at_the_switch(model_name, params):
    """At |l¹ − l⁰| = SWITCH l̄ the quotient ΔU/δ (its rounding ≈ ε|U|/δ) and the Gauss–Lobatto
    rule (its error ≈ 7e-10 δ⁸ T⁽⁸⁾) give the same Q and dQ/dl¹; s is continuous across."""
    model, P, k = spring_functions(model_name, params)
    th = np.array([200.0, 300.0, 900.0])
    for l in (0.4, 1.0, 2.5):
        for theta in th:
            eta = model.entropy(l, theta, 1.0, P, 0)
            U0 = model.internal_energy(l, eta, 1.0, P, 0)
            T0 = model.tension(l, theta, 1.0, P, 0)
            for sign in (1.0, -1.0):
                # δ = ±SWITCH l̄: l1 − l = r (l + l1)/2
                r = sign * em2_kernels.SWITCH
                l1 = l * (1 + r / 2) / (1 - r / 2)
                T1 = model.tension(l1, model.temperature(l1, eta, 1.0, P, 0), 1.0, P, 0)
                Qd, dQd = k.direct(l, l1, eta, 1.0, P, 0, U0, T1)
                Qq, dQq = k.quadrature(l, l1, eta, 1.0, P, 0, T0, T1)
                scale = abs(Qd) + abs(U0) / l + abs(T0)
                assert abs(Qd - Qq) <= 2e-13 * scale, (l, theta, Qd, Qq)
                assert abs(dQd - dQq) <= 1e-9 * (abs(dQq) + scale / l), (l, theta, dQd, dQq)
                # s just inside and just outside the switch: no jump beyond its slope times the distance
                la, lb = l + (1 - 1e-9) * (l1 - l), l + (1 + 1e-9) * (l1 - l)
                below, ds = k.slope(l, la, eta, 1.0, P, 0, U0, T0)[:2]
                above = k.slope(l, lb, eta, 1.0, P, 0, U0, T0)[0]
                assert abs(above - below - ds * (lb - la)) <= 2e-13 * scale / l


@pytest.mark.parametrize("model_name, params", MODELS + [("hencky_generic", HENCKY)])
def test_the_discrete_gradient_at_vanishing_length_change(model_name, params):
    """l¹ → l⁰: s → T(l̄)/l̄ with no cancellation (the quotient itself loses all digits there)."""
    model, P, k = spring_functions(model_name, params)
    l, theta = 1.3, 700.0
    eta = model.entropy(l, theta, 1.0, P, 0)
    U0 = model.internal_energy(l, eta, 1.0, P, 0)
    T0 = model.tension(l, theta, 1.0, P, 0)
    s, ds, th1 = k.slope(l, l, eta, 1.0, P, 0, U0, T0)
    assert s == pytest.approx(T0 / l, rel=1e-14) and th1 == pytest.approx(theta, rel=1e-14)
    k_ad = ds * l + 0.5 * s  # ds/dl¹ = (dQ/dl¹ − s/2)/l̄ and dQ/dl¹ → k/2 as l¹ → l
    F_lt = model.d2F_dl_dtheta(l, theta, 1.0, P, 0)
    stiffness = model.d2F_dl2(l, theta, 1.0, P, 0) - F_lt**2 / model.d2F_dtheta2(l, theta, 1.0, P, 0)
    assert 2 * k_ad == pytest.approx(stiffness, rel=1e-12)
    l1 = l * (1 + 1e-10)
    Tm = model.tension(0.5 * (l + l1), model.temperature(0.5 * (l + l1), eta, 1.0, P, 0), 1.0, P, 0)
    assert k.slope(l, l1, eta, 1.0, P, 0, U0, T0)[0] == pytest.approx(Tm / (0.5 * (l + l1)), rel=1e-14)


# ---------------------------------------------------------------------------------------------
# the Newton step


def random_simulation(model_name, gravity, seed=3, h=0.05, **options):
    """A jittered 3×2×2 lattice with face diagonals, one anchored node, random masses, pre-stress,
    temperatures and momenta, optionally gravity."""
    rng = np.random.default_rng(seed)
    base = tn.lattice((3, 2, 2), neighbours=18, jitter=0.2, seed=seed)
    anchored = np.zeros(base.n_nodes, dtype=bool)
    anchored[5] = True
    net = tn.Net(base.positions, base.edges, rng.uniform(0.5, 2.0, base.n_nodes), anchored,
                 rest_lengths=base.lengths() * rng.uniform(0.8, 1.2, base.n_springs))
    momenta = rng.normal(0.0, 3.0, (net.n_nodes, 3))
    momenta[anchored] = 0.0
    params = PARAMETERS[model_name]
    return tn.Simulation(net, model=get_model(model_name), parameters=params, temperatures=rng.uniform(250.0, 400.0, net.n_springs),
                         momenta=momenta, integrator="em2", h=h, gravity=[0.0, 0.0, -9.81] if gravity else None,
                         integrator_options=options, stability_guard="off", energy_tolerance=None)


def residual_at(stepper, u):
    status, spring = stepper.residual(u)
    assert status == 0
    return stepper.R.copy()


CLOSED_AND_GENERIC = [("hencky", True), ("quadratic", False), ("hencky_generic", True)]


@pytest.mark.parametrize("model_name, gravity", CLOSED_AND_GENERIC)
def test_jacobian_matches_finite_differences(model_name, gravity):
    sim = random_simulation(model_name, gravity)
    st, s = sim.stepper, sim._state
    st.begin(s.positions, s.momenta, s.entropy, sim.h)
    st.predict(st.u)
    u = st.u + np.random.default_rng(0).normal(0.0, 0.03, st.u.shape)  # away from the solution
    residual_at(st, u)
    change = np.abs(st.work.len1 - st.work.start.len0) / (0.5 * (st.work.len1 + st.work.start.len0))
    # both forms of the generic discrete gradient are in play, none within the differences' reach
    # of the switch
    assert (change > em2_kernels.SWITCH).any() and (change < em2_kernels.SWITCH).any()
    assert np.abs(change - em2_kernels.SWITCH).min() > 1e-4
    st.jacobian(st.data)
    J = st.pattern.matrix(st.data.copy()).toarray()
    eps = 1e-6
    J_fd = np.empty_like(J)
    for j in range(len(u)):
        up, um = u.copy(), u.copy()
        up[j] += eps
        um[j] -= eps
        J_fd[:, j] = (residual_at(st, up) - residual_at(st, um)) / (2 * eps)
    coupling = J.copy()
    for kb in range(st.pattern.n_free):
        coupling[3 * kb:3 * kb + 3, 3 * kb:3 * kb + 3] = 0.0
    assert np.abs(coupling).max() > 1e-2 * np.abs(J).max()
    assert np.abs(J - J_fd).max() <= 1e-6 * np.abs(J).max()


@pytest.mark.parametrize("model_name, gravity", CLOSED_AND_GENERIC)
def test_energy_kept_exactly_with_anchors_and_gravity(model_name, gravity):
    sim = random_simulation(model_name, gravity, h=0.02, **TIGHT)
    eta0 = sim.state.entropy.copy()
    d = sim.run(steps=300, diagnostics_every=30)
    # measured: 1.2e-15 (hencky, gravity), 9.9e-16 (quadratic), 8.1e-16 (hencky without its closed form)
    assert relative_drift(d.energy) <= 1e-13
    assert np.array_equal(sim.state.entropy, eta0)


def test_the_closed_form_and_the_generic_discrete_gradient_make_the_same_steps():
    """hencky's energy_quotient against the generic forms (quotient and Gauss–Lobatto rule) on the
    same net: the same trajectory to round-off (differences of a few ulps per step, grown by
    the motion), both solved to the same tolerance."""
    runs = []
    for name in ("hencky", "hencky_generic"):
        sim = random_simulation(name, True, h=0.02, **TIGHT)
        sim.run(steps=50, diagnostics_every=10)
        runs.append(sim)
    closed, generic = runs
    change = np.abs(closed.state.positions - generic.state.positions).max()
    # measured: 5.8e-15 in positions (of size up to 4.5), 1.8e-14 relative in momenta
    assert change <= 1e-12
    assert np.abs(closed.state.momenta - generic.state.momenta).max() <= 1e-12 * np.abs(closed.state.momenta).max()


def test_conservation_over_1e5_steps_on_the_chain():
    """The paper's chain, h = 0.01: energy, angular momentum (node 0 is anchored at the origin,
    so L about it is conserved) and every spring's entropy."""
    sim = tn.chain_simulation("em2", h=0.01, integrator_options=TIGHT)
    eta0 = sim.state.entropy.copy()
    d = sim.run(steps=100_000, diagnostics_every=10_000)
    assert sim.stepper.summary()["linear_solver"] == "compiled, dense"  # the automatic choice (9 unknowns)
    # measured: energy 7.4e-15, L 3.5e-13 (1.84 iterations per step)
    assert relative_drift(d.energy) <= 1e-13
    assert vector_drift(d, ("Lx", "Ly", "Lz")) <= 1e-12
    assert np.array_equal(sim.state.entropy, eta0)


def test_conservation_on_a_jittered_lattice():
    """No anchors, random momenta of zero sum: energy, linear and angular momentum, entropy."""
    net = tn.lattice((3, 2, 2), neighbours=18, jitter=0.2, seed=2)
    rng = np.random.default_rng(1)
    momenta = rng.normal(0.0, 2.0, (net.n_nodes, 3))
    sim = tn.Simulation(net, parameters=dict(c=100.0, beta=0.5), temperatures=rng.uniform(250, 450, net.n_springs),
                        momenta=momenta, integrator="em2", h=0.02, integrator_options=TIGHT)
    eta0 = sim.state.entropy.copy()
    d = sim.run(steps=1000, diagnostics_every=100)
    # measured: energy 1.3e-15, p 2.5e-15, L 3.8e-15
    assert relative_drift(d.energy) <= 1e-13
    assert vector_drift(d, ("px", "py", "pz")) <= 1e-12
    assert vector_drift(d, ("Lx", "Ly", "Lz")) <= 1e-12
    assert np.array_equal(sim.state.entropy, eta0)


# ---------------------------------------------------------------------------------------------
# order 2 against DOP853 (as tests/test_implicit_orders.py)

STEPS = np.array([0.1 * 2.0**-i for i in range(3, 8)])


def test_order_two_on_the_chain(chain_reference):
    x, p, theta = chain_reference
    errs = []
    for h in STEPS:
        sim = tn.chain_simulation("em2", h=h)
        sim.run(t_end=1.0, diagnostics_every=10**9)
        s = sim.state
        errs.append((np.abs(s.positions - x).max(), np.abs(s.momenta - p).max(), np.abs(sim.temperatures() - theta).max()))
    errs = np.array(errs)
    assert errs.min() > 1e-9
    for k, quantity in enumerate(("positions", "momenta", "temperatures")):
        slope = np.polyfit(np.log(STEPS), np.log(errs[:, k]), 1)[0]
        assert abs(slope - 2) <= 0.15, f"slope {slope:.3f} in {quantity}"


# ---------------------------------------------------------------------------------------------
# no stability limit


def stiff_net(integrator, factor, **kw):
    """Springs of c = 1e6 (every fourth) among springs of c = 1e2 on a jittered 18-neighbour
    2×2×2 lattice (27 nodes, 126 springs), hot (thermal stress), random momenta of zero sum; h =
    ``factor`` × CO2's stable step."""
    net = tn.lattice((2, 2, 2), neighbours=18, jitter=0.1, seed=1)
    c = np.full(net.n_springs, 1e2)
    c[::4] = 1e6
    momenta = np.random.default_rng(0).normal(size=(net.n_nodes, 3))
    momenta -= momenta.mean(axis=0)

    def make(name, h, **options):
        return tn.Simulation(net, parameters=dict(c=c, beta=0.2), temperatures=400.0, momenta=momenta,
                             integrator=name, h=h, **options)

    h = factor * stable_step(make("co2", 1.0))["h_max"]
    return make(integrator, h, **kw), net.rest_lengths


@pytest.mark.parametrize("factor", [10, 100])
def test_a_stiff_net_far_above_the_explicit_limit(factor):
    sim, rest = stiff_net("em2", factor, integrator_options=dict(TIGHT, retry=3))
    assert check_step(sim).verdict == "ok"  # EM2 is never refused
    stretches = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # retried steps (100×) are reported, not errors
        d = sim.run(steps=100, diagnostics_every=10,
                    observers=[(1, lambda s: stretches.append((s.lengths() / rest).min()))])
    assert sim.step == 100
    # measured 10×: energy 1.0e-15, stretch ≥ 0.700, no retries; 100×: 8.1e-15, ≥ 0.699, 19 of 100 steps
    # retried (as 2 substeps)
    assert relative_drift(d.energy) <= 1e-13
    assert relative_drift(d.entropy) == 0.0
    assert min(stretches) > 0.5
    assert np.isfinite(sim.state.positions).all() and np.abs(sim.state.positions).max() < 10.0
    if factor == 10:
        assert sim.stepper.summary()["retried_steps"] == 0
    for name in ("co2", "gtr-1/2", "ho4"):
        explicit = stiff_net(name, factor)[0]
        with pytest.raises(UnstableStepError, match="em2"):
            check_step(explicit)
        # forced past the policy: the run-time guards stop it
        with pytest.raises(tn.SimulationError):
            explicit.run(steps=100, diagnostics_every=10)


def test_matrix_free_product_is_the_assembled_jacobian():
    """The matrix-free sweep's r = R − J du (the large nets' solver) against the assembled J."""
    sim = random_simulation("hencky", True)
    st, s = sim.stepper, sim._state
    st.begin(s.positions, s.momenta, s.entropy, sim.h)
    st.predict(st.u)
    residual_at(st, st.u + np.random.default_rng(1).normal(0.0, 0.03, st.u.shape))
    st.jacobian(st.data)
    st.linearize()
    J = st.pattern.matrix(st.data.copy()).toarray()
    du = np.random.default_rng(2).normal(size=st.u.shape)
    rhs = np.random.default_rng(3).normal(size=st.u.shape)
    r = np.empty_like(du)
    st.sweep(du.copy(), rhs, r, False)
    assert np.abs(r - (rhs - J @ du)).max() <= 1e-12 * np.abs(J @ du).max()


# ---------------------------------------------------------------------------------------------
# what the messages recommend


def test_messages_recommend_em2_above_the_limit_and_never_refuse_it():
    from thermonet.blowup import remedy
    from thermonet.cli.info import _stable_step

    co2, gtr, em2 = (tn.get_integrator(n) for n in ("co2", "gtr-1/2", "em2"))
    for integ in (co2, gtr):
        text = remedy(integ, 0.01)
        assert "smaller h than 0.01" in text and "em2, which has none" in text and "ho4" not in text
    assert "gtr-1/2 has a stability limit too" in remedy(gtr, 0.01)
    assert "em2" not in remedy(co2, 0.01).split("em2", 1)[1]  # named once
    assert "smaller h" in remedy(em2, 0.01) and "retry" in remedy(em2, 0.01)

    # the blow-up of an explicit run names em2 (one linear spring just above CO2's limit)
    net = tn.Net([[0, 0, 0], [1, 0, 0]], [[0, 1]], masses=[1.0, 2.0], anchored=[0], rest_lengths=[1.0])
    sim = tn.Simulation(net, model="quadratic", parameters=dict(E=100.0, beta=0.0), momenta=[[0, 0, 0], [0.01, 0, 0]],
                        h=1.05 * 2.0 / np.sqrt(50.0), stability_guard="off", energy_tolerance=None)
    with pytest.raises(tn.SimulationError, match="the integrator em2, which has none"):
        sim.run(steps=100000, diagnostics_every=10**9)

    # EM2 far above the limit: the policy says ok, the guard is off, info says there is no limit
    sim = tn.Simulation(net, model="quadratic", parameters=dict(E=100.0, beta=0.0), momenta=[[0, 0, 0], [1.0, 0, 0]],
                        integrator="em2", h=100.0 / np.sqrt(50.0), integrator_options=TIGHT)
    verdict = check_step(sim)
    assert verdict.verdict == "ok" and math.isinf(verdict.h_max) and not sim.stability_guard.active
    assert "no stability limit" in _stable_step(sim, "initial state")
    d = sim.run(steps=200, diagnostics_every=20)
    # at h ω = 100 the residual's scale is the step's force term, ~ h ω/2 × |p|: measured 8.9e-13
    # (the default tolerance 1e-12: 1.1e-12)
    assert relative_drift(d.energy) <= 1e-12
