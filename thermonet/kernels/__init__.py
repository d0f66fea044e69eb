"""Numba kernels. Each is built per model by a factory (the model's scalar functions are inlined)
and cached per (model, options) in this process and on disk (``cache=True``)."""
