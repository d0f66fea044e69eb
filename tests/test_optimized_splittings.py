"""The optimized symmetric splittings — Blanes & Moan's RKN tables (``bm4``, ``bm6``, ``bm6a``) and
Omelyan, Mryglod & Folk's 4th-order velocity version (``omf4``): their tables, their measured orders
on the paper's chain, exact entropy, and the CUDA backend under the simulator.

Orders are log-log slopes of the error at t = 1 against DOP853 at rtol = atol = 1e-13 (the
``chain_reference`` fixture; good to ≈ 5e-14 in positions, ≈ 2e-13 in momenta). These methods'
errors are small: BM4 at h = 0.1·2⁻⁷ is 7e-12, BM6 and BM6A at h = 0.1·2⁻⁵ are 1.2e-12 and
4.9e-13, so the fitted ranges stop there (the next halving meets the reference's floor), and
start where the local slopes have settled (BM4's are 6.7, 4.5 at i = 2, 3; BM6's 6.7 at i = 2;
BM6A's 8.6, 4.4 at i = 1, 2; OMF4's 4.9, 3.9 at i = 2, 3, fitted over BM4's range, where its error
falls from 2.4e-7 to 6e-11). Positions and momenta give the order within ``TOLERANCE``. Temperatures converge *faster* than the order over every
range above the floor (BM4: local slopes 6.4, 6.0, 5.6, 4.8 from i = 2; the leading h⁴ term of
θ's error is still smaller than the next one there), so for them the test asserts a slope of at
least the order.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import thermonet as tn
from thermonet.explicit.splitting import BM4, BM6, BM6A, CO4, CO6, OMF4

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
T_END = 1.0
TOLERANCE = 0.15

# integrator -> (order, force evaluations per step, range of i in h = 0.1·2⁻ⁱ for the fit, the
# smallest error allowed in the fit: ≥ 5x the reference's error, except BM6A, whose smallest
# (4.9e-13 at i = 5, in both) is 10x the reference's error in positions but 2.4x in momenta)
CASES = {"bm4": (4, 6, range(4, 8), 1e-12), "bm6": (6, 11, range(3, 6), 1e-12),
         "bm6a": (6, 14, range(3, 6), 4e-13), "omf4": (4, 5, range(4, 8), 1e-12)}


@pytest.mark.parametrize("integrator", [BM4, BM6, BM6A, OMF4])
def test_tables_are_symmetric_and_consistent(integrator):
    k, d = np.array(integrator.kicks), np.array(integrator.drifts)
    assert len(k) == len(d) + 1
    assert abs(k.sum() - 1.0) < 1e-15 and abs(d.sum() - 1.0) < 1e-15
    np.testing.assert_array_equal(k, k[::-1])
    np.testing.assert_array_equal(d, d[::-1])
    # BM4, BM6, OMF4 start with a kick (first and last share one force evaluation in a long run);
    # BM6A with a drift
    assert (k[0] == 0.0) == (integrator.name == "bm6a")
    assert tn.get_integrator(integrator.name) is integrator
    assert integrator.force_evaluations == CASES[integrator.name][1]


def test_tables_are_the_papers():
    """Spot values of Blanes & Moan (2002), Table 3, and the dependent coefficients they imply."""
    assert BM4.kicks[:3] == (0.0829844064174052, 0.396309801498368, -0.0390563049223486)
    assert BM4.drifts[:2] == (0.245298957184271, 0.604872665711080)
    assert BM4.kicks[3] == pytest.approx(0.1195241940131508, abs=1e-15)
    assert BM4.drifts[2] == pytest.approx(-0.350171622895351, abs=1e-15)
    assert BM6.kicks[5] == pytest.approx(0.2366699247869311, abs=1e-15)
    assert BM6.drifts[5] == pytest.approx(0.20477705429147, abs=1e-14)
    assert BM6A.kicks[7] == pytest.approx(-0.19641146648645423, abs=1e-15)
    assert BM6A.drifts[7] == pytest.approx(0.2073050690568954, abs=1e-15)
    # same number of force evaluations as a classical method's stages: 6 and 11, versus CO4's 3, CO6's 7
    assert (CO4.force_evaluations, CO6.force_evaluations) == (3, 7)


def test_omf4_table_is_the_papers():
    """Omelyan, Mryglod & Folk (2003), eq. (63) with (71): B(ϑ) A(ρ) B(λ) A(θ) B(½ − λ − ϑ)
    A(1 − 2θ − 2ρ) …, B the kick."""
    rho, theta, vartheta, lam = 0.2539785108410595, -0.03230286765269967, 0.08398315262876693, 0.6822365335719091
    assert OMF4.kicks[:2] == (vartheta, lam) and OMF4.drifts[:2] == (rho, theta)
    assert OMF4.kicks[2] == pytest.approx(0.5 - lam - vartheta, abs=1e-16)
    assert OMF4.drifts[2] == pytest.approx(1.0 - 2.0 * (theta + rho), abs=1e-16)


def _errors(name, h, reference):
    sim = tn.chain_simulation(name, h=h)
    sim.run(t_end=T_END, diagnostics_every=10**9)
    assert sim.time == pytest.approx(T_END, abs=1e-12)
    x, p, theta = reference
    return (np.abs(sim.state.positions - x).max(), np.abs(sim.state.momenta - p).max(),
            np.abs(sim.temperatures() - theta).max())


@pytest.mark.parametrize("name", list(CASES))
def test_order_on_the_chain(name, chain_reference):
    order, _, exponents, smallest = CASES[name]
    assert tn.get_integrator(name).order == order
    h = np.array([0.1 * 2.0**-i for i in exponents])
    errs = np.array([_errors(name, hi, chain_reference) for hi in h])
    assert errs[:, :2].min() > smallest
    slopes = [np.polyfit(np.log(h), np.log(errs[:, k]), 1)[0] for k in range(3)]
    for k, quantity in enumerate(("positions", "momenta")):
        assert abs(slopes[k] - order) <= TOLERANCE, f"{name}: slope {slopes[k]:.3f} in {quantity}, expected {order}"
    assert slopes[2] >= order - TOLERANCE, f"{name}: slope {slopes[2]:.3f} in temperatures, expected ≥ {order}"


@pytest.mark.parametrize("name", ["bm4", "bm6", "omf4"])
def test_more_accurate_than_the_triple_jumps_at_equal_force_evaluations(name, chain_reference):
    """At equal force evaluations per unit time (BM4 at h = 0.02 and OMF4 at 1/60 against CO4 at
    0.01; BM6 at h = 1/40 against CO6 at 1/63) the optimized method's error on the chain is smaller."""
    other, h_new, h_old = {"bm4": ("co4", 0.02, 0.01), "bm6": ("co6", 1.0 / 40, 1.0 / 63),
                           "omf4": ("co4", 1.0 / 60, 0.01)}[name]
    new = tn.get_integrator(name).force_evaluations / h_new
    old = tn.get_integrator(other).force_evaluations / h_old
    assert new == pytest.approx(old, rel=0.02)
    assert _errors(name, h_new, chain_reference)[0] < 0.2 * _errors(other, h_old, chain_reference)[0]


@pytest.mark.parametrize("name", ["bm4", "bm6", "bm6a", "omf4"])
@pytest.mark.parametrize("parallel", [False, True])
def test_entropy_exact_and_momenta_conserved(name, parallel):
    net = tn.lattice((2, 2, 2), neighbours=18, jitter=0.1, seed=3)
    rng = np.random.default_rng(3)
    sim = tn.Simulation(net, temperatures=250.0 + 100.0 * rng.random(net.n_springs),
                        velocities=rng.normal(0.0, 0.5, (net.n_nodes, 3)), integrator=name, h=2e-3,
                        parallel=parallel, threads=2 if parallel else 1)
    eta0 = sim.state.entropy.copy()
    p0 = sim.state.momenta.sum(axis=0)
    sim.run(steps=200, diagnostics_every=50)
    np.testing.assert_array_equal(sim.state.entropy, eta0)
    scale = np.abs(sim.state.momenta).max()
    np.testing.assert_allclose(sim.state.momenta.sum(axis=0), p0, rtol=0, atol=1e-13 * scale * net.n_nodes)
    L = np.array([sim.diagnostics.column(c) for c in ("Lx", "Ly", "Lz")])
    assert np.abs(L - L[:, :1]).max() <= 1e-12 * max(np.abs(L).max(), 1.0)
    E = sim.diagnostics.column("energy")
    assert np.abs(E - E[0]).max() < 1e-6 * abs(E[0])


_CUDA_SIM_SCRIPT = textwrap.dedent("""
    import sys
    import numpy as np
    sys.path[:0] = [sys.argv[1], sys.argv[1] + "/tests"]
    import thermonet as tn
    from cuda_sim_cases import free_net, quadratic_parameters
    from simulator_pace import pace
    pace()
    net, v, temps = free_net()
    out = {}
    for model in ("hencky", "quadratic"):
        params = quadratic_parameters() if model == "quadratic" else None
        for name in ("bm4", "bm6", "bm6a", "omf4"):
            for backend in ("cpu", "cuda"):
                sim = tn.Simulation(net, model=model, parameters=params, temperatures=temps, velocities=v,
                                    integrator=name, h=2e-3, backend=backend)
                key = f"{model}-{name}/{backend}"
                out[key + "/eta0"] = sim.state.entropy.copy()
                out[key + "/positions0"] = sim.state.positions.copy()
                sim.run(steps=3, diagnostics_every=3)
                s = sim.state
                out[key + "/positions"], out[key + "/momenta"] = s.positions, s.momenta
                out[key + "/phi"], out[key + "/eta"] = s.thermal_displacement, s.entropy
                out[key + "/energy"] = sim.diagnostics.column("energy")
    np.savez(sys.argv[2], **out)
""")


@pytest.fixture(scope="module")
def cuda_sim_runs(tmp_path_factory):
    if importlib.util.find_spec("numba_cuda") is None:
        pytest.skip("numba-cuda is not installed (pip install '.[cuda]')")
    path = str(tmp_path_factory.mktemp("cuda-bm") / "runs.npz")
    proc = subprocess.run([sys.executable, "-c", _CUDA_SIM_SCRIPT, ROOT, path],
                          env=dict(os.environ, NUMBA_ENABLE_CUDASIM="1"), capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    with np.load(path) as data:
        return dict(data)


@pytest.mark.parametrize("case", [f"{m}-{n}" for m in ("hencky", "quadratic") for n in ("bm4", "bm6", "bm6a", "omf4")])
def test_cuda_simulator_equals_cpu(cuda_sim_runs, case):
    runs = cuda_sim_runs
    cpu, gpu = f"{case}/cpu", f"{case}/cuda"
    assert not np.array_equal(runs[f"{gpu}/positions"], runs[f"{gpu}/positions0"])
    for field in ("positions", "momenta", "phi"):
        a, b = runs[f"{cpu}/{field}"], runs[f"{gpu}/{field}"]
        assert np.abs(a - b).max() <= 1e-13 * np.abs(a).max(), field
    np.testing.assert_allclose(runs[f"{gpu}/energy"], runs[f"{cpu}/energy"], rtol=1e-12, atol=0)
    # a kick never writes η: bit for bit on both backends
    np.testing.assert_array_equal(runs[f"{gpu}/eta"], runs[f"{gpu}/eta0"])
    np.testing.assert_array_equal(runs[f"{gpu}/eta"], runs[f"{cpu}/eta"])


@pytest.mark.parametrize("name,expected,above,steps", [("bm4", 3.1635, 1.0008, 2000), ("bm6", 3.1414, 1.0001, 20000),
                                                       ("bm6a", 3.1409, None, 20000), ("omf4", 3.1421, 1.005, 400)])
def test_stability_interval_is_the_measured_limit(name, expected, above, steps):
    """h·ω_max from the coefficients (the step matrix of a linear spring), checked by running a
    linear spring just below (energy bounded) and just above it (grows or stops). For these
    methods the limit is a narrow resonance band at hω ≈ π, where the step's rotation angle
    reaches π and the trace touches −2: from c to 1.0016 c for BM4 (largest eigenvalue modulus
    1.0024 at 1.0008 c), to 1.0003 c for BM6 (1.0004 at 1.0001 c) and to 1.0103 c for OMF4 (1.016
    at 1.005 c); beyond the band the linear step is stable again. So "just above" is inside the
    band (for BM6A: where the modulus is largest below 1.002 c); BM6, BM6A run longer to show the
    growth, OMF4 shorter (its amplitude grows 1.6 % per step and would reach the spring's length,
    where the motion stops being linear, after about 450 steps)."""
    from test_hard_cases import linear_spring_energy_growth

    from thermonet.stability import stability_interval

    c = stability_interval(tn.get_integrator(name))
    assert c == pytest.approx(expected, abs=1e-4)
    assert linear_spring_energy_growth(name, 0.99 * c, steps=steps) < 1.5
    if above is None:
        above = _widest_growth(name, c)
    grown = linear_spring_energy_growth(name, above * c, steps=steps)
    assert not np.isfinite(grown) or grown > 10.0


def _widest_growth(name, c):
    """The factor f in [1, 1.002] where the linear step's eigenvalue modulus at f·c is largest."""
    I = tn.get_integrator(name)

    def modulus(hw):
        A = np.eye(2)
        for k, d in zip(I.kicks[:-1], I.drifts):
            A = np.array([[1.0, d * hw], [0.0, 1.0]]) @ (np.array([[1.0, 0.0], [-k * hw, 1.0]]) @ A)
        A = np.array([[1.0, 0.0], [-I.kicks[-1] * hw, 1.0]]) @ A
        return np.abs(np.linalg.eigvals(A)).max()

    fs = np.linspace(1.0, 1.002, 201)
    return float(fs[np.argmax([modulus(f * c) for f in fs])])


@pytest.mark.parametrize("name", ["bm4", "bm6", "bm6a", "omf4"])
@pytest.mark.parametrize("case_name", ["chain", "lattice-quadratic"])
def test_kernel_step_matches_the_numpy_reference(name, case_name):
    """The fused kernel reading the table against :func:`thermonet.reference.splitting_step`
    (the NumPy reference's own kick and drift), to round-off, one step and then a chunk."""
    from test_kernels_vs_reference import CASES as REFERENCE_CASES
    from test_kernels_vs_reference import assert_round_off, start

    from thermonet import reference as ref

    integrator = tn.get_integrator(name)
    sim, rnet, s = start(REFERENCE_CASES[case_name](), name, 0.005)
    step = ref.splitting_step(integrator.kicks, integrator.drifts)
    for n_steps in (1, 4):
        sim.run(steps=n_steps, diagnostics_every=10**9)
        s = ref.run(rnet, s, step, 0.005, n_steps)
        got = sim.state
        assert_round_off(got.positions, s.x, f"{name} positions")
        assert_round_off(got.momenta, s.p, f"{name} momenta")
        assert_round_off(got.thermal_displacement, s.phi, f"{name} Φ")
        assert np.array_equal(got.entropy, s.eta)
