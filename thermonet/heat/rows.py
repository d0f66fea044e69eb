"""The stage-table codes of the heat-flow rows (:mod:`thermonet.explicit.schedule`), named
here so that every kernel reads them by name: a row with one of these codes is a built-in heat
flow, not a stage (−1) or a sub-flow slot (≥ 0). With the CPU's explicit step the conduction
rows only mark where the sweeps stand (at the step's ends: the kernel runs them at the cycle's
boundaries); the GPU's kernels run them as rows, on the cycle's first and last steps.
"""

#: conduction, the forward half sweep (a cycle's start)
CONDUCTION_FORWARD = -2
#: conduction, the reverse half sweep (a cycle's end)
CONDUCTION_REVERSE = -3
#: the Green–Naghdi Φ-gradient flow (thermal waves)
THERMAL_WAVES = -4
