"""Newton's method and the linear solvers of the implicit integrators, each piece with one job:

- :mod:`.pattern`: :class:`BlockPattern`, the Newton matrix's block sparsity (built once per net);
- :mod:`.direct` (``"splu"``), :mod:`.krylov` (``"gmres"``), :mod:`.matrix_free` (``"matfree"``):
  the linear solvers, chosen by name in :mod:`.linear` (``"auto"``: direct for small nets);
- :mod:`.newton`: the iteration (``newton.newton``), its options, record and timings.
"""

from .linear import DIRECT_MAX_UNKNOWNS, LINEAR_SOLVERS, make_linear_solver
from .newton import NewtonOptions, NewtonResult, NewtonTimers
from .pattern import BlockPattern

__all__ = ["BlockPattern", "DIRECT_MAX_UNKNOWNS", "LINEAR_SOLVERS", "NewtonOptions", "NewtonResult", "NewtonTimers",
           "make_linear_solver"]
