"""The implicit integrators, one folder per scheme (its stepper and its kernels) on a shared core.

``core/``: what every scheme uses: the records its kernels take, the start kernel, the free
nodes' rows, the scheme registry, the stepper (predictor, Newton, continuation, retry), the
Newton drivers (Python and compiled) with their one policy, the local Jacobi step, the path
choice. ``gtr_alpha/``, ``ho4/``, ``em2/``: a scheme each (docs/theory.md §2). The linear
algebra the Newton steps use is :mod:`thermonet.solvers`.
"""
