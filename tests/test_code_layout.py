"""The package's layout rules (docs/architecture.md): kernels take a few records, not long
argument lists; files stay small enough to read; output writers see only the user's numbering
and no kernel."""

import ast
import os

import pytest

PACKAGE = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "thermonet")
MAX_KERNEL_ARGUMENTS = 10
MAX_FILE_LINES = 550


def sources(folder=PACKAGE):
    for root, _, files in os.walk(folder):
        for f in sorted(files):
            if f.endswith(".py"):
                yield os.path.join(root, f)


def module_functions(path):
    tree = ast.parse(open(path, encoding="utf-8").read())
    return [n for n in tree.body if isinstance(n, ast.FunctionDef)]


@pytest.mark.parametrize("folder", ["kernels", "cuda"])
def test_no_kernel_takes_more_than_ten_arguments(folder):
    long = [f"{os.path.relpath(p, PACKAGE)}:{fn.lineno} {fn.name} ({len(fn.args.args)})"
            for p in sources(os.path.join(PACKAGE, folder)) for fn in module_functions(p)
            if len(fn.args.args) + len(fn.args.kwonlyargs) > MAX_KERNEL_ARGUMENTS]
    assert not long, long


def test_no_source_file_is_longer_than_the_limit():
    long = [f"{os.path.relpath(p, PACKAGE)} ({n})" for p in sources()
            if (n := sum(1 for _ in open(p, encoding="utf-8"))) > MAX_FILE_LINES]
    assert not long, long


def test_output_writers_import_no_kernel():
    found = []
    for p in sources(os.path.join(PACKAGE, "io")):
        for node in ast.walk(ast.parse(open(p, encoding="utf-8").read())):
            if isinstance(node, ast.ImportFrom) and node.module and (
                    "kernels" in node.module.split(".") or "cuda" in node.module.split(".")):
                found.append(f"{os.path.relpath(p, PACKAGE)}:{node.lineno} {node.module}")
    assert not found, found
