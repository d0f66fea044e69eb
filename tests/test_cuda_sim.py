"""The CUDA backend against the CPU backend.

Under Numba's CUDA simulator (no GPU needed): ``tests/cuda_sim_cases.py`` runs tiny nets on both
backends in a process of its own with ``NUMBA_ENABLE_CUDASIM=1`` (the variable must be set before
Numba is imported, so not in this process). Tolerances: the GPU path performs the CPU's
operations in the CPU's order per spring and per node, so states agree to round-off
(``STATE_RTOL`` of the quantity's scale); diagnostics are tree sums on the device and agree to
round-off of the sum; η is never written, so it is bit-exact. On a real GPU (tests marked
``gpu``, skipped without one) fused multiply-adds change the last bits of each step, so the
tolerance there is looser.

Without numba-cuda the simulator tests skip; the error paths run either way.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys

import numpy as np
import pytest

import thermonet as tn
from thermonet.explicit.cuda import gpu_available
from thermonet.errors import InputError

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HAVE_NUMBA_CUDA = importlib.util.find_spec("numba_cuda") is not None
needs_numba_cuda = pytest.mark.skipif(not HAVE_NUMBA_CUDA, reason="numba-cuda is not installed (pip install '.[cuda]')")

sys.path.insert(0, os.path.join(ROOT, "tests"))
from cuda_sim_cases import BLOWUPS, EXPLICIT  # noqa: E402

CASES = [f"{m}-{i}" for m in ("hencky", "quadratic") for i in EXPLICIT] + [
    "hencky-per-spring-co2", "user-model-co2", "thermal-off-co2", "hencky-co4-two-launch", "gravity-chain-f10",
    "push-co2", "push-co2-two-launch"]
FREE = [c for c in CASES if not c.startswith(("gravity", "push"))]  # no anchors, no external field
STATE_RTOL = 1e-13
DIAG_RTOL = 1e-12


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    if not HAVE_NUMBA_CUDA:
        pytest.skip("numba-cuda is not installed (pip install '.[cuda]')")
    path = str(tmp_path_factory.mktemp("cuda") / "cases.npz")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "tests", "cuda_sim_cases.py"), path],
                          env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    with np.load(path) as data:
        return dict(data)


def _close(a, b, rtol):
    scale = max(float(np.max(np.abs(a))), 1e-300)
    return float(np.max(np.abs(a - b))) <= rtol * scale


@pytest.mark.parametrize("case", CASES)
def test_state_equals_cpu_to_round_off(runs, case):
    cpu, gpu = f"{case}/cpu", f"{case}/cuda"
    assert not np.array_equal(runs[f"{gpu}/positions"], runs[f"{gpu}/positions0"])  # it moved
    for field in ("positions", "momenta", "phi"):
        if f"{cpu}/{field}" in runs:
            assert _close(runs[f"{cpu}/{field}"], runs[f"{gpu}/{field}"], STATE_RTOL), field


@pytest.mark.parametrize("case", [c for c in CASES if c != "thermal-off-co2"])
def test_entropy_bit_exact(runs, case):
    eta = runs[f"{case}/cuda/eta"]
    assert np.array_equal(eta, runs[f"{case}/cuda/eta0"])
    assert np.array_equal(eta, runs[f"{case}/cpu/eta"])


@pytest.mark.parametrize("case", FREE)
def test_momenta_conserved(runs, case):
    for group in (("px", "py", "pz"), ("Lx", "Ly", "Lz")):
        cols = np.array([runs[f"{case}/cuda/{c}"] for c in group])
        scale = max(float(np.max(np.abs(cols))), 1.0)
        assert float(np.max(np.abs(cols - cols[:, :1]))) <= 1e-12 * scale, group


@pytest.mark.parametrize("case", CASES)
def test_diagnostics_equal_cpu(runs, case):
    for c in ("energy", "kinetic", "internal", "potential", "entropy", "px", "Lz", "theta_min", "theta_max"):
        a, b = runs[f"{case}/cpu/{c}"], runs[f"{case}/cuda/{c}"]
        assert np.array_equal(np.isnan(a), np.isnan(b)), c
        ok = ~np.isnan(a)
        scale = max(float(np.max(np.abs(a[ok]), initial=0.0)), 1e-300)
        assert np.all(np.abs(a[ok] - b[ok]) <= DIAG_RTOL * max(scale, 1.0)), c


@pytest.mark.parametrize("case", ["push-co2", "push-co2-two-launch"])
def test_a_sub_flow_defined_outside_the_package_runs_on_the_device(runs, case):
    """``tests/push_subflow.py``'s push (the worked example of docs/architecture.md) gives the
    momentum its impulse on the device as on the CPU; nothing in the package names it."""
    gained = runs[f"{case}/cuda/px"][-1] - runs[f"{case}/cuda/px"][0]
    assert abs(gained - 3 * 0.3 * 3 * 2e-3) <= 1e-13


@pytest.mark.parametrize("name", [b[0] for b in BLOWUPS])
def test_a_blow_up_stops_the_device_in_the_cpus_step_and_keeps_the_last_good_state(runs, name):
    """The GPU path's in-loop stop: the same first bad step as the CPU (found between the
    diagnostics stops of a chunked run), the same message, and the state rewound to the last
    good step, equal to the CPU's."""
    cpu, gpu = f"blowup-{name}/cpu", f"blowup-{name}/cuda"
    step = int(runs[f"{cpu}/step"])
    assert 5 < step < 1000
    assert int(runs[f"{gpu}/step"]) == step
    message = str(runs[f"{gpu}/message"])
    assert f"in step {step + 1} " in message and "spring 0 (nodes 0–1) has stretch l/l0 =" in message
    assert message == str(runs[f"{cpu}/message"])
    for field in ("positions", "momenta", "phi"):
        assert np.isfinite(runs[f"{gpu}/{field}"]).all()
        assert _close(runs[f"{cpu}/{field}"], runs[f"{gpu}/{field}"], STATE_RTOL), field


def test_thermal_off_has_no_thermal_state(runs):
    assert "thermal-off-co2/cuda/phi" not in runs
    assert np.isnan(runs["thermal-off-co2/cuda/theta_min"]).all()


def test_gravity_acts_on_the_device(runs):
    potential = runs["gravity-chain-f10/cuda/potential"]
    assert potential[-1] != potential[0]
    assert _close(runs["gravity-chain-f10/cpu/positions"], runs["gravity-chain-f10/cuda/positions"], STATE_RTOL)


def test_chunked_run_is_bit_identical(runs):
    for field in ("positions", "momenta", "phi"):
        assert np.array_equal(runs[f"chunks/cuda/{field}"], runs[f"hencky-co4/cuda/{field}"]), field


def test_loaded_state_replaces_the_device_state(runs):
    for field in ("positions", "momenta", "phi"):
        assert _close(runs[f"reload/cpu/{field}"], runs[f"reload/cuda/{field}"], STATE_RTOL), field


# ----------------------------------------------------------------------------------------------
# errors (no simulator needed)


def test_implicit_integrator_is_refused():
    with pytest.raises(InputError, match="implicit; backend 'cuda' runs only the explicit"):
        tn.Simulation(tn.chain(), integrator="ho4", h=0.01, backend="cuda")


def test_unknown_backend_is_refused():
    with pytest.raises(InputError, match="unknown backend 'opencl'"):
        tn.Simulation(tn.chain(), integrator="co2", h=0.01, backend="opencl")


def test_missing_numba_cuda_is_named(monkeypatch):
    import thermonet.explicit.cuda as tc

    real = importlib.util.find_spec
    monkeypatch.setattr(tc.importlib.util, "find_spec", lambda name, *a: None if name == "numba_cuda" else real(name, *a))
    with pytest.raises(InputError, match="numba-cuda is not installed"):
        tn.Simulation(tn.chain(), integrator="co2", h=0.01, backend="cuda")


@needs_numba_cuda
def test_no_gpu_names_the_simulator():
    from numba import cuda

    from thermonet.explicit.cuda import simulator_enabled

    if simulator_enabled() or cuda.is_available():
        pytest.skip("a GPU (or the simulator) is available here")
    with pytest.raises(InputError, match="no CUDA GPU is visible.*NUMBA_ENABLE_CUDASIM=1"):
        tn.Simulation(tn.chain(), integrator="co2", h=0.01, backend="cuda")


@needs_numba_cuda
def test_unsupported_numpy_is_named(monkeypatch):
    """numba-cuda 0.30.4 with NumPy 2.5 breaks at the first kernel compiled (np.row_stack is gone);
    the backend check must say so in one line instead."""
    import builtins

    from thermonet.explicit.cuda import _compiler_problem

    real_import = builtins.__import__

    def broken(name, globals=None, locals=None, fromlist=(), level=0):
        if name == "numba.cuda.np" and fromlist and "arrayobj" in fromlist:
            raise AttributeError("module 'numpy' has no attribute 'row_stack'")
        return real_import(name, globals, locals, fromlist, level)

    monkeypatch.setattr(builtins, "__import__", broken)
    message = _compiler_problem()
    assert message is not None
    assert "cannot compile kernels with NumPy" in message and "row_stack" in message
    assert np.__version__ in message and "numpy<2.5" in message


# ----------------------------------------------------------------------------------------------
# compiled for a real device


def _toolkit_compiles() -> bool:
    """Whether numba-cuda can compile to PTX here: NVVM and NVRTC must both load (a fresh
    ``pip install '.[test]'`` brings numba-cuda without the toolkit libraries), so try a
    trivial kernel."""
    if not HAVE_NUMBA_CUDA:
        return False
    try:
        from numba import cuda

        def _probe(out):
            out[0] = 1.0

        cuda.compile_ptx(_probe, "void(float64[:])", cc=(9, 0))
        return True
    except Exception:
        return False


@pytest.mark.skipif(not _toolkit_compiles(), reason="needs the CUDA toolkit libraries (NVVM, NVRTC) of "
                    "numba-cuda[cu12] or [cu13]; no GPU needed")
@pytest.mark.parametrize("model", ["hencky", "quadratic"])
def test_kernels_compile_to_ptx_for_h100(model):
    from thermonet.explicit.cuda.kernels import compile_ptx

    for thermal in (True, False):
        ptx = compile_ptx(tn.get_model(model), thermal=thermal, uniform=True, cc=(9, 0))
        assert set(ptx) == {"spring", "node", "spring_sums", "node_sums", "finish"}
        assert all(".target sm_90" in text for text in ptx.values())


@pytest.mark.gpu
@pytest.mark.skipif(not gpu_available(), reason="needs a CUDA GPU")
@pytest.mark.parametrize("integrator", EXPLICIT)
@pytest.mark.parametrize("model", ["hencky", "quadratic", "user"])
def test_gpu_equals_cpu(integrator, model):
    sys.path.insert(0, os.path.join(ROOT, "examples"))
    from custom_model import SOFTENING_HENCKY

    net = tn.lattice((6, 6, 6), neighbours=18, jitter=0.1, seed=2)
    rng = np.random.default_rng(2)
    v, temps = rng.normal(0, 1.0, (net.n_nodes, 3)), 300 + 400 * rng.random(net.n_springs)
    m = {"user": SOFTENING_HENCKY}.get(model, model)
    params = dict(E=100.0, beta=0.5, C0=5.0, theta0=300.0, eta0=0.0) if model == "quadratic" else None
    out = {}
    for backend in ("cpu", "cuda"):
        sim = tn.Simulation(net, model=m, parameters=params, temperatures=temps, velocities=v,
                            integrator=integrator, h=1e-3, backend=backend)
        sim.run(steps=50, diagnostics_every=10)
        out[backend] = sim
    a, b = out["cpu"].state, out["cuda"].state
    assert np.array_equal(a.entropy, b.entropy)
    for field in ("positions", "momenta", "thermal_displacement"):
        assert _close(getattr(a, field), getattr(b, field), 1e-10), field
    d = out["cuda"].diagnostics
    for cols in (d.linear_momentum, d.angular_momentum):
        assert np.max(np.abs(cols - cols[0])) <= 1e-12 * max(np.max(np.abs(cols)), 1.0)


@pytest.mark.gpu
@pytest.mark.skipif(not gpu_available(), reason="needs a CUDA GPU")
@pytest.mark.parametrize("integrator", ["co2", "co6", "gtr-1"])
def test_gpu_fused_launch_equals_two_launches(integrator):
    """One cooperative launch per chunk runs the same inlined per-spring and per-node updates as
    two launches per stage: the same numbers, chunked or not."""
    net = tn.lattice((9, 9, 9), neighbours=6, jitter=0.1, seed=3)
    rng = np.random.default_rng(3)
    v, temps = rng.normal(0, 0.5, (net.n_nodes, 3)), 250 + 100 * rng.random(net.n_springs)
    states = {}
    for fused, chunks in ((False, (40,)), (True, (40,)), (True, (1, 13, 26))):
        sim = tn.Simulation(net, temperatures=temps, velocities=v, integrator=integrator, h=2e-3, backend="cuda")
        sim.stepper.fused = fused
        for n in chunks:
            sim.run(steps=n, diagnostics_every=n)
        states[fused, chunks] = sim.state
    reference = states[False, (40,)]
    for state in states.values():
        for field in ("positions", "momenta", "thermal_displacement"):
            np.testing.assert_array_equal(getattr(state, field), getattr(reference, field), err_msg=field)



def test_fused_grid_covers_the_net_within_residency_and_caps_small_nets():
    """The fused launch's grid (H100 figures: 132 multiprocessors, 528 resident blocks of 256
    threads for the launch-bounded kernel): one thread per spring where it fits, all resident
    blocks on large nets, 2 blocks a multiprocessor below SMALL_NET_SPRINGS."""
    from thermonet.explicit.cuda.stepper import CudaSplittingStepper, fused_grid

    assert CudaSplittingStepper.SMALL_NET_BLOCKS_PER_SM == 2
    assert fused_grid(1000, 343, 256, 528, 132) == 4  # a tiny net: one thread per spring
    assert fused_grid(104_544, 35_937, 256, 528, 132) == 264  # would need 409: capped at 2 per SM
    assert fused_grid(1_014_300, 343_000, 256, 528, 132) == 528  # large: every resident block
    assert fused_grid(0, 0, 256, 528, 132) == 1


def test_the_launcher_counts_numpy_scalars_as_the_python_types_numba_types_alike():
    """A flag computed with NumPy (numpy.bool_) or a count read from an array (numpy.int64) keeps a
    launch on the launcher's fast path where the first launch had bool / int; a NumPy scalar that
    Numba types differently (int32) does not."""
    from thermonet.explicit.cuda.launch import _python_types

    assert _python_types(np.bool_(True)) == _python_types(False)
    assert _python_types((np.int64(3), 1.0, np.True_)) == _python_types((0, np.float64(2.0), False))
    assert _python_types(np.int32(1)) != _python_types(1)
