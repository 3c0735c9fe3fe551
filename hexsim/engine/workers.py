"""Worker processes for sweeps, compensator comparisons and effect fits.

Workers are forked from the calling process where the platform can (Linux), so they start with numpy,
scipy, MuJoCo and the compiled kernels already imported, in milliseconds; spawned workers (the only way
on macOS and Windows, or ``start_method="spawn"``) import all of it first, about 2.5 s each on a 2-vCPU
machine. Each worker loads its own MuJoCo model. MuJoCo's control callback is process-global: at the
fork the caller runs no simulation, so none is installed (:func:`hexsim.engine.runner.simulate` installs it
only for a python-engine run and always removes it), and a worker installs its own.

With a Dask scheduler (``scheduler``: ``"local"`` for a :class:`distributed.LocalCluster` of ``jobs``
single-threaded worker processes on this machine, or the address of a running scheduler, which is how a
lab's SLURM/PBS or Kubernetes cluster is reached through dask-jobqueue or dask-kubernetes) the same calls
go to Dask's workers through :meth:`distributed.Client.get_executor`; the results are the same, in the
same order. Dask is the optional extra ``pip install "hexsim[cluster]"``.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import sys
import warnings
from collections.abc import Iterator
from concurrent.futures import Executor, ProcessPoolExecutor

from hexsim.errors import InputError

#: Ways to start the workers.
START_METHODS = ("fork", "spawn", "forkserver")


def default_start_method() -> str:
    """``fork`` where the platform has it, else ``spawn``."""
    return "fork" if "fork" in multiprocessing.get_all_start_methods() else "spawn"


def _warm_up() -> None:
    """Import the simulator (MuJoCo, numba, the runner) in a Dask worker and load its compiled kernel from
    numba's disk cache (by setting a run up, which calls the kernel for zero steps), before the first task:
    a 0.4 s run would otherwise pay 1.5 s of imports and 0.2 s of loading in every worker."""
    from hexsim.control.scenario import make_scenario
    from hexsim.engine.config import RunConfig
    from hexsim.engine.runner import Simulator

    Simulator(RunConfig(make_scenario("heave", duration=6.0)))


#: The function :func:`forked_map`'s workers evaluate: set before they are forked, so they inherit it.
_MAPPED = None


def _call_mapped(x):
    return _MAPPED(x)


def forked_map(jobs: int):
    """A map-like callable for scipy's ``workers`` (``scipy.optimize.least_squares``' finite differences):
    ``mapper(fun, iterable)`` evaluates ``fun`` over ``iterable`` in ``jobs`` processes forked for that call, so
    ``fun`` need not pickle (a closure over replays and their MuJoCo models: each worker starts with it), and
    returns the list of results in order. Forking a worker costs milliseconds against a Jacobian's column,
    a replay of its logs. The builtin ``map`` where ``jobs`` <= 1 or the platform cannot fork."""
    if jobs <= 1 or "fork" not in multiprocessing.get_all_start_methods():
        return map

    def mapper(fun, iterable):
        global _MAPPED
        _MAPPED = fun
        try:
            with multiprocessing.get_context("fork").Pool(jobs) as pool:
                return pool.map(_call_mapped, list(iterable))
        finally:
            _MAPPED = None

    return mapper


def _ready() -> None:
    """A no-op submitted once per worker, so the pool forks its workers before it is handed out."""


@contextlib.contextmanager
def worker_pool(jobs: int, start_method: str | None = None) -> Iterator[Executor]:
    """A :class:`concurrent.futures.Executor` for ``jobs`` parallel calls: the active Dask client's
    (:func:`dask_client`, or any ``distributed.Client`` the caller made, the Dask convention) when there is
    one, else a :class:`ProcessPoolExecutor` of ``jobs`` workers started by ``start_method`` (one of
    :data:`START_METHODS`; None: :func:`default_start_method`), the workers already running.

    Make progress bars after entering: a bar may start a monitor thread, and threads should not exist
    at a fork. Raises InputError for a start method this platform does not have."""
    client = _active_dask_client()
    if client is not None:
        yield client.get_executor(pure=False)
        return
    method = start_method or default_start_method()
    if method not in multiprocessing.get_all_start_methods():
        raise InputError(f"start method {method!r} is not available here; choose one of "
                         f"{', '.join(multiprocessing.get_all_start_methods())}")
    import hexsim.engine.config  # noqa: F401
    import hexsim.engine.native  # noqa: F401 - imported once here, inherited by forked workers

    with ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context(method)) as pool:
        with warnings.catch_warnings():
            # Python >= 3.12 warns about forking a process that has threads; the only ones here are
            # OpenBLAS's idle pool, which re-initialises itself in the child (pthread_atfork)
            warnings.filterwarnings("ignore", message=".*multi-threaded.*fork", category=DeprecationWarning)
            for fut in [pool.submit(_ready) for _ in range(jobs)]:
                fut.result()
        yield pool


def in_workers(jobs: int) -> bool:
    """Whether calls for ``jobs`` workers go to worker processes: more than one job, or a Dask client is
    active (then even one job runs on its workers)."""
    return jobs > 1 or _active_dask_client() is not None


def worker_count(jobs: int) -> int:
    """How many workers the calls for ``jobs`` get: the active Dask client's workers, else ``jobs``."""
    client = _active_dask_client()
    return jobs if client is None else len(client.scheduler_info()["workers"])


def _active_dask_client():
    """The default ``distributed.Client`` of this process, or None (Dask not imported or no client)."""
    distributed = sys.modules.get("distributed")
    if distributed is None:
        return None
    try:
        return distributed.default_client()
    except ValueError:
        return None


#: [s] How long a Dask client tries to reach a running scheduler before it gives up (:func:`dask_client`).
SCHEDULER_TIMEOUT_S = 10.0


@contextlib.contextmanager
def dask_client(scheduler: str, jobs: int):
    """A Dask client, the default one while open (so every :func:`worker_pool` inside runs on it): on a
    LocalCluster of ``jobs`` single-threaded worker processes for ``scheduler`` = "local", else on the
    running scheduler at the address ``scheduler`` (e.g. ``tcp://head-node:8786``). Closed on exit.
    Raises InputError without Dask installed or for a scheduler that cannot be reached."""
    try:
        import distributed
    except ImportError:
        raise InputError('--scheduler needs Dask: pip install "hexsim[cluster]"') from None
    import logging

    cluster = None
    try:
        if scheduler == "local":
            cluster = distributed.LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True,
                                               dashboard_address=None, silence_logs=logging.ERROR)
            client = distributed.Client(cluster, set_as_default=True)
        else:
            client = distributed.Client(scheduler, timeout=f"{SCHEDULER_TIMEOUT_S}s", set_as_default=True)
    except (OSError, TimeoutError) as exc:
        if cluster is not None:
            cluster.close()
        raise InputError(f"--scheduler {scheduler}: cannot reach a Dask scheduler there ({exc})") from None
    try:
        client.run(_warm_up)  # import the simulator on every worker once, before the timed work
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
