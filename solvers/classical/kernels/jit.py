"""How the kernels are compiled: numba's nopython mode with numpy's error model, cached on disk,
every compiled function with a fixed identity in pickles, so that the closures that call it (the
variants of one integrator, `jit_variant`) find their cache entries in every process."""

from __future__ import annotations

from numba import njit

__all__ = ["jit_function", "jit_variant", "name_for_cache"]


def name_for_cache(dispatcher):
    """Give `dispatcher` a fixed identity in pickles, its function's module and qualified name, so
    that numba's on-disk cache can find a kernel that calls it: numba keys a closure's cache entry
    by the pickle of its closure variables, and a dispatcher pickles with a random per-process uuid
    unless it has one (the batch kernels, closures over the integrators that call these functions,
    were compiled afresh in every process: ~5-10 s each). Uses numba's private `_set_uuid`; without
    it the kernels still work, uncached."""
    set_uuid = getattr(dispatcher, "_set_uuid", None)
    if set_uuid is not None and getattr(dispatcher, "_MemoMixin__uuid", "") is None:
        set_uuid(f"{dispatcher.py_func.__module__}.{dispatcher.py_func.__qualname__}")
    return dispatcher


def jit_function(py_func):
    """`py_func` compiled as every function the kernels call (cached, numpy's error model), with
    its identity for the cache (`name_for_cache`)."""
    return name_for_cache(njit(cache=True, error_model="numpy")(py_func))


def jit_variant(py_func, variant: str, **flags):
    """`py_func` compiled (cached, numpy's error model), its qualified name suffixed by `variant`.
    The variants of one closure must differ in name: numba names a compiled function (and the
    environment it boxes results with) by qualified name, argument types and a per-process
    counter, so two variants loaded from the cache that two processes numbered alike would clash
    (measured: a kernel returning with "'descr' is NULL")."""
    py_func.__qualname__ = f"{py_func.__qualname__}_{variant}"
    return name_for_cache(njit(cache=True, error_model="numpy", **flags)(py_func))
