"""Seeing Numba compile: the kernels are compiled on their first use for a model, integrator and
thermal/threading variant, then loaded from Numba's disk cache. A first run can spend seconds
compiling; :class:`CompileWatch` tells when compiling starts (the CLI says so) and how long it
took, so that a run's rate and ETA leave it out.

It listens to Numba's ``numba:compile`` events, which fire only for a real compilation (a load
from the disk cache fires none); nested compilations (a kernel's callees) count once.
"""

from __future__ import annotations

import threading
import time
from typing import Callable

from numba.core import event as _event


class CompileWatch(_event.Listener):
    """A context manager: while active, ``seconds`` sums the wall time of outermost Numba
    compilations (of any thread) and ``on_start()`` is called when the first one begins."""

    def __init__(self, on_start: Callable[[], None] | None = None):
        self.on_start_callback = on_start
        self.seconds = 0.0
        self.compilations = 0
        self._depth = 0
        self._began = 0.0
        self._lock = threading.Lock()

    # numba's Listener interface
    def on_start(self, event) -> None:
        with self._lock:
            self._depth += 1
            if self._depth > 1:
                return
            self._began = time.perf_counter()
            first = self.compilations == 0
            self.compilations += 1
        if first and self.on_start_callback is not None:
            self.on_start_callback()

    def on_end(self, event) -> None:
        with self._lock:
            self._depth -= 1
            if self._depth == 0:
                self.seconds += time.perf_counter() - self._began

    def __enter__(self) -> "CompileWatch":
        _event.register("numba:compile", self)
        return self

    def __exit__(self, *exc) -> None:
        _event.unregister("numba:compile", self)
