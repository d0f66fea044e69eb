"""What the CLI tests share: a folder's files as bytes, and the one error line a bad input gets."""

import os


def snapshot(folder) -> dict:
    """name -> bytes of every file in ``folder``."""
    return {n: open(os.path.join(folder, n), "rb").read() for n in sorted(os.listdir(folder))}


def one_error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.startswith("thermonet: error:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]
