"""The shared per-element toolkit that every slice's Numba kernels compile from: what one spring
or node does (:mod:`.subflows`), the blocked spring pass's pieces (:mod:`.blocks`), the kernels'
records (:mod:`.records`), per-model specialization and the kernels' parameter array
(:mod:`.specialize`), vectorizable maths (:mod:`.fastmath`), the diagnostics reductions and
per-spring fields (:mod:`.reductions`, :mod:`.springs`), the output gathers (:mod:`.gather`) and
row copies (:mod:`.copies`). Kernels that belong to one kind of integrator or physics
live in its slice (:mod:`thermonet.explicit`, :mod:`thermonet.heat`, :mod:`thermonet.loads`);
the implicit schemes' kernels are here for now.

Each kernel is built per model by a factory (the model's scalar functions are inlined) and
cached per (model, options) in this process and on disk (``cache=True``)."""
