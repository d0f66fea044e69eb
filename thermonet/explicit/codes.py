"""Where the explicit CPU kernel's node pass takes each node's force from: its ``force_source``
argument, named here so that every caller (the kernel's step, the heat passes' deferred kick,
the distributed stages) passes it by name. Module-level integers, which Numba compiles as
constants: the per-step node pass takes them as literals (its branches decided at compile
time); the closing node pass, which runs a few times per call, takes them as ``np.int64(...)``
(with ``want_sums`` as ``np.bool_``) so that one compiled variant serves every source (each
literal would compile one more, 8 s of CPU for a threaded one).
"""

#: gather f from the springs' T/l in ``s`` (every kick inside a call)
FORCE_GATHER = 0
#: gather f and keep it in ``f_keep`` (n, 3): a call's closing kick, whose drift is 0
FORCE_GATHER_KEEP = 1
#: take f from ``f_keep``: the first kick of a call that reuses the previous call's closing kick
FORCE_KEPT = 2
#: a kick deferred past the conduction sweeps: its forces from ``s_before`` (m,), the next kick's
#: from ``s`` (CONDUCTION only)
FORCE_DEFERRED = 3
