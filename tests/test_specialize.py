"""specialize(): kernels run without Numba's reference counting wherever nothing they reach needs
the runtime (docs/architecture.md, "Kernels run without reference counting"), and keep it where
something does, whatever the order in which the functions are first compiled."""

import time

import numpy as np
from numba import prange

import thermonet as tn
from thermonet.kernels.specialize import specialize

NO_RUNTIME = dict(cache=False, _nrt=False)


def _parallel_sum(x):
    s = 0.0
    for i in prange(x.shape[0]):
        s += x[i]
    return s


def _allocating(x):
    block = np.zeros((3, 3))
    block[0, 0] = x[0]
    return block[0, 0]


def _plain(x):
    return 2.0 * x[0]


def _outer(x):
    return callee(x)  # noqa: F821 (bound by specialize)


def _chain(callee_template, **callee_options):
    """outer → middle → callee, the outer two asking for no runtime; nothing compiled yet."""
    callee = specialize(callee_template, f"callee_{callee_template.__name__}", {}, **callee_options)
    middle = specialize(_outer, f"middle_{callee_template.__name__}", {"callee": callee}, **NO_RUNTIME)
    outer = specialize(_outer, f"outer_{callee_template.__name__}", {"callee": middle}, **NO_RUNTIME)
    return outer, middle, callee


def test_a_kernel_reaching_nothing_that_needs_the_runtime_runs_without_it():
    outer, middle, callee = _chain(_plain, **NO_RUNTIME)
    assert outer(np.ones(4)) == 2.0
    assert outer.targetoptions["_nrt"] is False and middle.targetoptions["_nrt"] is False


def test_callers_of_a_parallel_kernel_keep_the_runtime_and_compile_first():
    outer, middle, callee = _chain(_parallel_sum, parallel=True, **NO_RUNTIME)
    assert "_nrt" not in callee.targetoptions  # parallel loops allocate their schedules
    # compiled outermost first: the callee compiles inside its callers' setting
    assert outer(np.ones(5)) == 5.0
    assert "_nrt" not in outer.targetoptions and "_nrt" not in middle.targetoptions


def test_callers_of_an_allocating_kernel_keep_the_runtime():
    outer, middle, callee = _chain(_allocating, cache=False)
    assert outer(np.full(3, 7.0)) == 7.0
    assert "_nrt" not in outer.targetoptions


def test_the_serial_steppers_kernels_run_without_the_runtime():
    sim = tn.Simulation(tn.lattice((3, 3, 3), jitter=0.1, seed=1), model="hencky",
                        parameters=dict(c=100.0, beta=0.2, C0=5.0, theta0=300.0), temperatures=300.0,
                        integrator="co2", h=0.01, parallel=False, energy_tolerance=None)
    sim.run(steps=2, diagnostics_every=2)
    assert sim.stepper._advance.targetoptions["_nrt"] is False
    em2 = tn.chain_simulation("em2", h=0.01)
    em2.run(steps=2, diagnostics_every=2)
    kernels = em2.stepper.kernels
    for kernel in (em2.stepper.compiled.driver, kernels.residual, kernels.sweep, kernels.jacobian, kernels.start,
                   kernels.finish):
        assert kernel.targetoptions["_nrt"] is False, kernel


def test_processes_take_turns_at_a_kernels_lock(tmp_path):
    """A second process asking for a kernel's lock while another holds it (compiling the kernel)
    gets it only once the first lets go: then it loads the cache instead of compiling too."""
    import subprocess
    import sys
    import textwrap
    import uuid

    key = f"test-{uuid.uuid4().hex}"
    holder = textwrap.dedent(f"""
        import time
        from thermonet.kernels.specialize import _kernel_lock
        with _kernel_lock({key!r}):
            open({str(tmp_path / "in")!r}, "w").write("")
            time.sleep(1.5)
            released = time.time()
        open({str(tmp_path / "out")!r}, "w").write(repr(released))
    """)
    waiter = textwrap.dedent(f"""
        import time
        from thermonet.kernels.specialize import _kernel_lock
        with _kernel_lock({key!r}):
            got = time.time()
        open({str(tmp_path / "got")!r}, "w").write(repr(got))
    """)
    first = subprocess.Popen([sys.executable, "-c", holder])
    deadline = time.monotonic() + 60
    while not (tmp_path / "in").exists():
        assert first.poll() is None and time.monotonic() < deadline, "the first process never held the lock"
        time.sleep(0.02)
    second = subprocess.run([sys.executable, "-c", waiter], timeout=120)
    assert first.wait(timeout=120) == 0 and second.returncode == 0
    assert float((tmp_path / "got").read_text()) >= float((tmp_path / "out").read_text())


def test_a_lock_held_too_long_is_given_up(monkeypatch):
    """A process stopped while holding a kernel's lock delays the others by LOCK_PATIENCE at
    most: then they compile unlocked."""
    import fcntl
    import os
    import tempfile
    import uuid

    from thermonet.kernels import specialize as sp

    key = f"test-{uuid.uuid4().hex}"
    folder = os.path.join(tempfile.gettempdir(), "thermonet-compile-locks")
    os.makedirs(folder, exist_ok=True)
    monkeypatch.setattr(sp, "LOCK_PATIENCE", 0.3)
    with open(os.path.join(folder, key), "a") as other:  # (another open file: its lock excludes ours)
        fcntl.flock(other.fileno(), fcntl.LOCK_EX)
        t0 = time.monotonic()
        with sp._kernel_lock(key):
            waited = time.monotonic() - t0
    assert 0.3 <= waited < 10.0


def test_a_cached_kernel_compiles_and_loads_under_its_lock(monkeypatch):
    import contextlib

    from thermonet.kernels import specialize as sp

    taken = []

    @contextlib.contextmanager
    def recording(key):
        taken.append(key)
        yield

    monkeypatch.setattr(sp, "_kernel_lock", recording)
    kernel = specialize(_plain, "locked", {}, cache=True)
    assert kernel(np.array([1.5])) == 3.0
    assert taken == [kernel._thermonet_lock_key]
    assert not hasattr(specialize(_plain, "uncached", {}, cache=False), "_thermonet_lock_key")


# --- passes named by what they read -------------------------------------------------------------

from numba import njit  # noqa: E402

from thermonet.kernels.specialize import namespace_digest, rebind  # noqa: E402

INLINE = dict(inline="always")


def _scaled(x):
    return SCALE * helper(x)  # noqa: F821 (bound by specialize)


def _helper_twice(x):
    return 2.0 * x


def _helper_thrice(x):
    return 3.0 * x


def _ns(scale=2.0, helper=_helper_twice, tag="a", **extra):
    return dict(SCALE=scale, helper=njit(**INLINE)(rebind(helper, tag, {})), **extra)


def test_a_pass_is_named_by_what_it_reads_not_by_its_variant():
    base = namespace_digest(_scaled, _ns())
    # names it does not read, and the tag its callee was compiled under, change nothing
    assert namespace_digest(_scaled, _ns(LOADS=True, UNUSED=np.zeros(3), tag="another_variant")) == base
    # a constant it reads, its callee's code, or the callee's compile options do
    assert namespace_digest(_scaled, _ns(scale=3.0)) != base
    assert namespace_digest(_scaled, _ns(helper=_helper_thrice)) != base
    other_options = dict(_ns(), helper=njit(rebind(_helper_twice, "a", {})))
    assert namespace_digest(_scaled, other_options) != base
    # and so do its own compile options
    assert namespace_digest(_scaled, _ns(), {"parallel": True}) != base
    assert namespace_digest(_scaled, _ns(), {"parallel": False}) == namespace_digest(_scaled, _ns(), {"parallel": False})


def test_a_closure_value_and_a_global_array_are_part_of_the_name():
    def factory(k):
        def update(x):
            return k * x
        return update

    def digest(fn, **extra):
        return namespace_digest(_scaled, dict(SCALE=1.0, helper=njit(**INLINE)(fn), **extra))

    assert digest(factory(2.0)) == digest(factory(2.0))
    assert digest(factory(2.0)) != digest(factory(5.0))
    assert namespace_digest(_scaled, _ns(scale=np.array([1.0, 2.0]))) != namespace_digest(
        _scaled, _ns(scale=np.array([1.0, 3.0])))


def test_a_global_that_cannot_be_hashed_stably_is_refused():
    import pytest

    class Opaque:
        pass

    with pytest.raises(TypeError, match="cannot hash"):
        namespace_digest(_scaled, _ns(scale=Opaque()))


def test_kernel_variants_share_the_passes_that_do_not_read_what_they_differ_in():
    """Nothing compiled: the passes each variant binds, compared as objects."""
    from thermonet.explicit import cpu
    from thermonet.loads.elements import CPU_PASSES
    from thermonet.models import HENCKY, QUADRATIC

    hencky = cpu.variant_passes(HENCKY, parallel=False, uniform=True)
    quadratic = cpu.variant_passes(QUADRATIC, parallel=False, uniform=False)
    hencky_loads = cpu.variant_passes(HENCKY, parallel=False, uniform=True, loads=True)
    hencky_heat = cpu.variant_passes(HENCKY, parallel=False, uniform=True, conduction=True)
    hencky_heat_loads = cpu.variant_passes(HENCKY, parallel=False, uniform=True, conduction=True, loads=True)
    threaded = cpu.variant_passes(HENCKY, parallel=True, uniform=True)
    # the node pass reads no model and no parameter layout; it reads the loads and the heat flow
    assert quadratic["node_pass"] is hencky["node_pass"]
    assert hencky_loads["node_pass"] is not hencky["node_pass"]
    assert hencky_heat["node_pass"] is not hencky["node_pass"]
    # the spring pass reads the model and the heat flow, not the loads
    assert quadratic["spring_pass"] is not hencky["spring_pass"]
    assert hencky_loads["spring_pass"] is hencky["spring_pass"]
    assert hencky_heat_loads["boundary_spring_pass"] is hencky_heat["boundary_spring_pass"]
    assert hencky_heat["spring_pass"] is not hencky["spring_pass"]
    assert threaded["spring_pass"] is not hencky["spring_pass"]
    assert threaded["thermal_kick"] is not hencky["thermal_kick"] and quadratic["thermal_kick"] is hencky["thermal_kick"]
    # the loads' serial passes: one for every variant with loads, called, not inlined
    for name in CPU_PASSES:
        assert hencky_heat_loads[name] is hencky_loads[name]
        assert hencky_loads[name].targetoptions.get("inline", "never") == "never"
