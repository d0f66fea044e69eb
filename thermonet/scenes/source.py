"""Reading a scene file: TOML parsing, ``--set KEY=VALUE`` overrides, and where a key is.

``tomllib`` (``tomli`` before Python 3.11) gives no positions, so :func:`key_lines` scans the
text for table headers and assignments to find the line of each dotted key path.
"""

from __future__ import annotations

import re
import sys

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

from ..errors import InputError


class SceneError(InputError):
    """A scene that cannot be used; the message starts with ``file:line: key.path:``."""

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None, key: str | None = None):
        self.file, self.line, self.key, self.problem = file, line, key, message
        where = file or "<scene>"
        if line:
            where += f":{line}"
        super().__init__(f"{where}: {key}: {message}" if key else f"{where}: {message}")


def parse_toml(text: str, file: str) -> dict:
    """The TOML document ``text`` as a dict; a syntax error names the file and line."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = str(exc)
        m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
        line = int(m.group(1)) if m else None
        msg = re.sub(r"\s*\(at line \d+, column \d+\)", "", msg)
        raise SceneError(f"not valid TOML: {msg}", file=file, line=line) from None


_HEADER = re.compile(r"^\s*\[\[?\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_ASSIGN = re.compile(r"^\s*([A-Za-z0-9_\-\"'. ]+?)\s*=")
_INLINE_KEY = re.compile(r"[{,]\s*([A-Za-z0-9_\-\"']+)\s*=")


def _split_key(key: str) -> tuple[str, ...]:
    return tuple(part.strip().strip("\"'") for part in key.split("."))


def key_lines(text: str) -> dict[tuple[str, ...], int]:
    """Line number (1-based) of each table header and assigned key path in a TOML text."""
    lines: dict[tuple[str, ...], int] = {}
    table: tuple[str, ...] = ()
    for number, line in enumerate(text.splitlines(), start=1):
        header = _HEADER.match(line)
        if header:
            table = _split_key(header.group(1))
            for i in range(1, len(table) + 1):  # [material.plate] is also where "material" is
                lines.setdefault(table[:i], number)
            continue
        assign = _ASSIGN.match(line)
        if assign:
            path = table + _split_key(assign.group(1))
            lines.setdefault(path, number)
            for inner in _INLINE_KEY.finditer(line[assign.end():]):
                lines.setdefault(path + _split_key(inner.group(1)), number)
    return lines


def parse_override(item: str) -> tuple[tuple[str, ...], object]:
    """``"integrator.h=1e-3"`` -> (("integrator", "h"), 0.001). The value is read as TOML
    (numbers, booleans, arrays, quoted strings); anything else is taken as a bare string."""
    if "=" not in item:
        raise SceneError(f"--set {item!r}: expected KEY=VALUE, e.g. --set integrator.h=1e-4")
    key, value = item.split("=", 1)
    path = _split_key(key.strip())
    if not all(path):
        raise SceneError(f"--set {item!r}: empty part in key path {key.strip()!r}")
    try:
        parsed = tomllib.loads(f"v = {value.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        parsed = value.strip()
    return path, parsed


def apply_overrides(data: dict, overrides) -> set[tuple[str, ...]]:
    """Set each ``KEY=VALUE`` of ``overrides`` in ``data`` (in place); returns the paths set."""
    done = set()
    for item in overrides or ():
        path, value = parse_override(item)
        node = data
        for i, part in enumerate(path[:-1]):
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                raise SceneError(f"--set {item!r}: {'.'.join(path[:i + 1])} is not a table")
            node = child
        node[path[-1]] = value
        done.add(path)
    return done
