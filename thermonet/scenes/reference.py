"""The scene keys' reference, from the schema (:mod:`thermonet.scenes.schema`): the Markdown
table that ``docs/scenes.md`` contains, and every documented key path.

    python -m thermonet.scenes.reference      # prints the table
"""

from __future__ import annotations

from .schema import NO_DEFAULT, SCHEMA, Named, Table


def reference(spec=SCHEMA, path: str = "") -> list[str]:
    """Markdown rows ``| key | type | default | meaning |`` of every key, depth first."""
    rows = []
    if isinstance(spec, Table):
        if path:
            extra = f" (or {spec.shorthand_doc})" if spec.shorthand_doc else ""
            rows.append(_row(f"[{path}]", f"table{extra}", "optional" if spec.optional else "", spec.doc))
        for name, sub in spec.keys.items():
            rows += reference(sub, f"{path}.{name}" if path else name)
    elif isinstance(spec, Named):
        rows.append(_row(f"[{path}]", f"table of {spec.placeholder}", "", spec.doc))
        rows += reference(spec.entry, f"{path}.{spec.placeholder}")
    else:
        if spec.default is NO_DEFAULT:
            default = "required" if spec.required else ""
        else:
            default = "" if spec.default is None else f"`{_toml(spec.default)}`"
        rows.append(_row(path, spec.type, default, spec.doc))
    return rows


def _row(key: str, type_: str, default: str, doc: str) -> str:
    cells = [f"`{key}`", type_, default, doc]
    return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"


def all_key_paths(spec=SCHEMA, path: str = "") -> list[str]:
    """Every documented key path (``integrator.h``, ``materials.<region>``, ...)."""
    out = []
    if isinstance(spec, Table):
        for name, sub in spec.keys.items():
            p = f"{path}.{name}" if path else name
            out.append(p)
            out += all_key_paths(sub, p)
    elif isinstance(spec, Named):
        out += all_key_paths(spec.entry, f"{path}.{spec.placeholder}")
    return out


def _toml(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, list):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    return repr(v)


if __name__ == "__main__":  # pragma: no cover
    print("| key | type | default | meaning |\n|---|---|---|---|")
    print("\n".join(reference()))
