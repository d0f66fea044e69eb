"""The output folder of a run: whose files are in it, refusing to overwrite them silently,
removing them on request, and cleaning up after a killed run.

A run's files are ``<name>.pvd``, its ``<name>_NNNNNN.vtu`` frames (over MPI processes
``<name>_NNNNNN.pvtu`` and its pieces ``<name>_NNNNNN_p<rank>.vtu``), ``diagnostics.csv``,
``probe_<name>.csv``, ``summary.json``, ``<name>.checkpoint.npz`` (over MPI processes with the
folder of its pieces ``<name>.checkpoint.pieces``), ``scene-as-run.toml``, ``run.log`` and, after
a process was killed while writing, the temporary files of atomic writes (``*.tmp-<pid>``,
``diagnostics.csv.tmp``).
"""

from __future__ import annotations

import os
import re
import shutil

from ..errors import InputError, OutputError

_RUN_FILE = re.compile(r"(.+\.pvd|.+_\d{6}\.vtu|.+_\d{6}_p\d+\.vtu|.+_\d{6}\.pvtu|.+\.checkpoint\.npz"
                       r"|diagnostics\.csv|summary\.json|probe_.+\.csv|scene-as-run\.toml|run\.log)$")
_TEMPORARY = re.compile(r".+\.tmp(-\d+)?$")
_RUN_FOLDER = re.compile(r".+\.checkpoint\.pieces$")


def run_files(folder) -> list[str]:
    """Names of the files in ``folder`` that a run writes (temporaries included) and of the
    folder of its checkpoint's pieces, sorted."""
    try:
        names = os.listdir(folder)
    except OSError:
        return []
    return sorted(n for n in names if ((_RUN_FILE.match(n) or _TEMPORARY.match(n))
                                       and os.path.isfile(os.path.join(folder, n)))
                  or (_RUN_FOLDER.match(n) and os.path.isdir(os.path.join(folder, n))))


def stale_temporaries(folder) -> list[str]:
    """Names of leftover temporary files of atomic writes in ``folder`` (a killed run's)."""
    return [n for n in run_files(folder) if _TEMPORARY.match(n)]


def check_output_folder(folder, *, overwrite: bool = False) -> list[str]:
    """Whether ``folder`` may take a new run, changing nothing: refuses (an :class:`InputError`,
    naming the folder) a path that is not a folder, or a folder holding a previous run's files
    unless ``overwrite``. Returns the names of those files."""
    folder = os.fspath(folder)
    if os.path.exists(folder) and not os.path.isdir(folder):
        raise InputError(f"--out {folder}: exists and is not a folder")
    previous = run_files(folder)
    if previous and not overwrite:
        shown = ", ".join(previous[:4]) + (f", … ({len(previous)} files)" if len(previous) > 4 else "")
        raise InputError(f"--out {folder}: holds the output of a previous run ({shown}); pass --overwrite to "
                         f"replace it (its files are deleted), or continue it with: thermonet run --resume {folder}")
    return previous


def prepare_output_folder(folder, *, overwrite: bool = False) -> list[str]:
    """Make ``folder`` ready for a new run. Refuses what :func:`check_output_folder` refuses;
    with ``overwrite``, removes a previous run's files (and only those). Returns the names removed.
    ``thermonet run`` calls it only once the new run is built and its step checked, so that a
    scene that fails its checks leaves the previous run untouched."""
    folder = os.fspath(folder)
    previous = check_output_folder(folder, overwrite=overwrite)
    try:
        os.makedirs(folder, exist_ok=True)
        check_writable(folder)
        for name in previous:
            path = os.path.join(folder, name)
            if os.path.isdir(path):  # (a checkpoint's pieces)
                shutil.rmtree(path)
            else:
                os.unlink(path)
    except OSError as exc:
        raise OutputError(f"--out {folder}: cannot write the output folder: {describe_os_error(exc)}") from None
    return previous


def fresh_folder(base) -> str:
    """``base`` if it holds no previous run's files, else the first of ``base-2``, ``base-3``, …
    that holds none (a missing folder or one with other files only; not a file)."""
    base = os.fspath(base).rstrip(os.sep) or os.sep
    candidate, number = base, 1
    while (os.path.exists(candidate) and not os.path.isdir(candidate)) or run_files(candidate):
        number += 1
        candidate = f"{base}-{number}"
    return candidate


def check_writable(folder) -> None:
    """Create and remove a probe file in ``folder``; raises the OSError of a folder that cannot
    be written (read-only file system, no permission; as root, permission bits do not stop it)."""
    probe = os.path.join(os.fspath(folder), f".thermonet-write-probe-{os.getpid()}")
    try:
        with open(probe, "wb"):
            pass
        os.unlink(probe)
    except OSError as exc:  # the folder's problem, not the probe's: no file name
        raise OSError(exc.errno, exc.strerror or str(exc)) from None


def remove_stale_temporaries(folder) -> list[str]:
    """Remove a killed run's temporary files from ``folder`` (before resuming); returns their names."""
    removed = []
    for name in stale_temporaries(folder):
        try:
            os.unlink(os.path.join(folder, name))
            removed.append(name)
        except OSError:
            pass
    return removed


def describe_os_error(exc: OSError) -> str:
    """``file: reason`` of an OSError, the temporary-file suffix of an atomic write removed."""
    name = exc.filename
    reason = exc.strerror or str(exc)
    if name is None:
        return reason
    name = re.sub(r"\.tmp(-\d+)?$", "", os.fspath(name))
    return f"{name}: {reason}"
