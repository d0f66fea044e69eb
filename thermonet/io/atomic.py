"""Atomic file writes: write a temporary file beside the target, then rename it into place.

A process killed at any moment leaves either the old file or the new one, never a torn one
(``os.replace`` is atomic on POSIX and Windows). A failed write (a full disk) removes its
temporary file and raises an OSError naming the target file. Leftover ``*.tmp-<pid>`` files of a
killed process are harmless; ``thermonet run --resume`` removes them.
"""

from __future__ import annotations

import errno
import os
from contextlib import contextmanager

import numpy as np


@contextmanager
def _temporary_beside(path):
    """A temporary path beside ``path``, renamed to it on a clean exit, removed on an error."""
    path = os.fspath(path)
    tmp = f"{path}.tmp-{os.getpid()}"
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError) and exc.filename is None:  # a write(): say which file it was
            raise OSError(exc.errno, exc.strerror or str(exc), path) from exc
        raise


@contextmanager
def atomic_write(path, mode: str = "wb"):
    """Open a temporary file for writing; on a clean exit rename it to ``path``.

    On an exception the temporary file is removed and ``path`` is left untouched.
    """
    with _temporary_beside(path) as tmp:
        with open(tmp, mode, **({} if "b" in mode else {"encoding": "utf-8", "newline": ""})) as f:
            yield f


def release_page_cache(path) -> None:
    """Tell the OS that ``path``'s data will not be read again soon (``POSIX_FADV_DONTNEED``).

    On Linux this starts writing its dirty pages back without waiting, and frees the pages that
    are already clean. Output frames are written once and not read back by the run: called on
    each new frame and again on the one before (clean by then), it lets the next frame reuse
    the same memory instead of growing the page cache by a frame's size each time, which on
    virtual machines whose fresh pages fault slowly costs more than the write itself (measured
    here: a 10 MB frame 24–30 ms without, 4–10 ms with). A no-op where the call does not exist.
    """
    advise = getattr(os, "posix_fadvise", None)
    if advise is None:
        return
    try:
        fd = os.open(os.fspath(path), os.O_RDONLY)
    except OSError:
        return
    try:
        advise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
    except OSError:
        pass
    finally:
        os.close(fd)


#: block size that direct (unbuffered) writes are aligned to: buffer address, file offset and
#: length (4096 covers devices with 512- and 4096-byte logical blocks)
DIRECT_ALIGNMENT = 4096


def aligned_buffer(size: int, alignment: int = DIRECT_ALIGNMENT) -> np.ndarray:
    """A zeroed (padded,) uint8 array, padded = ``size`` rounded up to ``alignment``, whose data
    start at a multiple of ``alignment``: what :func:`atomic_write_direct` writes from."""
    padded = -(-int(size) // alignment) * alignment
    storage = np.empty(padded + alignment, dtype=np.uint8)
    storage.fill(0)  # touched now, not at the first frame: fresh pages fault slowly on VMs
    start = -storage.ctypes.data % alignment
    return storage[start:start + padded]


def atomic_write_direct(path, padded: np.ndarray, size: int, direct: bool = True) -> bool:
    """Write the first ``size`` bytes of ``padded`` (from :func:`aligned_buffer`) to ``path``
    atomically, bypassing the page cache where the file system allows it (``O_DIRECT``).

    A direct write moves the bytes from ``padded`` to the device without copying them into the
    page cache: the calling thread mostly waits for the device and uses little CPU, and the
    write leaves no dirty pages behind (``dd`` of 10 MB on the development machine: 5–9 ms
    direct with no measurable CPU time, 30–50 ms through the page cache into fresh pages). The
    whole padded buffer is written, then the file is cut to ``size``. Where ``O_DIRECT`` does
    not exist (macOS, Windows) or the file system refuses it (``EINVAL``: tmpfs before Linux
    6.6, some network and FUSE file systems), the bytes go through the page cache instead.
    ``padded`` must not change until this returns. ``direct=False`` always writes through the
    page cache.

    Returns whether the write was direct.
    """
    if padded.ctypes.data % DIRECT_ALIGNMENT or len(padded) % DIRECT_ALIGNMENT or size > len(padded):
        raise ValueError("atomic_write_direct needs a buffer from aligned_buffer() of at least size bytes")
    direct = getattr(os, "O_DIRECT", 0) if direct else 0
    with _temporary_beside(path) as tmp:
        if direct:
            try:
                fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | direct, 0o644)
            except OSError as error:
                if error.errno != errno.EINVAL:
                    raise
                direct = 0
            else:
                try:
                    _write_all(fd, memoryview(padded))
                    os.ftruncate(fd, size)
                except OSError as error:
                    if error.errno != errno.EINVAL:
                        raise
                    direct = 0  # refused part-way (an unaligned short write): start again buffered
                finally:
                    os.close(fd)
        if not direct:
            with open(tmp, "wb") as f:
                f.write(memoryview(padded)[:size])
    return bool(direct)


def _write_all(fd: int, data: memoryview) -> None:
    while len(data):
        data = data[os.write(fd, data):]


def direct_writes_possible(folder) -> bool:
    """Whether files in ``folder`` can be written with ``O_DIRECT`` (tried on a probe file)."""
    direct = getattr(os, "O_DIRECT", 0)
    if not direct:
        return False
    probe = os.path.join(os.fspath(folder), f".thermonet-direct-probe-{os.getpid()}")
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | direct, 0o644)
    except OSError:
        return False
    try:
        return os.write(fd, memoryview(aligned_buffer(DIRECT_ALIGNMENT))) == DIRECT_ALIGNMENT
    except OSError:
        return False
    finally:
        os.close(fd)
        os.unlink(probe)
