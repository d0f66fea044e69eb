"""The paper's two examples (Mata & Lew 2011, §5), ready to run: nets, parameters and initial data."""

from __future__ import annotations

import numpy as np

from .builders import chain, triangle
from .simulation import Simulation

CHAIN_PARAMETERS = {"c": 100.0, "beta": 0.2, "C0": 5.0, "theta0": 300.0}
CHAIN_TEMPERATURES = np.array([800.0, 1200.0, 400.0])
CHAIN_MOMENTA = np.array([[0.0, 0.0, 0.0], [20.0, 10.0, 10.0], [10.0, 20.0, 10.0], [0.0, 10.0, 0.0]])

TRIANGLE_PARAMETERS = {"c": np.array([400.0, 500.0, 400.0]), "beta": 0.2, "C0": 5.0, "theta0": 300.0}
TRIANGLE_TEMPERATURES = np.array([500.0, 1000.0, 500.0])
TRIANGLE_MOMENTA = np.array([[0.0, 0.0, -7.0], [0.0, 0.0, 7.0], [0.0, 5.0, 0.0]])


def chain_simulation(integrator="co2", h=0.01, momentum_scale: float = 1.0, **kwargs) -> Simulation:
    """The chain of three springs (Mata & Lew 2011, §5.1, Table II). Initial energy 7983.333…"""
    return Simulation(
        chain(), model="hencky", parameters=CHAIN_PARAMETERS, temperatures=CHAIN_TEMPERATURES,
        momenta=momentum_scale * CHAIN_MOMENTA, integrator=integrator, h=h, **kwargs,
    )


def triangle_simulation(integrator="co2", h=1e-3, **kwargs) -> Simulation:
    """The triangle net of three masses (Mata & Lew 2011, §5.2, Table III)."""
    return Simulation(
        triangle(), model="hencky", parameters=TRIANGLE_PARAMETERS, temperatures=TRIANGLE_TEMPERATURES,
        momenta=TRIANGLE_MOMENTA, integrator=integrator, h=h, **kwargs,
    )
