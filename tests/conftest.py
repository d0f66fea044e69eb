"""Fixtures shared by several test modules."""

import numpy as np
import pytest

import thermonet as tn
from thermonet import reference as ref
from thermonet.paper import CHAIN_MOMENTA, CHAIN_PARAMETERS, CHAIN_TEMPERATURES


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
