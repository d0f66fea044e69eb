"""Heat flow (conduction with baths and sources, thermal waves) on the CUDA backend against the
CPU backend (docs/theory.md §5–6; docs/gpu.md).

Under Numba's CUDA simulator: this file, run as a script in a process of its own with
``NUMBA_ENABLE_CUDASIM=1`` (the variable must be set before Numba is imported), runs tiny nets on
both backends and both launch modes and saves the results; the tests compare them. The device
runs the CPU's per-element functions (``thermonet/heat/exchange.py``) in the same order per
element (the CPU runs set to sweep conduction in the GPU's order: one junction node per block),
but not bit for bit: the CPU's entropy update uses a vectorizing ``log``
(``thermonet.kernels.fastmath``), the device ``math.log``, and the CPU's kick after the sweeps
takes the swept θ where the device evaluates θ(l, η) (docs/gpu.md). The tests allow
``STATE_RTOL`` (1e-13) of each quantity's scale. On a real GPU (``gpu`` tests) fused
multiply-adds change the last bits of each step too: 1e-10 there.

    python tests/test_cuda_heat_sim.py OUT.npz     # with NUMBA_ENABLE_CUDASIM=1
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)  # this checkout's thermonet, also when run as a script

import thermonet as tn  # noqa: E402
from thermonet.explicit.cuda import gpu_available  # noqa: E402
from thermonet.heat import Bath, Source  # noqa: E402
from thermonet.timefunctions import TimeFunction  # noqa: E402

HAVE_NUMBA_CUDA = importlib.util.find_spec("numba_cuda") is not None
QUIET = dict(stability_guard="off", energy_tolerance=None)
STEPS = 3
H = 2e-3
SOURCE_POWER = 20.0
SOURCE_SPRINGS = [3, 5]
STATE_RTOL = 1e-13
DIAG_RTOL = 1e-12
HEAT_COLUMNS = ("entropy_produced", "heat_in", "entropy_in", "energy_balance", "entropy_balance")
COLUMNS = ("energy", "kinetic", "internal", "entropy", "px", "Lz", "theta_min", "theta_max") + HEAT_COLUMNS
LOGS = ("produced", "entry_heat", "entry_flux", "theta", "theta_ok", "length", "pending_eta", "pending_produced",
        "pending_theta")


def small_net(shape=(1, 1, 1), neighbours=6, seed=5):
    """A free jittered lattice (the cube: 8 nodes, 12 springs), shaken, with a spread of
    temperatures."""
    net = tn.lattice(shape, neighbours=neighbours, jitter=0.1, seed=seed)
    rng = np.random.default_rng(seed)
    return net, rng.normal(0.0, 1.0, (net.n_nodes, 3)), 300.0 + 400.0 * rng.random(net.n_springs)


def conduction_sim(backend, fused=True, bath=None, integrator="co2", net=None, every=1, entries=True):
    """Conduction with a bath on nodes 0, 1 (a sine in time unless ``bath`` is a number) and a
    source on springs 3, 5 (neither unless ``entries``), every ``every`` steps (k, or (k, j): j
    sub-sweeps); on the CPU swept in the GPU's order."""
    every, sweeps = every if isinstance(every, tuple) else (every, 1)
    net, v, temps = net or small_net()
    temperature = TimeFunction.sine(50.0, 3.0, 0.0, 500.0) if bath is None else bath
    boundary = dict(baths={"hot": Bath([0, 1], temperature)},
                    sources={"s": Source(SOURCE_SPRINGS, SOURCE_POWER)}) if entries else {}
    sim = tn.Simulation(net, parameters=dict(c=100, beta=1.0, C0=1.0, theta0=300, g=0.5), temperatures=temps,
                        velocities=v, integrator=integrator, h=H, backend=backend, conduction_every=every,
                        conduction_sweeps=sweeps, **boundary, **QUIET)
    sim.system.heat.use_order_of("cuda")
    return _mode(sim, fused)


def bare_conduction_sim(backend, fused=True, bath=None, net=None):
    """:func:`conduction_sim` without baths and sources."""
    return conduction_sim(backend, fused, bath=bath, net=net, entries=False)


def waves_sim(backend, fused=True, integrator="co4", net=None):
    net, v, temps = net or small_net()
    sim = tn.Simulation(net, parameters=dict(c=100, beta=1.0, C0=1.0, theta0=300, g_star=0.3), temperatures=temps,
                        velocities=v, integrator=integrator, h=H, backend=backend, **QUIET)
    return _mode(sim, fused)


def blowup_sim(backend, fused=True):
    """A chain of two springs from an anchor, far over CO2's stability limit, with conduction,
    a bath at the anchor and a source: the stretch bound is crossed in the 14th step."""
    net = tn.Net([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1], [1, 2]], masses=[1.0, 1.0, 1.0], anchored=[0],
                 rest_lengths=[1.0, 1.0])
    omega = np.sqrt(100.0 * (3 + np.sqrt(5)) / 2)  # the chain's highest frequency, linearized
    from thermonet.stability import stability_interval

    h = 6.0 * stability_interval(tn.get_integrator("co2")) / omega
    sim = tn.Simulation(net, parameters=dict(c=100, beta=0.0, C0=1.0, theta0=300, g=2.0), temperatures=[400, 300],
                        momenta=[[0, 0, 0], [0, 0, 0], [0.01, 0, 0]], h=h, integrator="co2", backend=backend,
                        baths={"cold": Bath([0], 250.0)}, sources={"s": Source([1], 50.0)}, conduction_every=1,
                        **QUIET)
    sim.system.heat.use_order_of("cuda")
    return _mode(sim, fused)


def _mode(sim, fused):
    if hasattr(sim.stepper, "fused"):
        sim.stepper.fused = fused
    return sim


#: name -> (make(backend, fused), fused)
CASES = {
    "conduction": (conduction_sim, True),
    "conduction-two-launch": (conduction_sim, False),
    # (a cycle of STEPS steps, each boundary swept twice: sub-sweeps)
    "conduction-multirate": (lambda backend, fused: conduction_sim(backend, fused, every=(STEPS, 2)), True),
    "conduction-multirate-two-launch": (lambda backend, fused: conduction_sim(backend, fused, every=(STEPS, 2)),
                                        False),
    # (no baths or sources: at a cycle boundary the two half sweeps' meeting colours run as one phase)
    "conduction-bare": (lambda backend, fused: conduction_sim(backend, fused, entries=False), True),
    "conduction-bare-two-launch": (lambda backend, fused: conduction_sim(backend, fused, entries=False), False),
    "waves": (waves_sim, True),
    "waves-two-launch": (waves_sim, False),
}
BLOWUPS = {"blowup": True, "blowup-two-launch": False}


def record(out, key, sim):
    s = sim.state
    for field in ("positions", "momenta", "thermal_displacement", "entropy"):
        out[f"{key}/{field}"] = getattr(s, field)
    for name in LOGS:
        out[f"{key}/{name}"] = s.extra["heat"][name]
    d = sim.diagnostics
    for c in COLUMNS + (("wave_energy",) if sim.system.heat.waves else ("heat_hot", "heat_s")):
        if c in d.rows[-1]:
            out[f"{key}/col/{c}"] = d.column(c)


def main(path):
    out = {}
    for name, (make, fused) in CASES.items():
        for backend in ("cpu", "cuda"):
            sim = make(backend, fused)
            out[f"{name}/{backend}/entropy0"] = sim.state.entropy
            sim.run(steps=STEPS, diagnostics_every=STEPS)
            record(out, f"{name}/{backend}", sim)
    # a run cut into calls (a frame-style read between them), and a fused call cut into launches
    # of one step, equal one call bit for bit (constant bath: the calls' start times are then
    # irrelevant); the sweeps continue from the stored temperatures
    sim = conduction_sim("cuda", True, bath=500.0)
    sim.run(steps=2, diagnostics_every=2)
    record(out, "whole/cuda", sim)
    sim = conduction_sim("cuda", True, bath=500.0)
    sim.run(steps=1, diagnostics_every=1)
    sim.spring_fields()
    sim.run(steps=1, diagnostics_every=1)
    record(out, "calls/cuda", sim)
    sim = conduction_sim("cuda", True, bath=500.0)
    sim.stepper.FUSED_MAX_STEPS = 1
    sim.run(steps=2, diagnostics_every=2)
    record(out, "launches/cuda", sim)
    sim = conduction_sim("cuda", False, bath=500.0)
    sim.run(steps=1, diagnostics_every=1)
    sim.run(steps=1, diagnostics_every=1)
    record(out, "calls-two-launch/cuda", sim)
    # multirate: a cycle of 2 steps with 3 sub-sweeps in one call, and cut inside the cycle
    sim = conduction_sim("cuda", True, bath=500.0, every=(2, 3))
    sim.run(steps=2, diagnostics_every=2)
    record(out, "whole-multirate/cuda", sim)
    sim = conduction_sim("cuda", True, bath=500.0, every=(2, 3))
    sim.runner.advance(1)
    sim.runner.advance(1)
    sim.record_diagnostics()
    record(out, "calls-multirate/cuda", sim)
    # the same without baths and sources, cut into calls of 1 and 2 steps (two launches) or not
    sim = conduction_sim("cuda", True, entries=False)
    sim.run(steps=3, diagnostics_every=3)
    record(out, "whole-bare/cuda", sim)
    sim = conduction_sim("cuda", False, entries=False)
    sim.run(steps=1, diagnostics_every=1)
    sim.spring_fields()
    sim.run(steps=2, diagnostics_every=2)
    record(out, "calls-bare/cuda", sim)
    # a call that ends a cycle keeps its update pending (theta_ok 2): the other backend continues it
    sim = conduction_sim("cpu", True, bath=500.0)
    sim.run(steps=4, diagnostics_every=2)
    record(out, "cross-whole/cpu", sim)
    for first, second in (("cuda", "cpu"), ("cpu", "cuda")):
        sim = conduction_sim(first, False, bath=500.0)
        sim.run(steps=2, diagnostics_every=2)
        out[f"cross/{first}-{second}/theta_ok_between"] = sim.state.extra["heat"]["theta_ok"].copy()
        then = conduction_sim(second, False, bath=500.0)
        then.load_state(sim.state)
        then.run(steps=2, diagnostics_every=2)
        record(out, f"cross/{first}-{second}", then)
    out["phase-launches"] = np.array([phase_launches(4), phase_launches(4, calls=2)])
    out["phase-launches-bare"] = np.array([phase_launches(4, entries=False), phase_launches(4, calls=2, entries=False)])
    for name, fused in BLOWUPS.items():
        for backend in ("cpu", "cuda"):
            sim = blowup_sim(backend, fused)
            message = ""
            try:
                sim.run(steps=1000, diagnostics_every=5)
            except tn.SimulationError as exc:
                message = str(exc)
            key = f"{name}/{backend}"
            out[f"{key}/step"] = np.array(sim.step)
            out[f"{key}/message"] = np.array(message)
            record(out, key, sim)
        # the last good state without a blow-up: the CPU backend run up to it
        sim = blowup_sim("cpu")
        sim.run(steps=int(out[f"{name}/cpu/step"]), diagnostics_every=5)
        record(out, f"{name}/good", sim)
    np.savez(path, **out)


def phase_launches(steps, calls=1, entries=True):
    """The two-launch path's heat launches in the last of ``calls`` calls of ``steps`` CO2 steps
    with conduction every step: (temperature passes, start phases, star colours, boundary
    phases, finish phases, star colours of the net)."""
    from thermonet.heat.cuda import BLOCKS, BOUNDARY, FINISH, START, _phase_span

    sim = conduction_sim("cuda", False, bath=500.0, entries=entries)
    stepper, heat = sim.stepper, sim.stepper._heat
    counts = dict.fromkeys(("temperature", START, BLOCKS, BOUNDARY, FINISH), 0)
    launch = stepper._launch

    def counting(kernel, blocks, threads, *args):
        name = getattr(kernel, "py_func", kernel).__name__
        if name.startswith("_temperature_kernel"):
            counts["temperature"] += 1
        elif name.startswith("_sweep_kernel"):
            code, phase = args[0], args[1]
            counts[_phase_span(code, phase, heat.colour_ptr, heat.star_colour_ptr, heat.n_bound, heat.m, 1)[0]] += 1
        launch(kernel, blocks, threads, *args)

    for call in range(calls):
        if call == calls - 1:
            stepper._launch = counting
        sim.run(steps=steps, diagnostics_every=steps)
    return [counts[k] for k in ("temperature", START, BLOCKS, BOUNDARY, FINISH)] + [len(heat.star_colour_ptr) - 1]


# ----------------------------------------------------------------------------------------------
# the tests


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    if not HAVE_NUMBA_CUDA:
        pytest.skip("numba-cuda is not installed (pip install '.[cuda]')")
    path = str(tmp_path_factory.mktemp("cuda_heat") / "cases.npz")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    proc = subprocess.run([sys.executable, os.path.abspath(__file__), path], env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    with np.load(path) as data:
        return dict(data)


def _close(a, b, rtol):
    scale = max(float(np.max(np.abs(a), initial=0.0)), 1e-300)
    return float(np.max(np.abs(a - b), initial=0.0)) <= rtol * scale


def assert_states_agree(runs, a, b, rtol=STATE_RTOL):
    for field in ("positions", "momenta", "thermal_displacement", "entropy") + LOGS:
        x, y = runs[f"{a}/{field}"], runs[f"{b}/{field}"]
        if field == "theta_ok":  # 2 on both where a call ended with a reverse sweep, its update pending
            assert x[0] == y[0], field
        elif field in ("produced", "pending_produced"):  # per spring a change of η: rounded at η's scale
            scale = max(float(np.abs(runs[f"{a}/entropy"]).max()), 1e-300)
            assert float(np.max(np.abs(x - y), initial=0.0)) <= rtol * scale, field
        else:
            assert _close(x, y, rtol), field


@pytest.mark.parametrize("case", list(CASES))
def test_heat_flow_on_the_device_equals_the_cpu(runs, case):
    cpu, gpu = f"{case}/cpu", f"{case}/cuda"
    assert not np.array_equal(runs[f"{gpu}/entropy"], runs[f"{gpu}/entropy0"])  # heat moved
    assert_states_agree(runs, cpu, gpu)
    for c in COLUMNS + ("wave_energy", "heat_hot", "heat_s"):
        if f"{cpu}/col/{c}" in runs:
            a, b = runs[f"{cpu}/col/{c}"], runs[f"{gpu}/col/{c}"]
            assert np.all(np.abs(a - b) <= DIAG_RTOL * max(float(np.max(np.abs(a))), 1.0)), c


@pytest.mark.parametrize("case", ["conduction", "conduction-two-launch", "conduction-multirate",
                                  "conduction-multirate-two-launch"])
def test_baths_and_sources_give_their_heat_on_the_device(runs, case):
    gpu = f"{case}/cuda"
    # a source gives P τ per spring and half step, exactly
    assert runs[f"{gpu}/col/heat_s"][-1] == pytest.approx(SOURCE_POWER * len(SOURCE_SPRINGS) * STEPS * H, rel=1e-12)
    assert runs[f"{gpu}/col/heat_hot"][-1] != 0.0
    assert runs[f"{gpu}/produced"].sum() > 0.0  # (per spring it is ΔS less what entries brought: any sign)
    assert abs(runs[f"{gpu}/col/entropy_balance"][-1]) < 1e-12 * abs(runs[f"{gpu}/col/entropy"][-1])
    # the call ended a cycle: the reverse half sweep's entropy update pending for the next call
    assert runs[f"{gpu}/theta_ok"][0] == 2.0


@pytest.mark.parametrize("case", ["waves", "waves-two-launch"])
def test_thermal_waves_keep_the_total_entropy_on_the_device(runs, case):
    eta, eta0 = runs[f"{case}/cuda/entropy"], runs[f"{case}/cuda/entropy0"]
    assert abs(eta.sum() - eta0.sum()) <= 1e-12 * abs(eta).sum()
    assert runs[f"{case}/cuda/col/wave_energy"][-1] > 0.0


@pytest.mark.parametrize("chunked, whole", [("calls", "whole"), ("launches", "whole"),
                                           ("calls-multirate", "whole-multirate"), ("calls-bare", "whole-bare")])
def test_a_run_cut_into_calls_or_launches_equals_one_call(runs, chunked, whole):
    for field in ("positions", "momenta", "thermal_displacement", "entropy") + LOGS:
        np.testing.assert_array_equal(runs[f"{chunked}/cuda/{field}"], runs[f"{whole}/cuda/{field}"], err_msg=field)


@pytest.mark.parametrize("order", ["cuda-cpu", "cpu-cuda"])
def test_a_call_ending_a_cycle_is_continued_by_the_other_backend(runs, order):
    """2 steps on one backend (the call ends a cycle: its update pending, theta_ok 2, on both),
    2 on the other from that state: the state of 4 steps on the CPU, to round-off."""
    assert runs[f"cross/{order}/theta_ok_between"][0] == 2.0
    for field in ("positions", "momenta", "thermal_displacement", "entropy", "produced"):
        x, y = runs[f"cross-whole/cpu/{field}"], runs[f"cross/{order}/{field}"]
        scale = max(float(np.abs(runs["cross-whole/cpu/entropy"] if field == "produced" else x).max()), 1e-300)
        assert float(np.max(np.abs(x - y))) <= STATE_RTOL * scale, field


def test_the_two_launch_path_cut_into_calls_equals_the_fused_call(runs):
    for field in ("positions", "momenta", "thermal_displacement", "entropy") + LOGS:
        assert _close(runs[f"calls-two-launch/cuda/{field}"], runs[f"whole/cuda/{field}"], STATE_RTOL), field


@pytest.mark.parametrize("entries", [True, False])
def test_the_device_runs_no_pass_the_pass_before_already_did(runs, entries):
    """Conduction every step with two launches, 4 steps a call: a call's first sweep starts from
    a temperature pass (θ not valid: the first call) or a start phase taking back the last
    call's pending update (RESUME); after that the kick before each reverse sweep keeps θ and its
    start, the reverse row leaves its finish to the forward row after it, whose start it keeps,
    and the kick after the forward row runs the finish of both: per step the star colours twice,
    the boundary phase twice, and one finish a call (the last reverse row's, which keeps its
    update pending). Without baths and sources the reverse row's last colour and the forward
    row's first run as one phase: 3 colours fewer in 4 steps (docs/gpu.md)."""
    counts = runs["phase-launches" if entries else "phase-launches-bare"]
    for (temperature, start, colours, boundary, finish, n_colours), (want_temperature, want_start) in zip(
            counts, ((1, 0), (0, 1))):
        assert n_colours > 1
        assert (temperature, start) == (want_temperature, want_start)
        assert colours == 2 * n_colours * 4 - (0 if entries else 3)
        assert boundary == (2 * 4 if entries else 0) and finish == 1


@pytest.mark.parametrize("name", list(BLOWUPS))
def test_a_blow_up_with_conduction_rewinds_the_heat_with_the_state(runs, name):
    """The same first bad step and message as the CPU, and the last good state, η and the heat
    logs included, equal to a CPU run that stops there (the device backup holds the logs: a
    replay without them would count the heat of the replayed steps twice)."""
    cpu, gpu = f"{name}/cpu", f"{name}/cuda"
    step = int(runs[f"{cpu}/step"])
    assert 5 < step < 1000
    assert int(runs[f"{gpu}/step"]) == step
    assert "left the admissible states" in str(runs[f"{gpu}/message"])
    assert str(runs[f"{gpu}/message"]) == str(runs[f"{cpu}/message"])
    assert runs[f"{gpu}/entry_heat"].min() != 0.0
    assert_states_agree(runs, f"{name}/good", gpu)


# ----------------------------------------------------------------------------------------------
# compiled for a real device


def _toolkit_compiles() -> bool:
    if not HAVE_NUMBA_CUDA:
        return False
    try:
        from numba import cuda

        def _probe(out):
            out[0] = 1.0

        cuda.compile_ptx(_probe, "void(float64[:])", cc=(9, 0))
        return True
    except Exception:
        return False


@pytest.mark.skipif(not _toolkit_compiles(), reason="needs the CUDA toolkit libraries (NVVM, NVRTC) of "
                    "numba-cuda[cu12] or [cu13]; no GPU needed")
def test_heat_kernels_compile_to_ptx_for_h100():
    from thermonet.heat.cuda import compile_heat_ptx

    ptx = compile_heat_ptx(tn.get_model("hencky"), cc=(9, 0))
    assert set(ptx) == {"sweep", "temperature"}
    assert all(".target sm_90" in text for text in ptx.values())


@pytest.mark.skipif(not _toolkit_compiles(), reason="needs the CUDA toolkit libraries (NVVM, NVRTC) of "
                    "numba-cuda[cu12] or [cu13]; no GPU needed")
def test_fused_kernel_with_heat_rows_compiles_for_h100_but_for_its_grid_barriers():
    """The fused ``_steps_kernel`` with conduction and thermal waves compiled in, typed and
    compiled to PTX as for a GPU. numba-cuda types the grid-wide barrier only with a driver, so
    here it is replaced by a block barrier (source rewritten); everything else is the kernel's."""
    import inspect
    import textwrap

    from numba import cuda, njit, typeof

    from thermonet.explicit.cuda import kernels
    from thermonet.explicit.schedule import MAX_FLOWS, StageTable
    from thermonet.heat import cuda as device_heat
    from thermonet.kernels import records
    from thermonet.kernels.specialize import kernel_namespace
    from thermonet.kernels.subflows import bind_subflows

    ns = kernel_namespace(tn.get_model("hencky"), True, True)
    ns.update(CONDUCTION=True, WAVES=True)
    tag, inline = "fused_heat_ptx", njit(inline="always")
    bind_subflows(ns, tag, inline)
    device_heat.bind_device_heat(ns, tag, inline)
    for slot in range(MAX_FLOWS):
        ns[f"flow_update_{slot}"] = inline(kernels._no_update)
    kernels.bind_shared(ns, tag, inline)
    source = textwrap.dedent(inspect.getsource(kernels._steps_kernel))
    assert source.count("grid.sync()") >= 5
    source = source.replace("grid = cuda.cg.this_grid()", "pass").replace("grid.sync()", "cuda.syncthreads()")
    namespace = dict(vars(kernels), **ns)
    exec(source, namespace)
    v, x, i, u = np.empty(1), np.empty((1, 3)), np.empty(1, np.int64), np.empty(1, np.uint32)
    heat = device_heat.sample_heat()
    args = (records.StateArrays(x, x, v, v), x, v,
            records.Topology(np.empty((1, 2), np.uint32), i, u, u), records.Springs(v, np.empty((4, 1))),
            records.Nodes(v, v, np.empty(1, np.bool_), np.empty(3), True, np.empty(3)), StageTable(i, v, v, 0.5),
            (((v,),) * MAX_FLOWS, heat), records.Run(1.0, 0.0, 1, True, 0.1, 10.0, False, False), np.zeros(4, np.int64))
    ptx, _ = cuda.compile_ptx(namespace["_steps_kernel"], tuple(typeof(a) for a in args), cc=(9, 0))
    assert ".target sm_90" in ptx


@pytest.mark.gpu
@pytest.mark.skipif(not gpu_available(), reason="needs a CUDA GPU")
@pytest.mark.parametrize("make", [conduction_sim, bare_conduction_sim, waves_sim], ids=["conduction", "bare", "waves"])
def test_gpu_heat_flow_equals_cpu_and_launch_modes_agree(make):
    """On a GPU: CPU to 1e-10 after 40 steps (fused multiply-adds), the fused launch equal to two
    launches per stage bit for bit, cut into calls or not; every launch after a kernel's first
    took the launcher's fast path (its arguments kept their types). ``bare``: no baths or
    sources (the meeting colours of a cycle boundary as one phase)."""
    net = small_net((4, 4, 4), 18, seed=2)
    states = {}
    for backend, fused, chunks in (("cpu", True, (40,)), ("cuda", False, (40,)), ("cuda", True, (40,)),
                                   ("cuda", True, (1, 13, 26))):
        sim = make(backend, fused, net=net) if make is waves_sim else make(backend, fused, bath=500.0, net=net)
        for n in chunks:
            sim.run(steps=n, diagnostics_every=n)
        states[backend, fused, chunks] = sim.state
        if backend == "cuda" and not fused:
            slow = {launcher.dispatcher.py_func.__name__: launcher.slow_launches
                    for launcher in sim.stepper._launchers.values() if launcher.slow_launches}
            assert not slow, f"launches that fell back to the dispatcher: {slow}"
    cpu = states["cpu", True, (40,)]
    reference = states["cuda", False, (40,)]
    for field in ("positions", "momenta", "thermal_displacement", "entropy"):
        assert _close(getattr(cpu, field), getattr(reference, field), 1e-10), field
    for name in LOGS:
        x, y = cpu.extra["heat"][name], reference.extra["heat"][name]
        if name == "theta_ok":  # 2 on both where a call ended with a reverse sweep, its update pending
            assert x[0] == y[0], name
        else:
            assert _close(x, y, 1e-10), name
    for state in states.values():
        if state is cpu:
            continue
        for field in ("positions", "momenta", "thermal_displacement", "entropy"):
            np.testing.assert_array_equal(getattr(state, field), getattr(reference, field), err_msg=field)
        for name in LOGS:
            np.testing.assert_array_equal(state.extra["heat"][name], reference.extra["heat"][name], err_msg=name)


if __name__ == "__main__":
    from simulator_pace import pace

    pace()
    main(sys.argv[1])
