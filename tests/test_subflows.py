"""The explicit step as a schedule of sub-flows: the stage table every backend reads, and a
sub-flow defined outside the package (``tests/push_subflow.py``) running in the CPU kernel
(the CUDA simulator runs it too: ``tests/test_cuda_sim.py``)."""

import os
import sys

import numpy as np
import pytest

import thermonet as tn
from thermonet.explicit.schedule import MAX_FLOWS, STAGE, SubFlow, stage_table
from thermonet.explicit.splitting import CO2, CO4, F10, compose

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from push_subflow import push  # noqa: E402


def rows(table):
    return [(int(c), float(k), float(d)) for c, k, d in zip(table.code, table.kick, table.drift)]


def test_a_splitting_without_flows_shares_its_last_kick_with_the_next_step():
    assert rows(CO2.table) == [(STAGE, 0.5, 1.0)] and CO2.table.carry == 0.5
    assert rows(F10.table) == [(STAGE, 0.0, 0.5), (STAGE, 1.0, 0.5)] and F10.table.carry == 0.0
    assert len(CO4.table.code) == 3 and CO4.table.carry == CO4.kicks[-1]


def test_a_flow_around_a_step_gets_rows_at_both_ends_and_no_shared_kick():
    flow = push([0], [1.0, 0.0, 0.0])
    table = CO2.with_flow(flow, 0.5).table
    # the flow sees the step's start positions (time fraction 0), then the end ones (1)
    assert rows(table) == [(0, 0.5, 0.0), (STAGE, 0.5, 1.0), (STAGE, 0.5, 0.0), (0, 0.5, 1.0)]
    assert table.carry == 0.0


def test_a_composition_with_flows_keeps_them_in_every_substep():
    flow = push([0], [1.0, 0.0, 0.0])
    table = compose(CO2.with_flow(flow, 0.5), (0.25, 0.75), "x", 2, "").table
    # substeps' kicks stay apart (a zero drift), each substep's flows scaled by its γ
    assert rows(table) == [(0, 0.125, 0.0), (STAGE, 0.125, 0.25), (STAGE, 0.125, 0.0),
                           (0, 0.125, 0.25), (0, 0.375, 0.25), (STAGE, 0.375, 0.75), (STAGE, 0.375, 0.0),
                           (0, 0.375, 1.0)]


def test_schedule_errors_name_the_problem():
    flow = push([0], [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="cannot run backwards"):
        compose(CO2.with_heat(True, False), (0.5, 0.5), "x", 2, "")
    many = tuple((0, SubFlow(f"f{i}", flow.update, flow.prepare), 1.0) for i in range(MAX_FLOWS + 1))
    with pytest.raises(ValueError, match=f"at most {MAX_FLOWS} distinct sub-flows"):
        stage_table(CO2.kicks, CO2.drifts, many)
    with pytest.raises(ValueError, match="position 3 outside 0..2"):
        stage_table(CO2.kicks, CO2.drifts, ((3, flow, 1.0),))


def free_lattice():
    net = tn.lattice((2, 2, 2), neighbours=18, jitter=0.1, seed=4)
    rng = np.random.default_rng(4)
    return net, rng.normal(0.0, 1.0, (net.n_nodes, 3)), 300.0 + 100.0 * rng.random(net.n_springs)


def pushed(h=2e-3):
    net, v, temps = free_lattice()
    force = np.array([0.3, -0.2, 0.5])
    integrator = CO2.with_flow(push([0, 5, 7], force), 0.5)
    sim = tn.Simulation(net, temperatures=temps, velocities=v, integrator=integrator, h=h)
    return sim, 3 * force


def test_a_push_defined_in_a_test_file_changes_the_momentum_by_its_impulse_exactly():
    sim, total = pushed()
    p0 = sim.state.momenta.sum(axis=0)
    eta0 = sim.state.entropy.copy()
    sim.run(steps=400, diagnostics_every=100)
    gained = sim.state.momenta.sum(axis=0) - p0
    np.testing.assert_allclose(gained, 400 * 2e-3 * total, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(sim.state.entropy, eta0)  # the push never touches η


def test_a_run_with_a_flow_does_not_depend_on_its_chunks():
    whole, _ = pushed()
    whole.run(steps=30, diagnostics_every=30)
    cut, _ = pushed()
    for n in (1, 12, 17):
        cut.run(steps=n, diagnostics_every=n)
    for field in ("positions", "momenta", "thermal_displacement"):
        np.testing.assert_array_equal(getattr(whole.state, field), getattr(cut.state, field))
