"""docs/architecture.md's worked examples run as written: one per kind of addition (a sub-flow, an
explicit table, an implicit scheme, a heat method, a load kind), each a python block after a
``<!-- example: kind -->`` line, executed here on the tiny nets it builds. The blocks check their
own results; the registries they add to are restored afterwards. Kernel variants are those other
tests compile anyway (the sub-flow under tests/push_subflow.py's name, which takes its definitions
from the same block)."""

import os
import re
import sys

import pytest

from thermonet.integrators import base as integrator_registry
from thermonet.implicit.core import schemes as scheme_registry

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from push_subflow import DOC, example_code  # noqa: E402

KINDS = ("subflow", "explicit-table", "implicit-scheme", "heat-method", "load-kind")


def test_the_architecture_doc_has_one_example_per_kind_of_addition():
    with open(DOC, encoding="utf-8") as f:
        found = re.findall(r"<!-- example: ([\w-]+) -->\n```python\n", f.read())
    assert sorted(found) == sorted(KINDS)


@pytest.mark.parametrize("kind", KINDS)
def test_a_worked_example_runs_as_written(kind):
    integrators = dict(integrator_registry._REGISTRY)
    schemes = dict(scheme_registry._SCHEMES)
    # the sub-flow under the module name its definitions have in push_subflow: the same kernel
    namespace = {"__name__": "push_subflow" if kind == "subflow" else f"architecture_example_{kind}"}
    try:
        exec(compile(example_code(kind), f"{DOC} (example: {kind})", "exec"), namespace)
    finally:
        integrator_registry._REGISTRY.clear()
        integrator_registry._REGISTRY.update(integrators)
        scheme_registry._SCHEMES.clear()
        scheme_registry._SCHEMES.update(schemes)
