"""Worker processes for sweeps, compensator comparisons and effect fits.

Workers are forked from the calling process where the platform can (Linux), so they start with numpy,
scipy, MuJoCo and the compiled kernels already imported, in milliseconds; spawned workers (the only way
on macOS and Windows, or ``start_method="spawn"``) import all of it first, about 2.5 s each on a 2-vCPU
machine. Each worker loads its own MuJoCo model. MuJoCo's control callback is process-global: at the
fork the caller runs no simulation, so none is installed (:func:`hexsim.runner.simulate` installs it
only for a python-engine run and always removes it), and a worker installs its own.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import warnings
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor

from hexsim.errors import InputError

#: Ways to start the workers.
START_METHODS = ("fork", "spawn", "forkserver")


def default_start_method() -> str:
    """``fork`` where the platform has it, else ``spawn``."""
    return "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"


def _ready() -> None:
    """A no-op submitted once per worker, so the pool forks its workers before it is handed out."""


@contextlib.contextmanager
def worker_pool(jobs: int, start_method: str | None = None) -> Iterator[ProcessPoolExecutor]:
    """A :class:`ProcessPoolExecutor` of ``jobs`` workers started by ``start_method`` (one of
    :data:`START_METHODS`; None: :func:`default_start_method`), the workers already running.

    Make progress bars after entering: a bar may start a monitor thread, and threads should not exist
    at a fork. Raises InputError for a start method this platform does not have."""
    method = start_method or default_start_method()
    if method not in multiprocessing.get_all_start_methods():
        raise InputError(f"start method {method!r} is not available here; choose one of "
                         f"{', '.join(multiprocessing.get_all_start_methods())}")
    import hexsim.native  # noqa: F401 - imported once here, inherited by forked workers
    import hexsim.simulation  # noqa: F401

    with ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context(method)) as pool:
        with warnings.catch_warnings():
            # Python >= 3.12 warns about forking a process that has threads; the only ones here are
            # OpenBLAS's idle pool, which re-initialises itself in the child (pthread_atfork)
            warnings.filterwarnings("ignore", message=".*multi-threaded.*fork", category=DeprecationWarning)
            for fut in [pool.submit(_ready) for _ in range(jobs)]:
                fut.result()
        yield pool
