"""What accuracy costs in time: convergence, work-precision and long-run energy studies.

Every study is a set of independent runs (one per integrator and time step, or per SciPy
tolerance) executed by a :class:`~thermonet.studies.runner.Runner`, serially or on a Dask cluster,
and compared with one reference solution (:mod:`thermonet.studies.reference`).
"""

from .convergence import ConvergenceStudy, convergence_study
from .cost import CostStudy, cost_study
from .energy import EnergyStudy, energy_study
from .reference import ReferenceSolution, reference_solution
from .runner import Runner
from .slopes import asymptotic_slope

__all__ = [
    "Runner", "ReferenceSolution", "reference_solution", "asymptotic_slope",
    "ConvergenceStudy", "convergence_study", "CostStudy", "cost_study", "EnergyStudy", "energy_study",
]
