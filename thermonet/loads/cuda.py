"""The loads' passes on the GPU (numba-cuda; Python under the CUDA simulator): the per-element
functions of :mod:`thermonet.loads.elements`, one thread per load.

A stage of the two-launch path (:class:`~thermonet.explicit.cuda.stepper.CudaSplittingStepper`) runs,
after its node kernel, :func:`load_stage_kernel`: the kick's work at the stage's time (its rates
were evaluated at the end of the drift before, or by :func:`load_start_kernel` at the call's
start: the same time, bit for bit), then the loads at the end of this stage's drift and the
driven nodes moved there. A load's nodes are summed in one thread, in the CPU's order.
"""

from __future__ import annotations

from numba import cuda

from . import elements
from ..kernels.specialize import rebind
from ..timefunctions import evaluate_py, evaluate_rate_py

evaluate_load = load_power = add_work = drive_member = None


def bind_device_loads(ns: dict, tag: str, inline, simulator: bool) -> str:
    """Bind :mod:`thermonet.loads.elements`' functions into the CUDA kernel namespace ``ns``
    (compiled by ``inline``: device functions, or Python under the simulator). Returns the
    suffix of the kernels' cache tag."""
    from numba import njit

    suffix = f"_L{elements.source_digest()}"
    compile_time = (lambda fn: fn) if simulator else njit(inline="always")
    ns["evaluate"] = compile_time(evaluate_py)
    ns["evaluate_rate"] = compile_time(evaluate_rate_py)
    for name in elements.SHARED:
        ns[name] = inline(rebind(getattr(elements, name), tag + suffix, ns))
    return suffix


def load_start_kernel(loads, t):
    """Thread i: load i's value and rate at t (a call's first kick)."""
    i = cuda.grid(1)
    if i < loads.component.shape[0]:
        evaluate_load(i, loads, t)


def load_stage_kernel(x, x_new, s, topology, nodes, loads, steps, t_after):
    """Thread i, after a stage's node kernel: with a kick (steps = (kick1 h, kick2 h, with_force,
    with_drift)) load i's work at x; with a drift, its value at t_after and, for a drive, its
    nodes' driven axes in x_new."""
    i = cuda.grid(1)
    if i < loads.component.shape[0]:
        if steps[2]:
            add_work(i, loads, load_power(i, x, s, topology, nodes, loads), steps[0], steps[1])
        if steps[3]:
            evaluate_load(i, loads, t_after)
            if loads.is_drive[i]:
                for k in range(loads.member_ptr[i], loads.member_ptr[i + 1]):
                    drive_member(k, i, x_new, loads)
