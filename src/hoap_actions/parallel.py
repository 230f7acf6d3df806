"""Independent jobs on worker processes, local or on a Ray cluster, their results in job order.

The sweeps (``hoap-actions demo``'s episodes, ``record``'s demonstrations) hand their jobs to
:func:`ordered_map`. Every job depends on its own arguments alone (an episode on its seed) and the
results come back in the order of the jobs, so what a sweep writes is the same whatever ran it: one
process, ``workers`` local processes, or Ray actors on one machine or a cluster.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, TypeVar

from hoap_actions.errors import InvalidInputError

Job = TypeVar("Job")
Result = TypeVar("Result")

LOCAL_RAY = "local"
"""``ray_address`` that starts a Ray instance on this machine (instead of joining a cluster)."""


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
    survive a fork."""
    if ray_address is not None:
        return _ray_map(function, jobs, initializer, initargs, workers, ray_address)
    return _process_map(function, jobs, initializer, initargs, workers)


def check_ray_address(address: object) -> str:
    """``address`` as given, if it can name a Ray instance; else :class:`InvalidInputError`."""
    if not isinstance(address, str) or not address.strip():
        raise InvalidInputError(f"ray address {address!r} is empty; give {LOCAL_RAY!r}, 'auto' or a cluster address "
                                "such as ray://head:10001")
    return address


def _process_map(function, jobs, initializer, initargs, workers) -> Iterator:
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(workers, mp_context=context, initializer=initializer, initargs=initargs) as pool:
        yield from pool.map(function, jobs)


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
