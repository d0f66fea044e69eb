"""Atomic file writes: write a temporary file beside the target, then rename it into place.

A process killed at any moment leaves either the old file or the new one, never a torn one
(``os.replace`` is atomic on POSIX and Windows). Leftover ``*.tmp-<pid>`` files are harmless.
"""

from __future__ import annotations

import os
from contextlib import contextmanager


@contextmanager
def atomic_write(path, mode: str = "wb"):
    """Open a temporary file for writing; on a clean exit rename it to ``path``.

    On an exception the temporary file is removed and ``path`` is left untouched.
    """
    path = os.fspath(path)
    tmp = f"{path}.tmp-{os.getpid()}"
    f = open(tmp, mode, **({} if "b" in mode else {"encoding": "utf-8", "newline": ""}))
    try:
        with f:
            yield f
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
