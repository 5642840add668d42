"""Running frame jobs: in this process, or on a Dask cluster (extra ``dask``).

Both run the same :func:`~lidarsim_core.dataset.frames.run_frame_job`, so the files are the
same to the bit whichever executor and however many workers. Jobs are pulled lazily and at
most a few per worker thread are in flight, so the client's memory does not grow with the
number of frames.
"""

from __future__ import annotations

import logging
from contextlib import ExitStack, contextmanager
from typing import Any, Callable, Iterable, Iterator

from ..errors import ConfigError
from .frames import FrameJob, run_frame_job

OnResult = Callable[[dict[str, Any]], None]

#: Jobs in flight per worker thread on Dask (keeps every worker busy between results).
IN_FLIGHT_PER_THREAD = 2


def run_serial(jobs: Iterable[FrameJob], on_result: OnResult) -> None:
    """Run the jobs one after another in this process."""
    for job in jobs:
        on_result(run_frame_job(job))


def _dask() -> Any:
    try:
        from dask import distributed
    except ImportError as exc:
        raise ConfigError(f"--workers/--scheduler need Dask ({exc}); pip install "
                          "'lidarsim-core[dask]'", field="workers") from None
    return distributed


@contextmanager
def local_cluster(workers: int) -> Iterator[Any]:
    """A ``LocalCluster`` of ``workers`` single-threaded processes on 127.0.0.1, no dashboard.

    Each worker's simulation pipeline is single-threaded too (``LIDARSIM_THREADS=1``; the
    results do not depend on it) so ``workers`` processes use ``workers`` cores, and Dask's
    sampling profiler, which costs a few per cent of a busy Python worker, is off.
    """
    distributed = _dask()
    import dask

    environ = {**dask.config.get("distributed.nanny.pre-spawn-environ", {}),
               "LIDARSIM_THREADS": "1"}
    with dask.config.set({"distributed.nanny.pre-spawn-environ": environ,
                          "distributed.worker.profile.enabled": False}):
        cluster = distributed.LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
            dashboard_address=None, silence_logs=logging.CRITICAL)
    with cluster:
        yield cluster


def run_dask(jobs: Iterable[FrameJob], on_result: OnResult, *, workers: int | None = None,
             scheduler: str | None = None, timeout_s: float = 60.0) -> None:
    """Run the jobs on Dask: a local cluster of ``workers`` processes, or ``scheduler``.

    Parameters
    ----------
    jobs
        Frame jobs (consumed lazily).
    on_result
        Called in this process with each job's result, in completion order.
    workers
        Start a ``LocalCluster`` of this many single-threaded worker processes on 127.0.0.1
        (no dashboard); it is shut down at the end, also on errors and interrupts.
    scheduler
        Address of an existing scheduler (e.g. ``tcp://head:8786``); its workers must see
        the output directory at the same path.
    timeout_s
        Time allowed to start the cluster or reach the scheduler.
    """
    if (workers is None) == (scheduler is None):
        raise ConfigError("give either a number of workers or a scheduler address",
                          field="workers")
    distributed = _dask()
    with ExitStack() as stack:
        if scheduler is not None:
            try:
                client = stack.enter_context(distributed.Client(scheduler, timeout=timeout_s))
            except OSError as exc:
                raise ConfigError(f"cannot reach the Dask scheduler at {scheduler}: {exc}",
                                  field="scheduler") from None
        else:
            assert workers is not None
            cluster = stack.enter_context(local_cluster(workers))
            client = stack.enter_context(distributed.Client(cluster, timeout=timeout_s))
        threads = sum(client.nthreads().values()) or 1
        pending = iter(jobs)
        running = distributed.as_completed()
        in_flight: set[Any] = set()

        def submit_next() -> bool:
            job = next(pending, None)
            if job is None:
                return False
            future = client.submit(run_frame_job, job, pure=False)
            in_flight.add(future)
            running.add(future)
            return True

        for _ in range(IN_FLIGHT_PER_THREAD * threads):
            if not submit_next():
                break
        try:
            for future in running:
                in_flight.discard(future)
                result = future.result()
                future.release()
                on_result(result)
                submit_next()
        except BaseException:
            client.cancel(list(in_flight))
            raise
