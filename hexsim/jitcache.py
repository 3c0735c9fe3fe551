"""numba's on-disk cache across files: drop a compiled function's cache when a callee's file changed.

numba keys the cache of a ``cache=True`` function on its own file's time stamp only; a compiled function
that calls into another file (the runners in :mod:`hexsim.engine.native` call :func:`hexsim.plant.legs.step_legs`
and :func:`compensation.buffered.buffered_tick`) would keep running the old callee after an edit there
(numba documents that changes in other files are not detected). :func:`guard` keeps a marker next to
the cache with the callees' time stamps and sizes and flushes the cache when they differ.
"""

from __future__ import annotations

import os
import pathlib


def guard(dispatchers, *callee_files: str) -> None:
    """Flush the on-disk cache of each numba dispatcher in ``dispatchers`` whose callee files
    (paths, e.g. ``module.__file__``) changed since it was written. A read-only cache directory is left
    alone (numba then keeps no cache there to go stale either)."""
    try:
        stamp = ";".join(f"{st.st_mtime_ns} {st.st_size}" for st in map(os.stat, callee_files))
    except OSError:
        return
    for dispatcher in dispatchers:
        cache = getattr(dispatcher, "_cache", None)  # numba's FunctionCache of a cache=True dispatcher
        if cache is None or not hasattr(cache, "flush"):
            continue
        name = f"{dispatcher.py_func.__module__}.{dispatcher.py_func.__name__}.callee-stamp"
        try:
            marker = pathlib.Path(cache.cache_path) / name
            if not marker.exists() or marker.read_text() != stamp:
                cache.flush()
                marker.write_text(stamp)
        except OSError:
            pass
