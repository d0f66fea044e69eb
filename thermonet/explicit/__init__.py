"""The explicit integrators, one slice: kick/drift splittings as coefficient tables and everything
that runs them.

- :mod:`.splitting`: ``Splitting`` (kicks, drifts and extra sub-flows as data), ``compose``,
  ``palindrome`` and the shipped tables (GTR-0, GTR-1, CO2, F10, NM2, CO4, CO6, BM4, BM6, BM6A,
  OMF4), registered with :func:`thermonet.integrators.register_integrator` (importing
  :mod:`thermonet.integrators` imports them); :mod:`.stepper`, the CPU stepper.
- :mod:`.schedule`: ``SubFlow`` and the stage table every backend reads, with its row codes;
  :mod:`.codes`: the other codes the kernels read by name.
- :mod:`.cpu`, :mod:`.passes`: the CPU kernel (a blocked spring pass and a node pass per stage)
  and its small passes.
- :mod:`.cuda`: the GPU backend (kernels, launcher, stepper; imports no CUDA code until used).

What one spring or node does in a kick or a drift is :mod:`thermonet.kernels.subflows`, shared
with the heat passes and the diagnostics; heat flow's rows and loads' passes come from
:mod:`thermonet.heat` and :mod:`thermonet.loads`. This package's own import loads nothing (its
modules are imported by name), so the heat and loads slices may read its schedule and codes.
"""
