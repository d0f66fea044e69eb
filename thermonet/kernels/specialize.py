"""Compile a kernel template for one model, with an on-disk cache that survives new processes.

A template is a plain Python function at module level that calls model functions by global
name (``temperature``, ``tension``, …). :func:`specialize` binds those names to a model's Numba
functions and compiles it. Numba's disk cache keys a closure by pickling its cells, which for
Numba functions differs in every process, so closures would recompile on every start; instead the
template's code object is rebound to new globals and given a qualified name that carries the
model's fingerprint, which keeps cache entries of different models, or of an edited user model,
apart. The fingerprint hashes the model functions' modules, names, bytecode and constants, and
those of every Numba function they call (recursively): a cached kernel refers to the modules its
callees live in, so the same model code imported under another module name (a script run as
``__main__`` and later imported) must not load it.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import tempfile
import threading
import time
import types
import weakref

import numpy as np
from numba import njit

try:
    from fcntl import LOCK_EX as _LOCK_EX, LOCK_NB as _LOCK_NB, LOCK_UN as _LOCK_UN, flock as _flock
except ImportError:  # pragma: no cover - (not on Windows)
    _flock = None

MODEL_FUNCTIONS = ("free_energy", "tension", "entropy", "temperature", "internal_energy",
                   "d2F_dl2", "d2F_dl_dtheta", "d2F_dtheta2")
#: a model's optional functions (None where it has none), fingerprinted with the others
OPTIONAL_MODEL_FUNCTIONS = ("energy_quotient", "strain", "tension_at_strain")


def _code_digest(code: types.CodeType, h) -> None:
    h.update(code.co_code)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            _code_digest(const, h)
        else:
            h.update(repr(const).encode())
    h.update(repr(code.co_names).encode())


def _function_digest(fn, h, seen: set) -> None:
    """Hash a (Numba or Python) function and, recursively, the Numba functions it calls."""
    py = getattr(fn, "py_func", fn)
    if py is None or not hasattr(py, "__code__") or id(py) in seen:
        return
    seen.add(id(py))
    h.update(f"{py.__module__}.{py.__qualname__}".encode())
    _code_digest(py.__code__, h)
    glb = getattr(py, "__globals__", {})
    for name in _all_names(py.__code__):
        callee = glb.get(name)
        if hasattr(callee, "py_func"):
            _function_digest(callee, h, seen)


def _all_names(code: types.CodeType):
    yield from code.co_names
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            yield from _all_names(const)


_FINGERPRINTS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def model_fingerprint(model) -> str:
    """A short stable hash of the model's name, parameters and functions (see the module doc);
    computed once per model object (models are immutable)."""
    try:
        return _FINGERPRINTS[model]
    except (KeyError, TypeError):
        pass
    h = hashlib.sha256(model.name.encode())
    h.update(repr(model.parameters).encode())
    h.update(repr(getattr(model, "entropy_log_affine", False)).encode())  # selects kernel code
    h.update(repr(getattr(model, "temperature_can_vanish", False)).encode())  # so does this (EM2)
    seen: set = set()
    for name in MODEL_FUNCTIONS + OPTIONAL_MODEL_FUNCTIONS:
        _function_digest(getattr(model, name, None), h, seen)
    fingerprint = h.hexdigest()[:12]
    try:
        _FINGERPRINTS[model] = fingerprint
    except TypeError:  # not weak-referenceable: recomputed next time
        pass
    return fingerprint


def function_fingerprint(*functions) -> str:
    """A short stable hash of (Numba or Python) functions and the Numba functions they call, for
    cache names of kernels compiled around them (as :func:`model_fingerprint` for a model)."""
    h = hashlib.sha256()
    seen: set = set()
    for fn in functions:
        _function_digest(fn, h, seen)
    return h.hexdigest()[:12]


def namespace_digest(template, namespace: dict, options: dict | None = None) -> str:
    """A short stable hash of what ``template`` reads when compiled with ``namespace`` over its
    globals: its code and, recursively, the code and compile options of every Numba function it
    calls and the values of the constants it reads — not the names the functions were compiled
    under. A pass that reads less than its kernel variant's whole namespace (no loads, no model)
    thus gets the same hash, so the same cache name, in every variant that compiles it the same
    way. ``options``: the jit options it is compiled with, hashed too (Numba's disk cache checks
    only the template's file, not the caller's options). Raises TypeError for a global it cannot
    hash stably (the caller then names the pass by its variant's tag)."""
    h = hashlib.sha256(repr(sorted((options or {}).items())).encode())
    _content_digest(rebind(template, "", namespace), h, {})
    return h.hexdigest()[:12]


def _content_digest(py, h, seen: dict) -> None:
    if id(py) in seen:  # (its place in the walk, the same in every process)
        h.update(f"<{seen[id(py)]}>".encode())
        return
    seen[id(py)] = len(seen)
    h.update(f"{py.__module__}.{py.__name__}".encode())
    _code_digest(py.__code__, h)
    for cell in py.__closure__ or ():  # (a closure's values are compiled in, like globals)
        h.update(b"|cell=")
        _value_digest(cell.cell_contents, h, seen)
    for default in py.__defaults__ or ():
        h.update(b"|default=")
        _value_digest(default, h, seen)
    glb = py.__globals__
    names = sorted(set(_all_names(py.__code__)))
    for name in names:
        h.update(f"|{name}=".encode())
        if name in glb:
            _value_digest(glb[name], h, seen)
            if isinstance(glb[name], types.ModuleType):  # (module.function: the functions it may name)
                for attribute in names:
                    member = getattr(glb[name], attribute, None)
                    if hasattr(member, "py_func") and hasattr(member, "targetoptions"):
                        h.update(f"|{name}.{attribute}=".encode())
                        _value_digest(member, h, seen)


def _value_digest(value, h, seen: dict) -> None:
    if hasattr(value, "py_func") and hasattr(value, "targetoptions"):  # a Numba function
        options = {k: v for k, v in value.targetoptions.items() if k != "cache"}
        h.update(f"numba{sorted(options.items())!r}".encode())
        if value.py_func is not None:
            _content_digest(value.py_func, h, seen)
    elif isinstance(value, types.FunctionType):
        _content_digest(value, h, seen)
    elif value is None or isinstance(value, (bool, int, float, complex, str, bytes, np.generic)):
        h.update(f"{type(value).__name__}:{value!r}".encode())
    elif isinstance(value, tuple):
        h.update(f"tuple{len(value)}".encode())
        for item in value:
            _value_digest(item, h, seen)
    elif isinstance(value, np.ndarray):
        h.update(f"array{value.dtype.str}{value.shape}".encode())
        h.update(np.ascontiguousarray(value).tobytes())
    elif isinstance(value, (types.ModuleType, type)):
        h.update(f"{getattr(value, '__module__', '')}.{getattr(value, '__qualname__', value.__name__)}".encode())
    elif isinstance(value, types.BuiltinFunctionType):
        h.update(f"builtin:{getattr(value, '__module__', '')}.{value.__name__}".encode())
    elif type(value).__module__.startswith("numba") and " at 0x" not in repr(value):  # (Numba's types)
        h.update(f"{type(value).__qualname__}:{value!r}".encode())
    else:
        raise TypeError(f"cannot hash the global {value!r} of a kernel stably")


def model_namespace(model) -> dict:
    """Global names a template may use for the model's functions."""
    return {name: getattr(model, name) for name in MODEL_FUNCTIONS}


def kernel_namespace(model, thermal: bool = True, uniform: bool = False) -> dict:
    """The globals every kernel template of a model variant reads: the model's functions, and the
    compile-time constants THERMAL (thermal coupling on; off: every spring at its reference
    temperature, parameter row REFERENCE_TEMPERATURE) and UNIFORM (one (k, 1) parameter column
    shared by all springs)."""
    ns = model_namespace(model)
    # (the optional pair, None where the model has none: thermonet.heat.passes binds stand-ins)
    ns["model_strain"] = getattr(model, "strain", None)
    ns["tension_at_strain"] = getattr(model, "tension_at_strain", None)
    ns["THERMAL"] = bool(thermal)
    ns["REFERENCE_TEMPERATURE"] = model.parameter_index(model.reference_temperature)
    ns["UNIFORM"] = bool(uniform)
    return ns


def kernel_parameters(P: np.ndarray) -> tuple[np.ndarray, bool]:
    """The parameter array the kernels should read, and whether it is shared by all springs.

    P: (k, m) per-spring parameters. Returns ``(P[:, :1] copy, True)`` when every row is
    constant, else ``(P, False)``; pass the flag to :func:`kernel_namespace` as ``uniform``
    (the kernels then call the model's functions with column ``e = 0``).
    """
    P = np.ascontiguousarray(P, dtype=np.float64)
    if P.shape[1] > 0 and bool(np.all(P == P[:, :1])):
        return np.ascontiguousarray(P[:, :1]), True
    return P, False


def specialize(template, tag: str, namespace: dict, **jit_options):
    """``njit(**jit_options)`` of ``template`` with ``namespace`` overriding its globals.

    tag: made part of the qualified name (so of the cache file name); must identify everything
    in ``namespace`` and in the jit options that changes the compiled code.

    ``_nrt=False`` (the kernels' options: no reference counting, so no allocation) is kept only
    where nothing the kernel reaches needs Numba's runtime: it is dropped for a parallel kernel
    (Numba's parallel loops allocate their schedules) and for one that calls, directly or through
    other functions, a parallel or allocating kernel (Numba compiles a callee inside its
    caller's runtime setting, where such a callee fails to compile).
    """
    fn = rebind(template, tag, namespace)
    if jit_options.get("_nrt") is False and (jit_options.get("parallel") or _reaches_runtime(fn, set())):
        jit_options = {k: v for k, v in jit_options.items() if k != "_nrt"}
    dispatcher = njit(**jit_options)(fn)
    dispatcher._thermonet_runtime = jit_options.get("_nrt", True) is not False
    if jit_options.get("cache"):
        _compile_once_across_processes(dispatcher)
    return dispatcher


_BY_CONTENT: dict = {}


def specialize_by_content(template, tag: str, namespace: dict, **jit_options):
    """:func:`specialize`, named by :func:`namespace_digest` (what ``template`` reads and the jit
    options) rather than by ``tag``, and compiled once per process for that name: a pass that
    reads less than its kernel variant's namespace is shared by every variant that compiles it
    the same way (and loaded from Numba's disk cache under that one name in the next process).
    ``tag`` names it where the namespace cannot be hashed stably."""
    try:
        tag = f"c{namespace_digest(template, namespace, jit_options)}"
    except TypeError:
        pass
    key = (template, tag)
    if key not in _BY_CONTENT:
        _BY_CONTENT[key] = specialize(template, tag, namespace, **jit_options)
    return _BY_CONTENT[key]


def _compile_once_across_processes(dispatcher) -> None:
    """Make the processes that compile the same cached kernel at the same time (test workers,
    MPI ranks, Dask workers starting from a cold cache) take turns: the first compiles and
    writes Numba's disk cache, the others then load it instead of compiling it again. A lock
    file per kernel (its source file and qualified name), held while Numba compiles or loads it;
    the kernels it calls lock their own (the call graph has no cycles, so no two processes wait
    for each other). Without ``fcntl`` (Windows) every process compiles on its own."""
    if _flock is None:
        return
    compile_ = dispatcher.compile
    py = dispatcher.py_func
    key = hashlib.sha256(f"{py.__code__.co_filename}:{py.__qualname__}".encode()).hexdigest()[:20]

    def compile(sig):
        with _kernel_lock(key):
            return compile_(sig)

    dispatcher.compile = compile
    dispatcher._thermonet_lock_key = key


_HELD = threading.local()  # the kernel locks this thread holds (a lock is taken once per process)
#: how long a process waits for another to compile a kernel before compiling it itself (a cold
#: conducting kernel with loads takes up to two minutes on a busy machine)
LOCK_PATIENCE = 600.0


@contextlib.contextmanager
def _kernel_lock(key: str):
    """Hold the lock file of kernel ``key`` (in the temporary folder) while the block runs: the
    kernel's compile or cache load. Reentrant in a thread; a lock not had within LOCK_PATIENCE
    seconds (a process stopped while holding it) or a folder that cannot be written is given up
    and the block runs unlocked."""
    held = _HELD.__dict__.setdefault("keys", set())
    if key in held:
        yield
        return
    folder = os.path.join(tempfile.gettempdir(), "thermonet-compile-locks")
    try:
        os.makedirs(folder, exist_ok=True)
        handle = open(os.path.join(folder, key), "a")
    except OSError:
        yield
        return
    with handle:
        locked = _acquire(handle.fileno())
        if locked:
            held.add(key)
        try:
            yield
        finally:
            if locked:
                held.discard(key)
                _flock(handle.fileno(), _LOCK_UN)


def _acquire(fd: int) -> bool:
    deadline = time.monotonic() + LOCK_PATIENCE
    while True:
        try:
            _flock(fd, _LOCK_EX | _LOCK_NB)
            return True
        except BlockingIOError:
            if time.monotonic() > deadline:
                return False
            time.sleep(0.05)


def _reaches_runtime(fn, seen: set) -> bool:
    """Whether the Python function ``fn`` calls, directly or through Numba functions, a kernel
    made by :func:`specialize` that runs with Numba's runtime, or any parallel Numba function."""
    glb = getattr(fn, "__globals__", {})
    for name in set(_all_names(fn.__code__)):
        callee = glb.get(name)
        if not hasattr(callee, "py_func") or id(callee) in seen:
            continue
        seen.add(id(callee))
        if getattr(callee, "_thermonet_runtime", False) or getattr(callee, "targetoptions", {}).get("parallel"):
            return True
        if callee.py_func is not None and _reaches_runtime(callee.py_func, seen):
            return True
    return False


def rebind(template, tag: str, namespace: dict):
    """A copy of the Python function ``template`` whose globals are overridden by ``namespace``
    and whose qualified name carries ``tag`` (for any compiler's disk cache: Numba's CPU and
    CUDA targets alike)."""
    glb = dict(template.__globals__)
    glb.update(namespace)
    fn = types.FunctionType(template.__code__, glb, template.__name__, template.__defaults__, template.__closure__)
    fn.__qualname__ = f"{template.__qualname__}__{tag}"
    fn.__module__ = template.__module__
    fn.__doc__ = template.__doc__
    return fn
