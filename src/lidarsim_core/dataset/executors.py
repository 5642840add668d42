"""Running frame jobs: in this process, or on a Dask cluster (extra ``dask``).

Both run the same :func:`~lidarsim_core.dataset.frames.run_frame_job`, so the files are the
same to the bit whichever executor and however many workers. Jobs are pulled lazily and at
most a few per worker thread are in flight, so the client's memory does not grow with the
number of frames.
"""

from __future__ import annotations

import functools
import json
import logging
import queue
import threading
from contextlib import ExitStack, contextmanager
from typing import Any, Callable, Iterable, Iterator

from ..base.atomic import deferred_sync, sync_files
from ..base.errors import ConfigError
from ..base.optional import require
from ..plugins.resolve import exporter_named
from .frames import FrameJob, frame_result, run_frame_job, simulate_frame_job, write_frame_job
from .writer_process import sendable, writer_process

OnResult = Callable[[dict[str, Any]], None]
OnDurable = Callable[[list[dict[str, Any]]], None]

#: Jobs in flight per worker thread on Dask (keeps every worker busy between results).
IN_FLIGHT_PER_THREAD = 2


def run_serial(jobs: Iterable[FrameJob], on_result: OnResult, *,
               overlap: bool = True, on_durable: OnDurable | None = None) -> None:
    """Run the jobs one after another in this process.

    With ``overlap`` (the default) writer threads write each frame's file, checksum and
    sidecar while this thread simulates the next frame; at most :data:`WRITE_QUEUE` simulated
    frames wait for it, so memory stays bounded. The files are the same to the bit (the
    same code writes them, each atomically), ``on_result`` is called on this thread in frame
    order, and an error or interrupt on either side stops both: the frame being written is
    finished or left as a ``.part`` file, which the next run removes.

    With ``on_durable`` too, the frames' files are renamed into place without an ``fsync``
    each: a syncing thread makes every block of :data:`SYNC_BLOCK` written frames durable at
    once (:func:`~lidarsim_core.base.atomic.sync_files`) and then passes their results to
    ``on_durable`` (from that thread); the last block is synced before this returns. Without
    it (and without ``overlap``) every file is synced before its rename.
    """
    if not overlap:
        synced: list[dict[str, Any]] = []
        for job in jobs:
            result = run_frame_job(job)  # synced before its rename
            on_result(result)
            synced.append(result)
            if on_durable is not None and len(synced) >= SYNC_BLOCK:
                on_durable(synced)
                synced = []
        if on_durable is not None:
            on_durable(synced)
        return
    writer = _FrameWriter(on_durable)
    try:
        for job in jobs:
            spool, info = simulate_frame_job(job)
            writer.put(job, spool, info)  # waits while the queue is full
            for result in writer.results():
                on_result(result)
        writer.finish()
        for result in writer.results():
            on_result(result)
        writer.finish_sync()
    finally:
        writer.abandon()


#: Simulated frames waiting for the writer threads of :func:`run_serial`.
WRITE_QUEUE = 2
#: Writer threads when every frame is synced on its own: a frame's write then spends most of
#: its time in ``fsync``, which releases the GIL, so two writers keep up with a simulation
#: that is faster than one write.
WRITERS = 2
#: Writer threads when frames are synced a block at a time (``on_durable``): a write is then
#: CPU work (~0.4 ms a frame of 1,000 points), and a second thread would only contend with
#: the simulation's threads for the interpreter (measured: 0.74–0.88 of the in-memory
#: frames/s with one writer, 0.68–0.77 with two, interleaved).
BLOCK_WRITERS = 1
#: Frames made durable together by :func:`run_serial`'s syncing thread (with ``on_durable``).
SYNC_BLOCK = 64
#: Blocks of written frames waiting for the syncing thread.
SYNC_QUEUE = 2


class _FrameWriter:
    """The writer threads of :func:`run_serial`, and with ``on_durable`` the writer process
    (:mod:`~lidarsim_core.dataset.writer_process`) once it is ready; results come back in
    submission order."""

    def __init__(self, on_durable: OnDurable | None = None) -> None:
        self._on_durable = on_durable
        self._block: tuple[list[dict[str, Any]], list[Any]] = ([], [])
        self._sync_queue: queue.Queue[Any] = queue.Queue(maxsize=SYNC_QUEUE)
        self._syncer = threading.Thread(target=self._sync_run, name="lidarsim-syncer",
                                        daemon=True)
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=WRITE_QUEUE)
        self._lock = threading.Lock()
        self._finished: dict[int, dict[str, Any]] = {}
        self._submitted = 0
        self._reported = 0
        self._error: BaseException | None = None
        self._stop = threading.Event()
        self._threads = [threading.Thread(target=self._run, name=f"lidarsim-writer-{i}",
                                          daemon=True)
                         for i in range(WRITERS if on_durable is None else BLOCK_WRITERS)]
        for thread in self._threads:
            thread.start()
        if on_durable is not None:
            self._syncer.start()
        # the last jobs' exporter and options, and whether the writer process has it
        self._exporter: tuple[tuple[str, dict[str, Any]], bool] | None = None
        # frames sent to the writer process: submission number -> (job, info)
        self._sent: dict[int, tuple[FrameJob, Any]] = {}
        self._process = writer_process() if on_durable is not None else None
        if self._process is not None and not self._process.claim(self._written):
            self._process = None  # another run has it: threads only

    def _written(self, number: int, record: dict[str, Any] | None, paths: list[Any],
                 error: BaseException | None) -> None:
        """A frame the writer process wrote (called on its receiving thread)."""
        with self._lock:
            job, info = self._sent.pop(number)
            if error is not None:
                self._error = self._error or error
                return
            assert record is not None
            self._finished[number] = (frame_result(job, info, record), paths)

    def _to_process(self, job: FrameJob, parts: list[dict[str, Any]] | None) -> Any:
        """The writer process if it takes this frame now (ready, a built-in exporter, the
        chunks ``parts`` in memory and of plain columns: :func:`.writer_process.sendable`),
        else ``None``."""
        process = self._process
        if process is None or not process.ready.is_set() or parts is None or \
                not sendable(parts):
            return None
        exporter = (job.exporter, job.exporter_options)
        if self._exporter is None or self._exporter[0] != exporter:  # jobs share theirs
            self._exporter = (exporter, _built_in(*exporter))
        if not self._exporter[1]:
            return None
        while not process.wait_room(0.1):
            self._raise()
            if process.broken is not None:
                raise process.broken
        return process

    def _sync_run(self) -> None:
        assert self._on_durable is not None
        while True:
            item = self._sync_queue.get()
            if item is None:
                return
            results, paths = item
            if self._stop.is_set() or self._error is not None:
                continue
            try:
                sync_files(paths)
                self._on_durable(results)
            except BaseException as exc:  # reported on the simulating thread
                with self._lock:
                    self._error = self._error or exc

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            number, job, spool, info = item
            if self._stop.is_set() or self._error is not None:
                spool.close()  # stopping: drop what is left
                continue
            paths: list[Any] = []
            try:
                if self._on_durable is None:
                    result = write_frame_job(job, spool, info)
                else:
                    with deferred_sync(paths):
                        result = write_frame_job(job, spool, info)
            except BaseException as exc:  # reported on the simulating thread
                with self._lock:
                    self._error = self._error or exc
                continue
            with self._lock:
                self._finished[number] = (result, paths)

    def _raise(self) -> None:
        if self._error is not None:
            raise self._error

    def _alive(self) -> bool:
        return any(thread.is_alive() for thread in self._threads)

    def put(self, job: FrameJob, spool: Any, info: Any) -> None:
        """Queue a simulated frame (after re-raising an error of a writer)."""
        self._raise()
        parts = spool.parts() if self._process is not None else None
        process = self._to_process(job, parts)
        if process is not None:
            with self._lock:
                self._sent[self._submitted] = (job, info)
            dtype = spool.record_dtype
            spool.close()  # the chunks stay alive until they are sent
            process.send(self._submitted, job.path, job.exporter, job.exporter_options,
                         info.to_dict(), dtype, parts)
        else:
            self._put(self._queue, (self._submitted, job, spool, info))
        self._submitted += 1

    def results(self) -> Iterator[dict[str, Any]]:
        """The results written since the last call, in submission order."""
        while True:
            with self._lock:
                done = self._finished.pop(self._reported, None)
            if done is None:
                self._raise()
                return
            self._reported += 1
            result, paths = done
            if self._on_durable is not None:
                self._block[0].append(result)
                self._block[1].extend(paths)
                if len(self._block[0]) >= SYNC_BLOCK:
                    self._flush_block()
            yield result

    def _flush_block(self) -> None:
        """Hand the written frames not yet synced to the syncing thread."""
        if not self._block[0]:
            return
        item, self._block = self._block, ([], [])
        self._put(self._sync_queue, item)

    def _put(self, target: "queue.Queue[Any]", item: Any) -> None:
        """Put ``item`` on a bounded queue, re-raising a worker's error while it is full (a
        dead worker would otherwise leave the queue full for ever)."""
        while True:
            try:
                target.put(item, timeout=0.1)
                return
            except queue.Full:
                self._raise()

    def finish(self) -> None:
        """Wait until every queued frame is written."""
        for _ in self._threads:
            self._queue.put(None)
        while self._alive():
            for thread in self._threads:
                thread.join(0.1)
        if self._process is not None:
            self._process.wait_idle()
        self._raise()

    def finish_sync(self) -> None:
        """Once every result is taken: sync the last frames and wait for the syncing
        thread."""
        if self._on_durable is None:
            return
        self._flush_block()
        self._sync_queue.put(None)
        while self._syncer.is_alive():
            self._syncer.join(0.1)
        self._raise()

    def abandon(self) -> None:
        """Stop after the frames being written (no-op once finished); frames written but not
        yet synced stay unsynced (not passed to ``on_durable``)."""
        if self._process is not None:  # the frames sent are written (or fail), then it is free
            self._process.release()
            self._process = None
        if self._syncer.is_alive():
            self._stop.set()
            while self._syncer.is_alive():
                try:
                    self._sync_queue.put(None, timeout=0.1)
                except queue.Full:
                    continue
        if not self._alive():
            return
        self._stop.set()
        while self._alive():
            try:  # the threads close the spools they take, then meet a sentinel
                self._queue.put(None, timeout=0.1)
            except queue.Full:
                continue
        while True:  # close the spools nobody will write
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                break
            if item is not None:
                item[2].close()


@functools.lru_cache(maxsize=16)
def _built_in_options(name: str, options: str) -> bool:
    exporter = exporter_named(name, json.loads(options))
    return type(exporter).__module__.startswith("lidarsim_core.")


def _built_in(name: str, options: dict[str, Any]) -> bool:
    """Whether the exporter ``name`` is one of lidarsim's (the writer process resolves it
    by name; a plugin's exporter is written on a thread, where it was registered)."""
    return _built_in_options(name, json.dumps(options, sort_keys=True))


def _dask() -> Any:
    return require("dask.distributed", extra="dask", what="--workers/--scheduler",
                   error=ConfigError, field="workers")


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


def run_dask(jobs: Iterable[Any], on_result: OnResult, *, workers: int | None = None,
             scheduler: str | None = None, timeout_s: float = 60.0,
             task: Callable[[Any], dict[str, Any]] = run_frame_job) -> None:
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
    task
        What a worker runs on each job (default: a frame job; shard jobs pass
        :func:`~lidarsim_core.dataset.shards.run_shard_job`).
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
            future = client.submit(task, job, pure=False)
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
