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
