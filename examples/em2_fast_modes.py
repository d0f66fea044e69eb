"""What EM2 costs in accuracy above the explicit stability limit: the highest mode of a chain.

A straight chain of 16 hencky springs (c = 100, β = 0, unit masses, both ends anchored) starts
in its highest longitudinal mode at small amplitude. For each h ω_max the script runs EM2 and
measures the mode's phase advance per step Ω from the modal coordinate q_n (for a pure mode
q_{n+1} + q_{n−1} = 2 cos Ω q_n), next to the midpoint rule's 2 arctan(h ω/2) and the exact
h ω; and the energy error. Then the slow mode's frequency at the same steps. EM2 stays bounded
and keeps the energy at any step; the fast mode's frequency is what it loses.

    python examples/em2_fast_modes.py
"""

import math

import numpy as np

import thermonet as tn
from thermonet.stability import stable_step

N = 16


def chain_sim(h, mode, amplitude=1e-4):
    x = np.zeros((N + 1, 3))
    x[:, 0] = np.arange(N + 1)
    edges = np.column_stack([np.arange(N), np.arange(1, N + 1)])
    anchored = np.zeros(N + 1, dtype=bool)
    anchored[[0, N]] = True
    shape = np.sin(mode * math.pi * np.arange(N + 1) / N)
    start = x.copy()
    start[:, 0] += amplitude * shape
    net = tn.Net(start, edges, np.ones(N + 1), anchored, rest_lengths=np.ones(N))
    sim = tn.Simulation(net, parameters=dict(c=100.0, beta=0.0), integrator="em2", h=h)
    return sim, shape, x


def phase_per_step(sim, shape, x0, steps=400):
    q = []
    for _ in range(steps):
        q.append(float(shape @ (sim.state.positions[:, 0] - x0[:, 0])))
        sim.run(steps=1, diagnostics_every=10**9)
    q = np.array(q)
    c = np.dot(q[1:-1], q[2:] + q[:-2]) / (2 * np.dot(q[1:-1], q[1:-1]))
    return math.acos(max(-1.0, min(1.0, c)))


def main():
    probe, _, _ = chain_sim(1.0, N - 1)
    omega_fast = stable_step(probe, "co2")["omega_max"]
    omega_slow = 2 * 10.0 * math.sin(math.pi / (2 * N))  # the lowest mode (linear chain, c/l0² = 100)
    print(f"chain of {N} springs, ω_max = {omega_fast:.4f}, ω_min = {omega_slow:.4f}; CO2's limit h ω_max = 2\n")
    print("| h ω_max | h | fast mode: Ω per step | 2 arctan(hω/2) | hω (mod 2π) | period ratio | energy error | slow mode: rel. frequency error |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for hw in (0.5, 2.0, 10.0, 100.0):
        h = hw / omega_fast
        sim, shape, x0 = chain_sim(h, N - 1)
        omega_h = phase_per_step(sim, shape, x0)
        d = sim.diagnostics
        energy = np.asarray(d.energy)
        drift = float(np.abs(energy - energy[0]).max() / abs(energy[0]))
        slow, sshape, sx0 = chain_sim(h, 1)
        slow_h = phase_per_step(slow, sshape, sx0, steps=max(400, int(40 / (omega_slow * h))))
        print(f"| {hw:g} | {h:.4g} | {omega_h:.4f} | {2 * math.atan(hw / 2):.4f} | {math.fmod(hw, 2 * math.pi):.4f} | "
              f"{hw / omega_h:.3g} | {drift:.1e} | {slow_h / (omega_slow * h) - 1:.2e} |", flush=True)


if __name__ == "__main__":
    main()
