"""Numba's CUDA simulator made faster, and safe at that speed, for the tests' simulator processes.

The simulator runs each thread of a block as a Python thread, and its block manager polls them for
barriers in a loop that holds the interpreter lock: at Python's default switch interval (5 ms)
every thread's turn waits for the poller's interval to run out. At 0.1 ms the tests' simulator
runs take less than half the time (``tests/test_cuda_heat_sim.py``'s cases: 41.7 s against
17.8 s).

Threads that interleave that finely expose a race in the simulator's shared arrays (numba-cuda
0.30): ``cuda.shared.array`` looks its call site up in the block's allocations and, when absent,
allocates and stores one, without a lock. Two threads of a block that both find it absent get
different arrays, and a block reduction then adds up the wrong numbers (seen: the momenta sums of
``tests/cuda_sim_cases.py``'s quadratic case, 2 runs of 4). :func:`pace` puts that lookup under
a lock; the call site is found as the simulator finds it (file and line of the caller).

Call :func:`pace` in the simulator process before its first kernel launch.
"""

from __future__ import annotations

import sys
import threading

SWITCH_INTERVAL = 1e-4


def pace() -> None:
    import numpy as np
    from numba.core import config

    if not config.ENABLE_CUDASIM:
        return
    from numba.core import types
    from numba.cuda.simulator import kernelapi
    from numba.np import numpy_support

    shared = kernelapi.FakeCUDAShared
    if getattr(shared, "_thermonet_locked", False):
        return
    probe = shared(0)
    if not isinstance(getattr(probe, "_allocations", None), dict):  # the simulator changed: say so
        raise RuntimeError("numba-cuda's simulator no longer keeps shared arrays in _allocations: "
                           "update tests/simulator_pace.py")
    original = shared.array
    lock = threading.Lock()

    def array(self, shape, dtype, alignment=None):
        if shape == 0 or alignment is not None:  # dynamic shared memory, or the simulator's error
            return original(self, shape, dtype, alignment)
        frame = sys._getframe(1)
        caller = (frame.f_code.co_filename, frame.f_lineno)
        with lock:
            found = self._allocations.get(caller)
            if found is None:
                found = np.empty(shape, numpy_support.as_dtype(dtype) if isinstance(dtype, types.Type) else dtype)
                self._allocations[caller] = found
        return found

    shared.array = array
    shared._thermonet_locked = True
    sys.setswitchinterval(SWITCH_INTERVAL)
