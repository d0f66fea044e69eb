"""Kernel launches without re-typing and re-flattening the device arrays at every launch.

A launch through a numba-cuda dispatcher (``kernel[blocks, threads](*args)``) types every
argument and flattens every array into its pointer, shape and strides on each call: with the
stepper's records (tens of arrays) that costs 0.4 ms of host time a launch (measured on an H100
host, numba-cuda 0.30.4), which bounds two launches per stage and the heat phases far below what
the GPU does in that time. A :class:`Launcher` types the arguments once, keeps the compiled
kernel, and keeps the flattened form of each argument that holds device arrays (an array or a
record of arrays: immutable, so its flattened form stays valid while it is alive) keyed by the
object; only scalars and tuples of scalars (coefficients, times, the stage's position) are
flattened anew. The same kernel runs on the same arguments, so results are unchanged.

Under Numba's CUDA simulator, or wherever the fast path cannot be set up with the installed
numba-cuda, a launcher falls back to the dispatcher call.
"""

from __future__ import annotations

import numpy as np

#: flattened arguments kept per argument position (the oldest dropped beyond this)
KEEP = 8


#: NumPy scalar types that Numba types as the Python type they map to (a flag computed with NumPy
#: is a numpy.bool_, a count read from an array a numpy.int64): the same kernel signature
_SAME_AS_PYTHON = {np.bool_: bool, np.int64: int, np.float64: float}


def _python_types(value):
    """The Python types a scalar or tuple-of-scalars argument was typed from (NumPy's bool_,
    int64 and float64 counted as bool, int and float, which Numba types alike)."""
    if isinstance(value, tuple):
        return tuple(_SAME_AS_PYTHON.get(type(v), type(v)) for v in value)
    return _SAME_AS_PYTHON.get(type(value), type(value))


def _holds_device_array(value) -> bool:
    if hasattr(value, "copy_to_host"):
        return True
    return isinstance(value, tuple) and any(_holds_device_array(v) for v in value)


class Launcher:
    """Launches one kernel (a numba-cuda dispatcher) like ``dispatcher[blocks, threads](*args)``,
    with the argument types fixed by its first launch."""

    def __init__(self, dispatcher):
        self.dispatcher = dispatcher
        self._kernel = None  # the compiled kernel, after the first launch (False: dispatcher only)
        self._flat: list[dict] = []  # per argument position: id -> (object, flattened form)
        self._configs: dict = {}
        #: launches after the first that took the dispatcher's slow path (an argument typed
        #: differently from the first launch's): none in a run whose arguments keep their types
        self.slow_launches = 0

    def __call__(self, blocks: int, threads: int, *args) -> None:
        if not self._kernel:
            self.dispatcher[blocks, threads](*args)
            if self._kernel is None:
                self._kernel = self._set_up(args)
            return
        kernel = self._kernel
        flat = []
        for position, (ty, value) in enumerate(zip(kernel.argument_types, args)):
            if _holds_device_array(value):
                kept = self._flat[position].get(id(value))
                if kept is None or kept[0] is not value:
                    part = []
                    kernel._prepare_args(ty, value, self._stream, [], part)
                    if len(self._flat[position]) >= KEEP:
                        self._flat[position].clear()
                    kept = self._flat[position][id(value)] = (value, part)
                flat.extend(kept[1])
            elif _python_types(value) == self._scalar_types[position]:
                kernel._prepare_args(ty, value, self._stream, [], flat)
            else:  # typed differently from the first launch: the dispatcher types it
                self.slow_launches += 1
                self.dispatcher[blocks, threads](*args)
                return
        config = self._configs.get((blocks, threads))
        if config is None:
            config = self._configs[blocks, threads] = self._config(blocks, threads)
        self._launch(self._stream, config, self._cufunc.kernel, *flat)

    def _set_up(self, args):
        """The compiled kernel the dispatcher chose for ``args``, and the launch functions; False
        (the dispatcher call from then on) under the simulator or with a numba-cuda whose
        internals differ."""
        from . import simulator_enabled

        if simulator_enabled():
            return False
        try:
            from cuda.core import LaunchConfig, launch
            from numba.cuda.cudadrv import driver

            types = tuple(self.dispatcher.typeof_pyval(a) for a in args)
            kernel = self.dispatcher.overloads[types]
            self._cufunc = kernel._codelibrary.get_cufunc()
            self._stream = driver._to_core_stream(0)
            self._launch, self._launch_config = launch, LaunchConfig
            self._cooperative = bool(getattr(kernel, "cooperative", False))
            self._flat = [{} for _ in types]
            self._scalar_types = [None if _holds_device_array(a) else _python_types(a) for a in args]
            kernel._prepare_args  # noqa: B018 (present, or the fast path is not used)
            self._config(1, 1)
        except Exception:  # noqa: BLE001 (any mismatch: keep the dispatcher's own path)
            return False
        return kernel

    def _config(self, blocks: int, threads: int):
        try:
            return self._launch_config(grid=blocks, block=threads, shmem_size=0, is_cooperative=self._cooperative)
        except TypeError:  # cuda-core < 1.0
            return self._launch_config(grid=blocks, block=threads, shmem_size=0,
                                       cooperative_launch=self._cooperative)
