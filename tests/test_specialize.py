"""specialize(): kernels run without Numba's reference counting wherever nothing they reach needs
the runtime (docs/architecture.md, "Kernels run without reference counting"), and keep it where
something does, whatever the order in which the functions are first compiled."""

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
