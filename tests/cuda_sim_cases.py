"""Runs tiny nets on the CPU backend and on the CUDA backend and saves both, for
``tests/test_cuda_sim.py``. Run as a script in a process of its own, so that the environment
(``NUMBA_ENABLE_CUDASIM=1`` for the simulator) is set before Numba is first imported:

    python tests/cuda_sim_cases.py OUT.npz

For each case ``<name>`` the archive holds ``<name>/<backend>/<field>`` arrays: the final
positions, momenta, Φ, η (user numbering) and the diagnostics columns.
"""

from __future__ import annotations

import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [ROOT, os.path.join(ROOT, "examples"), os.path.join(ROOT, "tests")]  # this checkout's thermonet

import thermonet as tn  # noqa: E402

EXPLICIT = ("gtr-0", "gtr-1", "co2", "f10", "nm2", "co4", "co6")
COLUMNS = ("energy", "kinetic", "internal", "potential", "entropy", "px", "py", "pz", "Lx", "Ly", "Lz",
           "theta_min", "theta_max")
STEPS = 3


def free_net():
    """A free-floating jittered cube (8 nodes, 24 springs), shaken and heated."""
    net = tn.lattice((1, 1, 1), neighbours=18, jitter=0.1, seed=5)
    rng = np.random.default_rng(5)
    return net, rng.normal(0.0, 1.0, (net.n_nodes, 3)), 300.0 + 400.0 * rng.random(net.n_springs)


def quadratic_parameters():
    return dict(E=100.0, beta=0.5, C0=5.0, theta0=300.0, eta0=0.0)


def cases():
    net, v, temps = free_net()
    for model in ("hencky", "quadratic"):
        params = quadratic_parameters() if model == "quadratic" else None
        for name in EXPLICIT:
            yield f"{model}-{name}", lambda b, name=name, model=model, params=params: tn.Simulation(
                net, model=model, parameters=params, temperatures=temps, velocities=v, integrator=name,
                h=2e-3, backend=b)
    # per-spring parameters (not the shared-parameter kernel variant)
    c = np.linspace(80.0, 120.0, net.n_springs)
    yield "hencky-per-spring-co2", lambda b: tn.Simulation(
        net, parameters=dict(c=c), temperatures=temps, velocities=v, integrator="co2", h=2e-3, backend=b)
    from custom_model import build_simulation
    yield "user-model-co2", lambda b: _with_backend(build_simulation("co2", h=2e-3), b)
    yield "thermal-off-co2", lambda b: tn.Simulation(net, velocities=v, thermal=False, integrator="co2",
                                                     h=2e-3, backend=b)
    yield "hencky-co4-two-launch", lambda b: _two_launch(tn.Simulation(
        net, temperatures=temps, velocities=v, integrator="co4", h=2e-3, backend=b))
    from push_subflow import push  # a sub-flow no package file knows of
    pushing = tn.get_integrator("co2").with_flow(push([0, 5, 7], [0.3, -0.2, 0.5]), 0.5)
    yield "push-co2", lambda b: tn.Simulation(net, temperatures=temps, velocities=v, integrator=pushing, h=2e-3,
                                              backend=b)
    yield "push-co2-two-launch", lambda b: _two_launch(tn.Simulation(
        net, temperatures=temps, velocities=v, integrator=pushing, h=2e-3, backend=b))
    chain = tn.chain()
    p = [[0, 0, 0], [20, 10, 10], [10, 20, 10], [0, 10, 0]]
    yield "gravity-chain-f10", lambda b: tn.Simulation(chain, temperatures=[800, 1200, 400], momenta=p,
                                                       gravity=[0, 0, -9.81], integrator="f10", h=1e-2,
                                                       backend=b)


def _two_launch(sim):
    """``sim`` with the CUDA stepper's two launches per stage instead of one fused launch per chunk."""
    if hasattr(sim.stepper, "fused"):
        sim.stepper.fused = False
    return sim


def _with_backend(sim, backend):
    """The example's simulation rebuilt on ``backend`` (same net, model and initial state)."""
    if backend == "cpu":
        return sim
    other = tn.Simulation(sim.net, model=sim.model, parameters={"softening": 0.05}, integrator=sim.integrator,
                          h=sim.h, backend=backend)
    other.load_state(sim.state)
    return other


def record(out, key, sim):
    s = sim.state
    out[f"{key}/positions"] = s.positions
    out[f"{key}/momenta"] = s.momenta
    if s.entropy is not None:
        out[f"{key}/phi"] = s.thermal_displacement
        out[f"{key}/eta"] = s.entropy
    for c in COLUMNS:
        out[f"{key}/{c}"] = sim.diagnostics.column(c)


def main(path):
    out = {}
    for name, make in cases():
        for backend in ("cpu", "cuda"):
            sim = make(backend)
            out[f"{name}/{backend}/eta0"] = sim.state.entropy if sim.system.thermal else np.empty(0)
            out[f"{name}/{backend}/positions0"] = sim.state.positions
            sim.run(steps=STEPS, diagnostics_every=STEPS)
            record(out, f"{name}/{backend}", sim)
    # chunks: 1 + 2 steps, with a frame-style read of the state in between, equal 3 steps at once
    net, v, temps = free_net()
    sim = tn.Simulation(net, temperatures=temps, velocities=v, integrator="co4", h=2e-3, backend="cuda")
    sim.run(steps=1, diagnostics_every=1)
    sim.spring_fields()
    sim.run(steps=2, diagnostics_every=2)
    record(out, "chunks/cuda", sim)
    # a state loaded between runs is uploaded; the device must not overwrite it with its own
    for backend in ("cpu", "cuda"):
        sim = tn.Simulation(net, temperatures=temps, velocities=v, integrator="co2", h=2e-3, backend=backend)
        sim.run(steps=2, diagnostics_every=2)
        state = sim.state
        state.momenta = -state.momenta
        sim.load_state(state)
        sim.run(steps=2, diagnostics_every=2)
        record(out, f"reload/{backend}", sim)
    blowups(out)
    np.savez(path, **out)


#: (name, integrator, fused launch) of the blow-up cases: one linear spring at 1.2× its stability
#: limit, whose stretch bound is crossed in the 13th-14th step
BLOWUPS = (("co2", "co2", True), ("co2-two-launch", "co2", False), ("co4", "co4", True),
           ("f10-two-launch", "f10", False), ("gtr-0", "gtr-0", True))


def blowups(out):
    """Each blow-up case on both backends, run in chunks of 5 steps until it stops: the step it
    stopped at, its message and the state it kept."""
    from thermonet.stability import stability_interval

    for name, integrator, fused in BLOWUPS:
        h = 1.2 * stability_interval(tn.get_integrator(integrator)) / np.sqrt(100.0 / 2.0)
        for backend in ("cpu", "cuda"):
            net = tn.Net([[0, 0, 0], [1, 0, 0]], [[0, 1]], masses=[1.0, 2.0], anchored=[0], rest_lengths=[1.0])
            # the run-time guards off: only the in-kernel detector is to stop these runs
            sim = tn.Simulation(net, model="quadratic", parameters=dict(E=100.0, beta=0.0),
                                momenta=[[0, 0, 0], [0.01, 0, 0]], h=h, integrator=integrator, backend=backend,
                                stability_guard="off", energy_tolerance=None)
            if backend == "cuda":
                sim.stepper.fused = fused
            message = ""
            try:
                sim.run(steps=1000, diagnostics_every=5)
            except tn.SimulationError as exc:
                message = str(exc)
            key = f"blowup-{name}/{backend}"
            out[f"{key}/step"] = np.array(sim.step)
            out[f"{key}/message"] = np.array(message)
            record(out, key, sim)


if __name__ == "__main__":
    from simulator_pace import pace

    pace()
    main(sys.argv[1])
