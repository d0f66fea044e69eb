"""A sub-flow defined outside the package, as docs/architecture.md's worked example: a constant
push f on listed nodes, p_a += τ f_a. Nothing in ``thermonet/`` knows of it; the CPU kernel and
both CUDA launch modes run it from its one definition, which is the example's own code: this
module takes the imports and definitions of that code block (``push_update``, ``push``)."""

from __future__ import annotations

import ast
import os
import re

DOC = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "docs", "architecture.md")


def example_code(name: str) -> str:
    """The python block that follows ``<!-- example: name -->`` in docs/architecture.md."""
    with open(DOC, encoding="utf-8") as f:
        text = f.read()
    found = re.search(rf"<!-- example: {re.escape(name)} -->\n```python\n(.*?)\n```", text, re.S)
    if found is None:
        raise LookupError(f"docs/architecture.md has no example {name!r}")
    return found.group(1)


def _definitions(code: str) -> ast.Module:
    tree = ast.parse(code)
    tree.body = [n for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom, ast.FunctionDef))]
    return tree


exec(compile(_definitions(example_code("subflow")), f"{DOC} (example: subflow)", "exec"), globals())
