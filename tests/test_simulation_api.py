"""What the Simulation offers scripts besides running: probes attached with ``add_probes`` and a
run continued with ``RunOutput.resume``, the same bits as an uninterrupted run, as the CLI gets
them; and the wiring it holds (a Runner, an assembled stepper)."""

import os

import numpy as np

import thermonet as tn
from thermonet.driver import Runner
from thermonet.io import RunOutput
from thermonet.probes import Probe

CHAIN = dict(model="hencky", parameters=dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0),
             temperatures=[800.0, 1200.0, 400.0], momenta=[[0, 0, 0], [20, 10, 10], [10, 20, 10], [0, 10, 0]],
             integrator="co2", h=0.01)


def _sim():
    sim = tn.Simulation(tn.chain(), **CHAIN)
    sim.add_probes({"theta": Probe([0, 1, 2], "temperature"), "tip": Probe([3], "displacement", every=5)})
    return sim


def test_a_script_resumes_a_run_with_its_probes_bit_for_bit(tmp_path):
    whole = _sim()
    whole.run(steps=300, diagnostics_every=10)

    first = _sim()
    out = RunOutput.for_simulation(first, tmp_path / "run", frames_every=0, diagnostics_every=10,
                                   checkpoint_every=100)
    first.run(steps=200, diagnostics_every=out.diagnostics_every, observers=out.observers())
    first.probes.to_csv(out.folder)

    again = _sim()
    out = RunOutput.for_simulation(again, tmp_path / "run", frames_every=0, diagnostics_every=10,
                                   checkpoint_every=100, resume=True)
    out.resume(os.path.join(out.folder, "run.checkpoint.npz"))
    assert again.step == 200
    again.run(steps=100, diagnostics_every=out.diagnostics_every, observers=out.observers())

    np.testing.assert_array_equal(again.state.positions, whole.state.positions)
    np.testing.assert_array_equal(again.state.entropy, whole.state.entropy)
    assert again.probes.series == whole.probes.series
    assert [r["step"] for r in again.diagnostics.rows] == [r["step"] for r in whole.diagnostics.rows]


def test_the_simulation_holds_a_runner_and_declares_what_it_reads():
    sim = _sim()
    assert isinstance(sim.runner, Runner) and not isinstance(sim, Runner)
    assert sim.loads is None and sim.conduction_cycle is None and sim.runner.backup is None
    sim.run(steps=3)
    assert [r[0] for r in sim.probes.series["tip"]] == [0, 3]  # every 5 steps and at the run's end
