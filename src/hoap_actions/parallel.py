"""Independent jobs on worker processes, local or on a Ray cluster, their results in job order.

The sweeps (``hoap-actions demo``'s episodes, ``record``'s demonstrations) hand their jobs to
:func:`ordered_map`. Every job depends on its own arguments alone (an episode on its seed) and the
results come back in the order of the jobs, so what a sweep writes is the same whatever ran it: one
process, ``workers`` local processes, or Ray actors on one machine or a cluster.
"""

from __future__ import annotations

import collections
import contextlib
import multiprocessing
import os
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from typing import Any, TypeVar

from hoap_actions.errors import InvalidInputError

Job = TypeVar("Job")
Result = TypeVar("Result")

LOCAL_RAY = "local"
"""``ray_address`` that starts a Ray instance on this machine (instead of joining a cluster)."""
JOBS_AHEAD_PER_WORKER = 2
"""Jobs handed to the local processes ahead of the one awaited, per process: enough to keep them busy,
few enough that stopping a sweep never waits for a queue of thousands."""
PARENT_CHECK_S = 0.5
"""How often a worker process checks that the process that started it is still there."""
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
"""What OpenBLAS, OpenMP and MKL builds read for their thread count when a process loads them."""


def ordered_map(
    function: Callable[[Job], Result],
    jobs: Sequence[Job],
    initializer: Callable[..., None],
    initargs: tuple = (),
    workers: int = 2,
    ray_address: str | None = None,
) -> Iterator[Result]:
    """``function(job)`` for every job, yielded in job order, on ``workers`` spawned processes or,
    with ``ray_address``, on Ray actors (:data:`LOCAL_RAY` for a Ray instance on this machine, or a
    cluster address such as ``"auto"`` or ``"ray://head:10001"``; ``workers`` actors, or one per CPU
    of the cluster when ``workers`` is 1, never more than its CPUs). Each process or actor first runs
    ``initializer(*initargs)``, which sets up what ``function`` uses (an env, a scene); both must be
    importable module-level functions. Processes are spawned, not forked: PyBullet and placo do not
    survive a fork. Local processes are given a few jobs at a time; if the caller stops early (an
    error, Ctrl-C, SIGTERM turned into KeyboardInterrupt) they are ended at once, and a process whose
    parent died ends itself. More local processes than this machine's CPUs are refused."""
    if ray_address is not None:
        return _ray_map(function, jobs, initializer, initargs, workers, ray_address)
    cpus = os.cpu_count() or 1
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= cpus:
        raise InvalidInputError(f"workers must be an int in 1..{cpus} (this machine's CPUs); got {workers!r} "
                                "(on a Ray cluster, --ray takes more)")
    return _process_map(function, jobs, initializer, initargs, workers)


def check_ray_address(address: object) -> str:
    """``address`` as given, if it can name a Ray instance; else :class:`InvalidInputError`."""
    if not isinstance(address, str) or not address.strip():
        raise InvalidInputError(f"ray address {address!r} is empty; give {LOCAL_RAY!r}, 'auto' or a cluster address "
                                "such as ray://head:10001")
    return address


def _process_map(function, jobs, initializer, initargs, workers) -> Iterator:
    context = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(workers, mp_context=context, initializer=_start_watched_worker,
                               initargs=(os.getpid(), initializer, initargs))
    pending: collections.deque[Future] = collections.deque()
    queue = iter(jobs)
    finished = False
    try:
        with _one_blas_thread_per_worker():  # the processes are spawned by these first submissions
            for job in queue:
                pending.append(pool.submit(function, job))
                if len(pending) >= JOBS_AHEAD_PER_WORKER * workers:
                    break
        while pending:
            result = pending.popleft().result()
            for job in queue:  # keep the window full: one new job for each one done
                pending.append(pool.submit(function, job))
                break
            yield result
        finished = True
    finally:
        if finished:
            pool.shutdown(wait=True)
        else:  # stopped early: nothing queued runs, and the running jobs are not waited for
            _end_workers(pool)


@contextlib.contextmanager
def _one_blas_thread_per_worker() -> Iterator[None]:
    """Worker processes spawned meanwhile use one BLAS thread each (unless the caller's environment says
    otherwise): ``workers`` processes then share ``workers`` cores, where BLAS's default of a thread per
    core in every process oversubscribes them (products several times slower, measured in recognition)."""
    unset = [name for name in BLAS_THREAD_VARIABLES if name not in os.environ]
    os.environ.update(dict.fromkeys(unset, "1"))
    try:
        yield
    finally:
        for name in unset:
            os.environ.pop(name, None)


def _end_workers(pool: ProcessPoolExecutor) -> None:
    """Cancel what is queued and terminate the pool's processes now (the executor's own API from Python
    3.14 on; before it, its process table, which ``shutdown`` forgets, is read first)."""
    terminate = getattr(pool, "terminate_workers", None)
    if terminate is not None:
        terminate()  # cancels what is queued, terminates the processes, shuts the executor down
        return
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.terminate()
    deadline = time.monotonic() + 2.0
    for process in processes:
        process.join(max(0.0, deadline - time.monotonic()))


def _start_watched_worker(parent: int, initializer: Callable[..., None], initargs: tuple) -> None:
    """A worker's start: a thread that ends the process once its parent is gone (killed, crashed), then
    the caller's ``initializer``."""
    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_CHECK_S)
        os._exit(1)

    threading.Thread(target=watch, name="hoap-actions-parent-watch", daemon=True).start()
    initializer(*initargs)


class _RayWorker:
    """One Ray actor: the initialised state of a worker process, kept between its jobs."""

    def __init__(self, initializer: Callable[..., None], initargs: tuple) -> None:
        initializer(*initargs)

    def run(self, function: Callable[[Any], Any], job: Any) -> Any:
        return function(job)


def _ray_map(function, jobs, initializer, initargs, workers, address) -> Iterator:
    check_ray_address(address)
    try:
        import ray
        from ray.util import ActorPool
    except ImportError:
        raise InvalidInputError("Ray is not installed; pip install 'hoap-actions[ray]' (or leave --ray out)") from None
    started = not ray.is_initialized()
    if started:
        try:
            ray.init(address=None if address == LOCAL_RAY else address, include_dashboard=False, log_to_driver=False,
                     configure_logging=False)
        except Exception as exc:  # Ray raises ConnectionError, ValueError or RuntimeError for a bad address
            raise InvalidInputError(f"could not start or join Ray at {address!r} ({type(exc).__name__}: {exc}); "
                                    f"give {LOCAL_RAY!r} for this machine "
                                    "or the address of a running cluster") from None
    actors = []
    try:
        cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
        # one CPU per actor, never more actors than CPUs: an actor that is never placed would hold
        # its first job, and every result after it, forever
        count = min(workers if workers > 1 else cpus, cpus, len(jobs))
        actor_class = ray.remote(num_cpus=1)(_RayWorker)
        actors = [actor_class.remote(initializer, initargs) for _ in range(count)]
        yield from ActorPool(actors).map(lambda actor, job: actor.run.remote(function, job), list(jobs))
    finally:
        for actor in actors:
            ray.kill(actor)
        if started:
            ray.shutdown()
