"""GPU backend of the explicit integrators (``backend="cuda"``), on NVIDIA's numba-cuda.

The same kick/drift stages as :mod:`thermonet.explicit.cpu`, as two CUDA kernels per stage,
with the state resident on the device across steps (:mod:`.stepper`); the kernels are compiled per
model from the model's own ``@njit`` scalar functions (:mod:`.kernels`). Importing this package
imports no CUDA code: :func:`require_cuda` says whether the backend can run, and why not.

Without a GPU, Numba's CUDA simulator runs the same kernels as Python (slowly) when the
environment variable ``NUMBA_ENABLE_CUDASIM=1`` is set before Numba is first imported; the
tests use it.
"""

from __future__ import annotations

import importlib.util
import os

from ...errors import InputError

INSTALL_HINT = "pip install 'thermonet[cuda]' (numba-cuda >= 0.30)"

#: the stepping kernels' blow-up flag (4,) int64: set, and the step, row of the schedule (its
#: length for a call's closing kick) and stage count since the launch sequence began at which a
#: spring left the admissible states
FLAG_SET, FLAG_STEP, FLAG_ROW, FLAG_STAGES = range(4)


def simulator_enabled() -> bool:
    """True when Numba's CUDA simulator is switched on (it must be before numba is imported)."""
    from numba.core import config

    return bool(config.ENABLE_CUDASIM)


def gpu_available() -> bool:
    """True when numba-cuda sees a real GPU here (not the simulator): what the ``gpu`` tests need."""
    if importlib.util.find_spec("numba_cuda") is None:
        return False
    try:
        from numba import cuda

        return not simulator_enabled() and cuda.is_available()
    except Exception:
        return False


def cuda_problem() -> str | None:
    """Why the CUDA backend cannot run here, or None when it can."""
    if importlib.util.find_spec("numba_cuda") is None:
        return f"numba-cuda is not installed ({INSTALL_HINT})"
    try:
        from numba import cuda
    except Exception as exc:  # a broken install must say what broke, not only "not available"
        return f"numba-cuda is installed but numba.cuda does not import: {exc}"
    if getattr(cuda, "implementation", "") == "Built-in":
        return f"numba.cuda is Numba's deprecated built-in target, not numba-cuda ({INSTALL_HINT})"
    if simulator_enabled():
        return None
    if not cuda.is_available():
        env = "NUMBA_ENABLE_CUDASIM" in os.environ
        return ("no CUDA GPU is visible to numba-cuda (numba.cuda.is_available() is False: no NVIDIA GPU or "
                "driver)" + ("" if env else "; to run the CUDA kernels without a GPU, slowly, start Python with "
                             "NUMBA_ENABLE_CUDASIM=1 (Numba's CUDA simulator)"))
    return _compiler_problem()


def _compiler_problem() -> str | None:
    """Why numba-cuda's compiler cannot load with this NumPy, or None.

    numba-cuda loads its array registry lazily, at the first kernel compiled; a NumPy it does not
    support (numba-cuda 0.30.4 with NumPy >= 2.5, which removed ``np.row_stack``) breaks there,
    deep inside the first ``advance``. Importing the registry here moves that failure to a message.
    """
    try:
        from numba.cuda.np import arrayobj  # noqa: F401
    except Exception as exc:
        import numpy as np
        import numba_cuda

        return (f"numba-cuda {numba_cuda.__version__} cannot compile kernels with NumPy {np.__version__} "
                f"({type(exc).__name__}: {exc}); install a NumPy it supports (e.g. 'numpy<2.5') or a newer "
                "numba-cuda")
    return None


def require_cuda() -> None:
    """Raise :class:`~thermonet.errors.InputError` naming what is missing for the CUDA backend."""
    problem = cuda_problem()
    if problem is not None:
        raise InputError(f"backend 'cuda' is not available: {problem}")


__all__ = ["cuda_problem", "require_cuda", "simulator_enabled"]
