"""Helpers of the simulation hot path: ordered parallel processing of ray pieces, and pose
transforms that reuse one rotation matrix for every ray of a piece.

NumPy, SciPy and Embree release the GIL inside their loops, so pieces of a frame processed on
a few threads overlap pattern generation, noise, frame changes and ray casting on all cores.
Every ray's result depends only on its own index, so the outcome does not depend on the piece
size or the number of threads.

Environment variables
---------------------
``LIDARSIM_THREADS``
    Threads used by the simulation pipeline and by multi-threaded backends (default: one per
    CPU core; ``1`` runs everything on the calling thread).
``LIDARSIM_PIN_THREADS``
    ``auto`` (default) binds each pool thread to a CPU of its own, ``off`` does not
    (:mod:`lidarsim_core.base.pinning`).
"""

from __future__ import annotations

import functools
import os
import threading
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Callable, Iterable, Iterator, TypeVar

from .pinning import pinning_initializer, pool_cpus

T = TypeVar("T")


R = TypeVar("R")


_pools: dict[tuple[str, int], ThreadPoolExecutor] = {}


_pools_lock = threading.Lock()


_worker = threading.local()


@functools.lru_cache(maxsize=1)
def _cpu_count() -> int:
    return os.cpu_count() or 1


def worker_threads() -> int:
    """Threads to use: ``LIDARSIM_THREADS`` if set (a positive integer within the limit of
    :mod:`lidarsim_core.base.limits`), else the CPU count."""
    from .limits import threads_from_env  # refuses junk and absurd counts with one line

    return threads_from_env(_cpu_count())


def shared_pool(threads: int, purpose: str = "cast") -> ThreadPoolExecutor:
    """A process-wide pool of ``threads`` threads for ``purpose``, created on first use and
    kept (starting threads for every call would cost as much as casting a few thousand rays).

    The pipeline's pieces and the backends' ray parts use different pools, so a piece waiting
    for its ray parts never waits for a thread it holds itself. Each thread is bound to a CPU
    of its own where :func:`~lidarsim_core.base.pinning.pool_cpus` says so.
    """
    with _pools_lock:
        pool = _pools.get((purpose, threads))
        if pool is None:
            cpus = pool_cpus(threads)
            pool = _pools[(purpose, threads)] = ThreadPoolExecutor(
                threads, thread_name_prefix=f"lidarsim-{purpose}",
                initializer=pinning_initializer(cpus) if cpus else None)
        return pool


def in_pipeline_worker() -> bool:
    """Whether the calling thread is processing a piece for :func:`ordered_map`: the pieces
    already keep every core busy, so a backend should not split its rays further."""
    return getattr(_worker, "active", False)


def _as_worker(func: Callable[[T], R], item: T) -> R:
    _worker.active = True
    try:
        return func(item)
    finally:
        _worker.active = False


def piece_size(rays: int, workers: int, largest: int) -> int:
    """Rays per piece: ``rays`` shared evenly by ``workers`` threads, at most ``largest``
    (few, large pieces keep the per-piece Python work small; one per thread keeps every core
    busy)."""
    if workers <= 1:
        return max(1, min(rays, largest))
    pieces = max(workers, -(-rays // largest))
    pieces = -(-pieces // workers) * workers  # a multiple of the thread count
    return max(1, -(-rays // pieces))


def ordered_map(func: Callable[[T], R], items: Iterable[T], workers: int) -> Iterator[R]:
    """``map(func, items)`` on ``workers`` threads, yielding results in order.

    At most ``workers + 1`` items are in flight, so memory stays bounded; closing the
    iterator early cancels what has not started.
    """
    if workers <= 1:
        yield from map(func, items)
        return
    source = iter(items)
    pool = shared_pool(workers, "pipeline")
    pending: deque[Future] = deque()
    try:
        for item in source:
            pending.append(pool.submit(_as_worker, func, item))
            if len(pending) > workers:
                break
        while pending:
            result = pending.popleft().result()
            for item in source:
                pending.append(pool.submit(_as_worker, func, item))
                break
            yield result
    finally:
        for future in pending:
            future.cancel()
        for future in pending:  # let started pieces finish before the caller moves on
            if not future.cancelled():
                future.exception()


def split_range(start: int, stop: int, size: int) -> list[tuple[int, int]]:
    """``[start, stop)`` cut into consecutive pieces of at most ``size``."""
    return [(lo, min(lo + size, stop)) for lo in range(start, stop, size)]
