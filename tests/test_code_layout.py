"""The package's layout rules that a test can keep (docs/architecture.md, "Adding things"): the
output writers see only the user's numbering and no kernel. How long a file or a kernel's
argument list may grow is guidance in that section, not a limit checked here: a count met by
bundling unnamed tuples would be worse than the long list it replaced."""

import ast
import os

PACKAGE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "thermonet")


def sources(folder=PACKAGE):
    for root, _, files in os.walk(folder):
        for f in sorted(files):
            if f.endswith(".py"):
                yield os.path.join(root, f)


def test_output_writers_import_no_kernel():
    found = []
    for p in sources(os.path.join(PACKAGE, "io")):
        for node in ast.walk(ast.parse(open(p, encoding="utf-8").read())):
            if isinstance(node, ast.ImportFrom) and node.module and (
                    "kernels" in node.module.split(".") or "cuda" in node.module.split(".")):
                found.append(f"{os.path.relpath(p, PACKAGE)}:{node.lineno} {node.module}")
    assert not found, found
