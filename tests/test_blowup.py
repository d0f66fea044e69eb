"""Blow-up detection inside the compiled loop: the run stops in the first bad step, names it, and
keeps the last good state bit for bit; the energy tolerance stops a run at the diagnostics
cadence; the CLI leaves a checkpoint of the last good state and only complete frames."""

import os

import meshio
import numpy as np
import pytest

import thermonet as tn

#: the run-time guards off: these tests run beyond the stability limit on purpose, to see the
#: in-kernel detector act (the guards would stop the runs first)
UNGUARDED = dict(stability_guard="off", energy_tolerance=None)
OMEGA = np.sqrt(100.0 / 2.0)  # one linear spring, mass 2 on a free end


def linear_spring(h, **kwargs):
    net = tn.Net([[0, 0, 0], [1, 0, 0]], [[0, 1]], masses=[1.0, 2.0], anchored=[0], rest_lengths=[1.0])
    return tn.Simulation(net, model="quadratic", parameters=dict(E=100.0, beta=0.0),
                         momenta=[[0, 0, 0], [0.01, 0, 0]], h=h, **{**UNGUARDED, **kwargs})


@pytest.mark.parametrize("integrator", ["gtr-0", "co2", "f10", "co4"])
def test_the_kernel_stops_in_the_bad_step_and_keeps_the_last_good_state(integrator):
    """Just beyond the stability limit the amplitude grows until the stretch bound is crossed.
    Diagnostics are never taken in between, so only the in-kernel detector can stop it."""
    from thermonet.stability import stability_interval

    h = 1.05 * stability_interval(tn.get_integrator(integrator)) / OMEGA
    sim = linear_spring(h, integrator=integrator)
    with pytest.raises(tn.SimulationError) as info:
        sim.run(steps=100000, diagnostics_every=10**9)
    message = str(info.value)
    bad_step = sim.step + 1
    assert f"in step {bad_step} " in message
    assert "spring 0 (nodes 0–1) has stretch l/l0 =" in message and "Stopped; the state is the last good one" in message
    assert 10 < sim.step < 100000
    state = sim.state
    assert np.isfinite(state.positions).all() and np.isfinite(state.momenta).all()
    # the last good state is exactly what an uninterrupted run of that many steps gives
    fresh = linear_spring(h, integrator=integrator)
    fresh.run(steps=sim.step, diagnostics_every=7)
    np.testing.assert_array_equal(fresh.state.positions, state.positions)
    np.testing.assert_array_equal(fresh.state.momenta, state.momenta)
    np.testing.assert_array_equal(fresh.state.thermal_displacement, state.thermal_displacement)
    assert sim.time == fresh.time
    assert 1e-4 < abs(state.positions[1, 0]) < 1e4  # the last good state is inside the stretch bounds


def test_the_energy_tolerance_stops_the_run_at_the_diagnostics_cadence():
    sim = tn.chain_simulation("co2", h=0.05, energy_tolerance=1e-4)
    with pytest.raises(tn.SimulationError, match=r"energy departed .* by [\d.e-]+ \(relative; tolerance 0.0001\)"):
        sim.run(t_end=10.0, diagnostics_every=10)
    energy = sim.diagnostics.energy
    assert np.all(np.abs(energy - energy[0]) <= 1e-4 * energy[0])  # every kept row is within tolerance
    assert sim.diagnostics.step[-1] == sim.step  # the state is the last stop's
    fresh = tn.chain_simulation("co2", h=0.05)
    fresh.run(steps=sim.step)
    np.testing.assert_array_equal(fresh.state.positions, sim.state.positions)


def test_the_energy_tolerance_rewinds_to_the_last_stop_when_the_backup_lags_behind():
    """The state copy for rewinds is refreshed only every BACKUP_SPAN steps; a rewind then
    replays from the older copy to the last good stop, bit for bit."""
    sim = tn.chain_simulation("co2", h=0.05, energy_tolerance=1e-2)
    assert sim.runner.BACKUP_SPAN > 150
    with pytest.raises(tn.SimulationError, match="rewound to step 140"):
        sim.run(t_end=50.0, diagnostics_every=10)  # fails at step 150; the copy is of step 0
    assert sim.step == 140 and sim.diagnostics.step[-1] == 140
    fresh = tn.chain_simulation("co2", h=0.05)
    fresh.run(steps=140)
    np.testing.assert_array_equal(fresh.state.positions, sim.state.positions)
    np.testing.assert_array_equal(fresh.state.momenta, sim.state.momenta)
    assert sim.time == fresh.time


def test_a_loose_energy_tolerance_does_not_stop_a_good_run():
    sim = tn.chain_simulation("co2", h=0.01, energy_tolerance=1e-3)
    sim.run(t_end=5.0, diagnostics_every=10)
    assert sim.time == pytest.approx(5.0)


def test_stretch_bounds_are_validated():
    with pytest.raises(tn.InputError, match="stretch_bounds must satisfy 0 <= lo < 1 < hi"):
        linear_spring(0.01, stretch_bounds=(2.0, 3.0))
    with pytest.raises(tn.InputError, match="energy_tolerance must be > 0"):
        linear_spring(0.01, energy_tolerance=0.0)


def test_the_cli_keeps_a_checkpoint_of_the_last_good_state_and_complete_frames(tmp_path):
    from thermonet.cli.main import main
    from thermonet.io import load_checkpoint

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    scene = os.path.join(root, "scenes", "chain.toml")
    out = tmp_path / "out"
    code = main(["run", scene, "--out", str(out), "--quiet", "--allow-unstable-step",
                 "--set", "integrator.h=0.3", "--set", "integrator.t_end=999.9",
                 "--set", "integrator.energy_tolerance=false",
                 "--set", "integrator.stretch_bounds=[0.5, 2.0]",
                 "--set", "output.frames_every=1", "--set", "output.checkpoint_every=1000"])
    assert code == tn.SimulationError.exit_code
    state, meta = load_checkpoint(str(out / "chain.checkpoint.npz"))
    assert np.isfinite(state.positions).all()
    lengths = np.linalg.norm(np.diff(state.positions, axis=0), axis=1)
    assert np.all((lengths > 0.5) & (lengths < 2.0))
    # every frame the PVD lists is complete and readable, the last one is the last good state
    pvd = (out / "chain.pvd").read_text()
    files = [line.split('file="')[1].split('"')[0] for line in pvd.splitlines() if 'file="' in line]
    assert files
    for name in files:
        meshio.read(out / name)
    last = meshio.read(out / files[-1])
    np.testing.assert_array_equal(last.points, state.positions)
