"""Time integrators, registered by name. Each declares its ``order`` and whether it is explicit.
The implicit schemes live in :mod:`thermonet.implicit` (a folder each); they are registered here
with the explicit ones."""

from .base import (Integrator, Stepper, StepFailure, available_integrators, explicit_integrators, get_integrator,
                   register_integrator)
from .splitting import BM4, BM6, BM6A, CO2, CO4, CO6, F10, GTR0, GTR1, NM2, OMF4, Splitting, compose
from ..implicit.gtr_alpha.stepper import GTR_HALF, GTRAlpha
from ..implicit.ho4.stepper import HO4, HO4_INTEGRATOR
from ..implicit.em2.stepper import EM2, EM2_INTEGRATOR

__all__ = [
    "Integrator", "Stepper", "StepFailure", "Splitting", "compose", "get_integrator", "register_integrator",
    "available_integrators", "explicit_integrators", "GTR0", "GTR1", "CO2", "F10", "NM2", "CO4", "CO6", "BM4", "BM6", "BM6A",
    "OMF4", "GTRAlpha", "GTR_HALF", "HO4", "HO4_INTEGRATOR", "EM2", "EM2_INTEGRATOR",
]
