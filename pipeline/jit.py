"""numba compilation with an on-disk cache where one can be written (shared by the compiled kernels
of :mod:`pipeline.emd` and :mod:`models.valve_effects`)."""

from __future__ import annotations

from numba import njit

__all__ = ["compile_cached"]


def compile_cached(function):
    """``numba.njit`` with an on-disk cache when a cache directory is writable, without otherwise.

    numba refuses ``cache=True`` (``RuntimeError`` at decoration, i.e. at import) when it finds no
    writable cache location: ``__pycache__`` beside the module, else the user's cache directory.
    A read-only installation with a read-only home then compiles in memory on first use instead
    of failing to import.

    The kernels release the GIL (``nogil``): they touch only their own arrays, so callers may run
    them on several threads (:func:`models.reconcile.reconcile` runs its multi-start fits so).
    numba's cache index does not record the flag: a cache written before it was set (session 8)
    is loaded as it is and holds the GIL (threads then gain nothing); deleting the
    ``__pycache__/*.nbi`` / ``*.nbc`` files beside the modules rebuilds it.
    """
    try:
        return njit(cache=True, nogil=True)(function)
    except RuntimeError:  # pragma: no cover - read-only installation and home
        return njit(cache=False, nogil=True)(function)
