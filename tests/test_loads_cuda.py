"""Loads on the CUDA backend against the CPU: under Numba's CUDA simulator (``tests/cuda_sim_loads.py``
in a process of its own) the states and work agree bit for bit (the simulator runs the CPU's
operations in the CPU's order), chunked runs too; on a real GPU (``gpu``) to round-off."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys

import numpy as np
import pytest

from thermonet.explicit.cuda import gpu_available

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HAVE_NUMBA_CUDA = importlib.util.find_spec("numba_cuda") is not None
sys.path.insert(0, os.path.join(ROOT, "tests"))


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    if not HAVE_NUMBA_CUDA:
        pytest.skip("numba-cuda is not installed (pip install '.[cuda]')")
    path = str(tmp_path_factory.mktemp("cuda") / "loads.npz")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "tests", "cuda_sim_loads.py"), path],
                          env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    with np.load(path) as data:
        return dict(data)


@pytest.mark.parametrize("integrator", ["co2", "f10", "co4"])
def test_the_simulated_gpu_runs_loads_as_the_cpu_does(runs, integrator):
    cpu, gpu = f"{integrator}/cpu", f"{integrator}/cuda"
    for field in ("positions", "momenta", "phi", "load_work", "pull_Rx", "pull_work", "push_work"):
        np.testing.assert_array_equal(runs[f"{cpu}/{field}"], runs[f"{gpu}/{field}"], err_msg=field)
    assert np.any(runs[f"{gpu}/load_work"] != 0.0)
    # the balance differs by the device's tree sums of the energy only
    np.testing.assert_allclose(runs[f"{cpu}/energy_balance"], runs[f"{gpu}/energy_balance"], rtol=0,
                               atol=1e-12 * np.max(np.abs(runs[f"{cpu}/energy"])))


def test_a_chunked_device_run_with_loads_equals_one_call(runs):
    np.testing.assert_array_equal(runs["chunks/positions"], runs["co2/cuda/positions"])
    np.testing.assert_array_equal(runs["chunks/load_work"], runs["co2/cuda/load_work"])


@pytest.mark.gpu
@pytest.mark.skipif(not gpu_available(), reason="needs a CUDA GPU")
@pytest.mark.parametrize("integrator", ["co2", "co4"])
def test_gpu_loads_equal_cpu_to_round_off(tmp_path, integrator):
    from cuda_sim_loads import loaded

    out = {}
    for backend in ("cpu", "cuda"):
        sim = loaded(backend, integrator)
        sim.run(steps=200, diagnostics_every=50)
        out[backend] = sim
    a, b = out["cpu"], out["cuda"]
    for field in ("positions", "momenta", "thermal_displacement"):
        x, y = getattr(a.state, field), getattr(b.state, field)
        assert np.max(np.abs(x - y)) <= 1e-10 * np.max(np.abs(x)), field
    np.testing.assert_allclose(b.state.extra["load_work"], a.state.extra["load_work"], rtol=1e-10)
    np.testing.assert_allclose(b.diagnostics.energy_balance, a.diagnostics.energy_balance,
                               atol=1e-10 * np.max(np.abs(a.diagnostics.energy)))


def test_the_simulated_gpu_runs_loads_with_heat_flow_as_the_cpu_does(runs):
    """The CPU defers the kick before the reverse sweep and merges it with the next one; the
    device runs the schedule as written: the same dynamics to round-off."""
    cpu, gpu = "heat/cpu", "heat/cuda"
    np.testing.assert_allclose(runs[f"{gpu}/positions"], runs[f"{cpu}/positions"], rtol=0, atol=1e-12)
    # (of the entropies' scale, as tests/test_cuda_heat_sim.py compares them: η's rounding follows
    # the size of its changes, not of its value; a spring whose η the exchanges brought near 0
    # keeps the rounding of the larger changes that took it there)
    eta = runs[f"{cpu}/entropy"]
    np.testing.assert_allclose(runs[f"{gpu}/entropy"], eta, rtol=0, atol=1e-13 * np.abs(eta).max())
    np.testing.assert_allclose(runs[f"{gpu}/load_work"], runs[f"{cpu}/load_work"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(runs[f"{gpu}/energy_balance"], runs[f"{cpu}/energy_balance"], rtol=0, atol=1e-10)
    assert np.any(runs[f"{cpu}/load_work"] != 0.0)
