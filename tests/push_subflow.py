"""A sub-flow defined outside the package, as docs/architecture.md's worked example: a constant
push f on listed nodes, p_a += τ f_a. Nothing in ``thermonet/`` knows of it; the CPU kernel and
both CUDA launch modes run it from its one definition here."""

from __future__ import annotations

import numpy as np

from thermonet.integrators.schedule import SubFlow


def push_update(i, data, tau, t, x, p, phi, eta):
    """Element i of the push: node data[0][i] (internal numbering) gets tau × force data[1][i]."""
    a = data[0][i]
    p[a, 0] += tau * data[1][i, 0]
    p[a, 1] += tau * data[1][i, 1]
    p[a, 2] += tau * data[1][i, 2]


def push(nodes, force) -> SubFlow:
    """The push of ``force`` (3,) on each of the user's ``nodes``."""
    nodes = np.asarray(nodes, dtype=np.int64)
    force = np.asarray(force, dtype=np.float64)

    def prepare(system):
        return system.layout.node_rank[nodes].astype(np.int64), np.tile(force, (len(nodes), 1))

    return SubFlow("push", push_update, prepare, "a constant force on listed nodes")
