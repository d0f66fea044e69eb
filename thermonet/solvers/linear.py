"""The registry of linear solvers a Newton step can use, each with ``factorize(data)`` once per
Newton iteration (``data``: the CSR values, for the ``assembled`` ones) and ``solve(rhs, target,
settled)``, and the choice "auto" makes.
"""

from __future__ import annotations

from .direct import ReusedLU, ReusedLUDouble, SparseLU
from .krylov import Krylov
from .matrix_free import MatrixFree
from .pattern import BlockPattern

LINEAR_SOLVERS = {"splu": SparseLU, "splu-reuse": ReusedLU, "splu-reuse-double": ReusedLUDouble,
                  "matfree": MatrixFree, "gmres": Krylov}

#: "auto" uses the direct solver up to this many unknowns (measured crossover on 3D lattices:
#: at ~200 unknowns SuperLU and an iterative solve cost the same, at ~1000 SuperLU is 10× slower)
DIRECT_MAX_UNKNOWNS = 500


def make_linear_solver(name: str, pattern: BlockPattern, problem=None):
    """The linear solver ``name`` for ``pattern`` (``problem``: the stepper, for matfree)."""
    if name == "auto":
        name = "splu" if pattern.size <= DIRECT_MAX_UNKNOWNS else "matfree"
    return LINEAR_SOLVERS[name](pattern, problem)
