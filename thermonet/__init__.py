"""thermonet: structure-preserving time integrators for networks of thermo-elastic springs.

Implements the variational integrators of Mata & Lew, "Variational time integrators for finite
dimensional thermo-elasto-dynamics without heat conduction", IJNME 88 (2011) 1-30.
"""

#: set before the imports below, so that a module they load may read it at its own import
__version__ = "0.1.0"

from .builders import chain, from_meshio, lattice, read_mesh, triangle
from .diagnostics import Diagnostics
from .errors import InputError, MeshError, SimulationError, ThermonetError, UnknownNameError
from .heat import Bath, Source
from .integrators import Integrator, available_integrators, get_integrator, register_integrator
from .models import Model, available_models, get_model, register_model
from .net import Net
from .paper import chain_simulation, triangle_simulation
from .simulation import Simulation
from .state import State
from .timefunctions import TimeFunction


__all__ = [
    "Net", "chain", "triangle", "lattice", "read_mesh", "from_meshio",
    "Model", "register_model", "get_model", "available_models",
    "Integrator", "get_integrator", "register_integrator", "available_integrators",
    "Simulation", "State", "Diagnostics", "chain_simulation", "triangle_simulation",
    "ThermonetError", "InputError", "MeshError", "SimulationError", "UnknownNameError",
    "Bath", "Source", "TimeFunction",
]
