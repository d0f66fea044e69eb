"""Fixtures shared by several test modules."""

import os

# The suite runs pytest-xdist workers, each with Numba's OpenMP pool of one thread per core: more
# threads than cores. GNU OpenMP's idle threads spin by default and take the cores the other
# workers' threads need (threaded tests of heat flow and loads, measured on 2 busy cores: 15-24 s
# against 3 s); passive waiting yields them. Set before a parallel kernel loads the runtime.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

import thermonet as tn  # noqa: E402
from thermonet import reference as ref  # noqa: E402
from thermonet.paper import CHAIN_MOMENTA, CHAIN_PARAMETERS, CHAIN_TEMPERATURES  # noqa: E402


# Seconds each module took in a cold-cache run of the suite on 2 cores (mostly compiling its
# kernels; commit 3b87913): the modules run longest first, so that the two workers finish
# together instead of one running a long module alone at the end (without an order, one worker
# idled for the last 92 s of a 973 s run).
# Only an order: a module missing here runs after these, in collection order.
COLD_SECONDS = {
    "test_implicit_newton.py": 315, "test_loads_heat.py": 198, "test_em2.py": 189,
    "test_implicit_thermal.py": 144, "test_mpi.py": 110, "test_benchmarks.py": 102,
    "test_implicit_compiled.py": 99, "test_cuda_sim.py": 96, "test_heat_flow.py": 94,
    "test_study_scenes.py": 93, "test_first_use.py": 68, "test_cuda_heat_sim.py": 60, "test_em2_paths.py": 57,
    "test_optimized_splittings.py": 45, "test_io.py": 41, "test_loads_cuda.py": 29,
    "test_implicit_conservation.py": 16, "test_examples.py": 16, "test_fuzz_inputs.py": 13,
    "test_custom_model_example.py": 13,
}


def pytest_configure(config):
    # pytest-xdist hands out whole modules (--dist loadfile) largest-count first unless told to
    # keep the collection order, which pytest_collection_modifyitems sets below
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False


def pytest_collection_modifyitems(config, items):
    items.sort(key=lambda item: -COLD_SECONDS.get(item.path.name, 0))  # (stable: a module's own order kept)


@pytest.fixture(scope="session")
def chain_reference():
    """(positions, momenta, temperatures) of the paper's chain at t = 1 from DOP853 at
    rtol = atol = 1e-13 on Hamilton's equations (the NumPy reference's right-hand side)."""
    net = tn.chain()
    rnet = ref.ReferenceNet.build(net, "hencky", CHAIN_PARAMETERS)
    eta = rnet.entropies(net.positions, CHAIN_TEMPERATURES)
    start = ref.ReferenceState(net.positions.copy(), CHAIN_MOMENTA.copy(), np.zeros(3), eta)
    end = ref.hamilton_solution(rnet, start, 1.0, rtol=1e-13, atol=1e-13)
    return end.x, end.p, rnet.temperatures(end.x, eta)
