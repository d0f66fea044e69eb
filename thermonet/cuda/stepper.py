"""The CUDA stepper: a :class:`~thermonet.integrators.splitting.Splitting` run on the GPU with the
state resident in device memory.

The host :class:`~thermonet.system.State` stays the one the :class:`~thermonet.simulation.Simulation`
holds (step and time are kept there), but while the stepper owns it its arrays are stale: the
simulation calls :meth:`CudaSplittingStepper.sync` before it reads them (output frames, the state
property, error reports) and :meth:`CudaSplittingStepper.measure` for a diagnostics row, which is
reduced on the device. So a run copies back only frames and diagnostics rows. A state the
simulation replaces (``load_state``) is a new object, and is uploaded at the next ``advance``.
"""

from __future__ import annotations

import numpy as np

from ..diagnostics import diagnostics_row
from ..integrators.base import Stepper
from ..kernels.splitting import kernel_parameters
from . import require_cuda


class CudaSplittingStepper(Stepper):
    """A :class:`~thermonet.integrators.splitting.Splitting` bound to a system, on the GPU."""

    #: the state lives on the device: the simulation must sync() before reading its arrays
    resident = True
    #: run whole chunks of steps as one cooperative launch (``_steps_kernel``: grid-wide barriers
    #: between the passes) instead of two launches per stage; the same numbers either way (tested
    #: bit for bit on an H100). None: by net size, below :data:`FUSED_MAX_SPRINGS`.
    fused: bool | None = None
    #: Measured on an H100 (CO2, 6-neighbour lattices, G spring-steps/s fused / two launches):
    #: 1e5 springs 10.0 / 0.50, 1e6 13.0 / 7.0, 3e6 14.7 / 21.3, 1e7 15.3 / 22.3. Launching from
    #: Python costs ~70 µs a launch, which bounds two launches per stage on small nets; a
    #: cooperative launch keeps only the blocks that fit at once, which caps it at ~65% of the copy
    #: bandwidth on large ones. The two cross near 2e6 springs (both ≈ 144 µs a step there).
    FUSED_MAX_SPRINGS = 2_000_000
    #: most steps per fused launch (a launch cannot be interrupted; a few hundred steps keep
    #: Ctrl-C and progress reports responsive and cost one launch each)
    FUSED_MAX_STEPS = 256

    def __init__(self, integrator, system):
        require_cuda()
        from numba import cuda

        from .kernels import NODE_OPS, SPRING_OPS, cuda_kernels

        self.integrator = integrator
        self.system = system
        self._cuda = cuda
        P, uniform = kernel_parameters(system.parameters)
        self._k = cuda_kernels(system.model, system.thermal, uniform)
        self._kicks = tuple(float(k) for k in integrator.kicks)
        self._drifts = tuple(float(d) for d in integrator.drifts)
        n, m = system.n_nodes, system.n_springs
        lay = system.layout
        dev = cuda.to_device
        gravity = np.zeros(3) if system.gravity is None else np.asarray(system.gravity, dtype=np.float64)
        self._l0, self._P = dev(system.rest_lengths), dev(P)
        # unsigned indices: no negative-index wraparound test per access
        self._edges = dev(np.ascontiguousarray(lay.edges).view(np.uint32))
        self._inc_ptr = dev(np.ascontiguousarray(lay.inc_ptr, dtype=np.int64))
        self._inc_spring = dev(np.ascontiguousarray(lay.inc_spring).view(np.uint32))
        self._inc_other = dev(np.ascontiguousarray(lay.inc_other).view(np.uint32))
        self._masses, self._inv_mass = dev(system.masses), dev(system.inv_mass)
        self._anchored = dev(np.ascontiguousarray(system.anchored, dtype=np.bool_))
        self._gravity, self._ref = dev(gravity), dev(np.asarray(system.reference_point, dtype=np.float64))
        self._with_gravity = system.gravity is not None
        self._s = cuda.device_array(max(m, 1))
        self._x = cuda.device_array((n, 3))
        self._x_buf = cuda.device_array((n, 3))
        self._p = cuda.device_array((n, 3))
        empty = cuda.device_array(0)
        self._phi = cuda.device_array(m) if system.thermal else empty
        self._eta = cuda.device_array(m) if system.thermal else empty
        self._kick_table = dev(np.array(self._kicks, dtype=np.float64))
        self._drift_table = dev(np.array(self._drifts, dtype=np.float64))
        self._fused_blocks = None
        self._spring_ops, self._node_ops = dev(np.array(SPRING_OPS, np.int32)), dev(np.array(NODE_OPS, np.int32))
        blocks = self._k.reduce_blocks
        self._spring_partial = cuda.device_array((blocks, len(SPRING_OPS)))
        self._node_partial = cuda.device_array((blocks, len(NODE_OPS)))
        self._spring_out = cuda.device_array(len(SPRING_OPS))
        self._node_out = cuda.device_array(len(NODE_OPS))
        self._bound = None  # the host State whose arrays the device arrays hold (or are newer than)
        self._device_newer = False

    # ------------------------------------------------------------------------------------------
    # host <-> device

    def _bind(self, state) -> None:
        """Upload ``state`` unless it is the one already on the device."""
        if state is self._bound:
            return
        self._x.copy_to_device(np.ascontiguousarray(state.positions))
        self._p.copy_to_device(np.ascontiguousarray(state.momenta))
        if self.system.thermal:
            self._phi.copy_to_device(np.ascontiguousarray(state.thermal_displacement))
            self._eta.copy_to_device(np.ascontiguousarray(state.entropy))
        self._bound = state
        self._device_newer = False

    def sync(self, state) -> None:
        """Copy the device state into ``state``'s arrays if the device holds a newer one."""
        if state is not self._bound or not self._device_newer:
            return
        self._x.copy_to_host(state.positions)
        self._p.copy_to_host(state.momenta)
        if self.system.thermal:
            self._phi.copy_to_host(state.thermal_displacement)
            self._eta.copy_to_host(state.entropy)
        self._device_newer = False

    # ------------------------------------------------------------------------------------------
    # stepping

    def _stage(self, k1: float, k2: float, drift: float, with_force: bool, track_phi: bool) -> None:
        k = self._k
        n, m = self.system.n_nodes, self.system.n_springs
        if with_force and m > 0:
            k.spring[k.blocks(m), k.threads](self._x, self._eta, self._l0, self._P, self._edges, self._s,
                                             self._phi, k1, k2, track_phi)
        if n > 0:
            k.node[k.blocks(n), k.threads](self._x, self._x_buf, self._p, self._s, self._inc_ptr,
                                           self._inc_spring, self._inc_other, self._masses, self._inv_mass,
                                           self._anchored, k1, k2, drift, with_force, self._gravity,
                                           self._with_gravity)
        self._x, self._x_buf = self._x_buf, self._x

    def advance(self, state, n_steps: int, h: float):
        """As :meth:`thermonet.integrators.splitting.SplittingStepper.advance`; the same stage
        sequence, kick coefficients and chunk-boundary handling, so results do not depend on
        how a run is cut into chunks."""
        if n_steps <= 0:
            return None
        self._bind(state)
        h = float(h)
        track_phi = bool(self.integrator.track_phi)
        fused = self.fused if self.fused is not None else self.system.n_springs < self.FUSED_MAX_SPRINGS
        if fused:
            done = 0
            while done < n_steps:
                chunk = min(int(n_steps) - done, self.FUSED_MAX_STEPS)
                self._fused_steps(chunk, h, track_phi)
                done += chunk
            self._device_newer = True
            return None
        kicks, drifts = self._kicks, self._drifts
        pending = 0.0
        for _ in range(int(n_steps)):
            for i, d in enumerate(drifts):
                k1 = pending if i == 0 else 0.0
                k2 = kicks[i]
                self._stage(k1 * h, k2 * h, d * h, k1 != 0.0 or k2 != 0.0, track_phi)
            pending = kicks[-1]
        if pending != 0.0:
            self._stage(0.0, pending * h, 0.0, True, track_phi)
        self._device_newer = True
        return None

    def _fused_steps(self, n_steps: int, h: float, track_phi: bool) -> None:
        """``n_steps`` steps as one cooperative launch; the same stages as :meth:`advance`'s
        two-launch loop (including the closing half kick), so a chunk ends in the same state."""
        k = self._k
        args = (self._x, self._x_buf, self._p, self._eta, self._l0, self._P, self._edges, self._s, self._phi,
                self._inc_ptr, self._inc_spring, self._inc_other, self._masses, self._inv_mass, self._anchored,
                self._gravity, self._with_gravity, self._kick_table, self._drift_table, h, n_steps, track_phi)
        if self._fused_blocks is None:
            self._fused_blocks = self._cooperative_blocks(args)
        k.steps[self._fused_blocks, k.threads](*args)
        stages = n_steps * len(self._drifts) + (1 if self._kicks[-1] != 0.0 else 0)
        if stages % 2:
            self._x, self._x_buf = self._x_buf, self._x

    def _cooperative_blocks(self, args) -> int:
        """Blocks of the fused launch: enough for one thread per spring or node, at most as many
        as can be resident at once (a grid-wide barrier needs every block running); one block
        under the simulator, which supports grid barriers only there."""
        from numba import typeof

        from . import simulator_enabled

        if simulator_enabled():
            return 1
        k = self._k

        kernel = k.steps.compile(tuple(typeof(a) for a in args))
        resident = kernel.max_cooperative_grid_blocks(k.threads)
        needed = k.blocks(max(self.system.n_springs, self.system.n_nodes, 1))
        return max(1, min(resident, needed))

    # ------------------------------------------------------------------------------------------
    # diagnostics

    def measure(self, system, state) -> dict[str, float]:
        """One diagnostics row (the keys of :func:`thermonet.diagnostics.measure`), reduced on the
        device from the device state; only the few sums come back."""
        self._bind(state)
        k = self._k
        blocks, threads = k.reduce_blocks, k.reduce_threads
        k.spring_sums[blocks, threads](self._x, self._eta, self._l0, self._P, self._edges, self._spring_partial)
        k.finish[1, threads](self._spring_partial, self._spring_ops, self._spring_out)
        k.node_sums[blocks, threads](self._x, self._p, self._masses, self._anchored, self._ref, self._gravity,
                                     self._node_partial)
        k.finish[1, threads](self._node_partial, self._node_ops, self._node_out)
        internal, entropy, theta_min, theta_max = (float(v) for v in self._spring_out.copy_to_host())
        kinetic, potential, px, py, pz, Lx, Ly, Lz = (float(v) for v in self._node_out.copy_to_host())
        return diagnostics_row(system, state, kinetic, internal, potential, entropy, (px, py, pz), (Lx, Ly, Lz),
                               theta_min, theta_max)
