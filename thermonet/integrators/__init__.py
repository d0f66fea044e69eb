"""Time integrators, registered by name. Each declares its ``order`` and whether it is explicit.

The registry and the ``Integrator``/``Stepper`` interface are :mod:`.base`; the explicit
splittings (CO2, CO4, OMF4, ...) live in :mod:`thermonet.explicit` and register there, the
implicit schemes in :mod:`thermonet.implicit` (a folder each) and are registered here.
Importing this package registers both.
"""

from ..explicit import splitting as _explicit_splittings  # noqa: F401  (registers them)
from ..implicit.em2.stepper import EM2, EM2_INTEGRATOR
from ..implicit.gtr_alpha.stepper import GTR_HALF, GTRAlpha
from ..implicit.ho4.stepper import HO4, HO4_INTEGRATOR
from .base import (Integrator, Stepper, StepFailure, available_integrators, explicit_integrators, get_integrator,
                   register_integrator)

__all__ = [
    "Integrator", "Stepper", "StepFailure", "get_integrator", "register_integrator",
    "available_integrators", "explicit_integrators", "GTRAlpha", "GTR_HALF", "HO4", "HO4_INTEGRATOR", "EM2",
    "EM2_INTEGRATOR",
]
