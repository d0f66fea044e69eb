"""The linear solvers of the implicit integrators' Newton steps, each piece with one job:

- :mod:`.pattern`: :class:`BlockPattern`, the Newton matrix's block sparsity (built once per net);
- :mod:`.direct` (``"splu"``, ``"splu-reuse"``: kept factors in single precision,
  ``"splu-reuse-double"``), :mod:`.krylov` (``"gmres"``), :mod:`.matrix_free` (``"matfree"``):
  the linear solvers, chosen by name in :mod:`.linear` (``"auto"``: direct for small nets).

They solve ``J du = R`` for a block pattern and know nothing of springs or schemes; Newton's
iteration that calls them is :mod:`thermonet.implicit.core.newton`.
"""

from .linear import DIRECT_MAX_UNKNOWNS, LINEAR_SOLVERS, make_linear_solver
from .pattern import BlockPattern

__all__ = ["BlockPattern", "DIRECT_MAX_UNKNOWNS", "LINEAR_SOLVERS", "make_linear_solver"]
