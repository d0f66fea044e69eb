"""A progress bar on stderr for long runs: percentage, steps/s and ETA."""

from __future__ import annotations

import sys
import time


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m:d}:{s:02d}"


class ProgressBar:
    """``progress(done, total, elapsed)`` callback for ``Simulation.run`` (elapsed: seconds of
    stepping, compilation excluded; :meth:`compiling` says when kernels are being compiled).

    Shows nothing during the first ``delay`` seconds (short runs stay quiet); then redraws one
    line at most every ``interval`` seconds on a terminal, or prints a line every
    ``log_interval`` seconds when stderr is a file or pipe.
    """

    def __init__(self, stream=None, delay: float = 1.0, interval: float = 0.2, log_interval: float = 10.0, width: int = 30):
        self.stream = stream or sys.stderr
        self.delay, self.width = delay, width
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.interval = interval if self.tty else log_interval
        self._last = -float("inf")
        self.shown = False
        self._compiling_said = False

    def line(self, done: int, total: int, elapsed: float) -> str:
        frac = done / total if total else 1.0
        filled = int(round(frac * self.width))
        rate = done / elapsed if elapsed > 0 else float("nan")
        eta = (total - done) / rate if rate > 0 else float("nan")
        eta_text = _clock(eta) if eta == eta else "?"
        return (f"[{'#' * filled}{'.' * (self.width - filled)}] {100 * frac:5.1f}%  "
                f"step {done}/{total}  {_three_digits(rate)} steps/s  ETA {eta_text}")

    def compiling(self) -> None:
        """Say, once, that kernels are being compiled (a first run; Numba caches them on disk)."""
        if self._compiling_said:
            return
        self._compiling_said = True
        self.stream.write("thermonet: compiling kernels (first run of this model and integrator only; "
                          "cached for later runs; not counted in steps/s and ETA)\n")
        self.stream.flush()

    def __call__(self, done: int, total: int, elapsed: float) -> None:
        now = time.monotonic()
        if elapsed < self.delay or (now - self._last < self.interval and done < total):
            return
        self._last = now
        text = self.line(done, total, elapsed)
        if self.tty:
            self.stream.write("\r" + text)
        else:
            self.stream.write(text + "\n")
        self.stream.flush()
        self.shown = True

    def close(self) -> None:
        if self.shown and self.tty:
            self.stream.write("\n")
            self.stream.flush()


def _three_digits(rate: float) -> str:
    """A rate with 3 significant digits: ``1,230,000``, ``45.6``, ``0.0123``; ``?`` if unknown."""
    if not rate == rate or rate in (float("inf"), float("-inf")):
        return "?"
    if abs(rate) >= 100:
        return f"{float(f'{rate:.3g}'):,.0f}"
    return f"{rate:.3g}"
