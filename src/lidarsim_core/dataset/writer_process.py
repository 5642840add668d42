"""A child process that writes a serial dataset's frames beside the simulation.

Writing a frame is Python work: the PLY header and the sidecar's JSON, the records converted to
the file's layout, the checksum, the files. On a thread it holds the interpreter lock that the
simulating thread needs between its compiled loops: a serial ``lidarsim dataset`` ran at
0.72-0.78 of the in-memory frames/s however the writing was trimmed. In a process of its own it
has a lock of its own and runs on whatever core time the simulation leaves (0.78-0.94 of the
same in-memory frames/s, docs/performance.md, "In a writer process of its own").

The simulating process sends each frame as its spool holds it: the columns of its pieces,
not joined (the child joins them into records, :func:`joined_records`, ~30 µs a frame taken
off the simulating thread). A frame is a header (framed as ``Connection.send`` frames it,
:func:`_framed`: its path, exporter, frame metadata, each piece's length and its columns'
dtypes, the records' dtype when it changed) and the columns' bytes, all in one ``writev``
(:func:`_layout`). The child writes the frame
with the same :func:`~lidarsim_core.io.write.write_points_file` inside
:func:`~lidarsim_core.base.atomic.deferred_sync` and answers with the frame's record and the
paths to sync, for up to :data:`REPLY_FRAMES` frames in one reply (each reply wakes the
parent's receiving thread, whose Python takes turns with the simulation's at the
interpreter lock). The files are the same to the bit as the thread's.

The child is started once per process, on first use (:func:`writer_process`), as ``python -c``
with this process's import path, in a process group of its own: the terminal's Ctrl-C reaches
only the simulating process, which stops sending and waits for the frames sent (each written
atomically or left as a ``.part`` file, as on a thread). It exits when the pipe closes: at the
parent's exit, or when the parent dies (then without writing the frames still in the pipe).
Until it is ready (the imports take ~0.35 s) and for what it cannot take (an exporter that is
not built in, a frame spilled to disk, columns that are not plain bytes: :func:`sendable`),
frames go to the writer thread.

Environment variables
---------------------
``LIDARSIM_WRITER``
    ``process`` (default on Linux and macOS) or ``threads`` (the writer threads only; the
    default elsewhere).
"""

from __future__ import annotations

import atexit
import json
import os
import select
import struct
import subprocess
import sys
import threading
from multiprocessing.reduction import ForkingPickler
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..base import errors
from ..base.limits import env_choice

#: Values of ``LIDARSIM_WRITER``.
MODES = ("process", "threads")
#: Frames sent to the child and not yet answered (the pipe holds their records; a frame
#: larger than its room waits in ``writev``).
IN_FLIGHT = 8
#: Frames the child answers in one reply at most; it answers sooner when no frame comes
#: within :data:`REPLY_WAIT_S` (one wake-up of the parent's receiving thread per reply, whose
#: Python work takes turns with the simulation's at the interpreter lock).
REPLY_FRAMES = 4
#: Seconds the child waits for another frame before it answers those it wrote (at the end of
#: a run the parent asks for the answers at once).
REPLY_WAIT_S = 0.002
#: Capacity asked for the pipe to the child (Linux): a few frames of ~1,000 points.
PIPE_BYTES = 2 ** 20
#: Seconds to wait for the child to finish the frames sent when a run stops or the process
#: exits, before it is killed.
STOP_TIMEOUT_S = 60.0

#: What the parent receives for a frame: ``(token, result or None, paths, error or None)``.
Reply = Callable[[int, "dict[str, Any] | None", "list[str]", "BaseException | None"], None]


def mode() -> str:
    """``LIDARSIM_WRITER`` (validated): ``process`` or ``threads``."""
    if os.name != "posix":
        return "threads"
    return env_choice("LIDARSIM_WRITER", MODES)


#: The child's program: this process's import path, then :func:`serve`.
_CHILD = ("import json, sys; sys.path[:] = json.loads(sys.argv[1]); "
          "from lidarsim_core.dataset.writer_process import serve; "
          "serve(int(sys.argv[2]), int(sys.argv[3]))")


class WriterProcess:
    """The child, and the thread that receives its replies (see the module docstring).

    One run at a time sends frames (:meth:`claim`); the others write on threads.
    """

    def __init__(self) -> None:
        from multiprocessing.connection import Connection

        to_child_r, to_child_w = os.pipe()
        from_child_r, from_child_w = os.pipe()
        try:  # the child imports what this process imports, from where it does
            self._child = subprocess.Popen(
                [sys.executable, "-c", _CHILD, json.dumps(sys.path), str(to_child_r),
                 str(from_child_w)],
                pass_fds=(to_child_r, from_child_w), process_group=0,
                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL)  # its errors come back as frames' errors
        except BaseException:
            os.close(to_child_w)
            os.close(from_child_r)
            raise
        finally:
            os.close(to_child_r)
            os.close(from_child_w)
        import fcntl  # POSIX: mode() is "threads" elsewhere

        if hasattr(fcntl, "F_SETPIPE_SZ"):
            try:
                fcntl.fcntl(to_child_w, fcntl.F_SETPIPE_SZ, PIPE_BYTES)
            except OSError:  # above /proc/sys/fs/pipe-max-size: the default, 64 KiB
                pass
        self._tx = Connection(to_child_w, readable=False)
        self._dtype: Any = None  # the records' dtype the child has (sent when it changes)
        self._rx = Connection(from_child_r, writable=False)
        self.pid = os.getpid()
        self.ready = threading.Event()
        self._lock = threading.Lock()
        self._claimed = False
        self._reply: Reply | None = None
        self._in_flight: dict[int, str] = {}
        self._idle = threading.Condition(self._lock)
        self.broken: BaseException | None = None
        #: Frames sent so far (all runs).
        self.sent = 0
        self._receiver = threading.Thread(target=self._receive, name="lidarsim-writer-rx",
                                          daemon=True)
        self._receiver.start()

    # ---- the run that uses it ----------------------------------------------------------------
    def claim(self, reply: Reply) -> bool:
        """Take the child for one run (``reply`` receives its frames); False if another run
        has it or it is not usable."""
        with self._lock:
            if self._claimed or self.broken is not None:
                return False
            self._claimed, self._reply = True, reply
            return True

    def release(self) -> None:
        """End the run: wait for the frames sent (their replies still go to the run's
        ``reply``), then free the child for the next run."""
        self.wait_idle()
        with self._lock:
            self._claimed, self._reply = False, None

    def wait_idle(self, timeout_s: float = STOP_TIMEOUT_S) -> None:
        """Wait until every frame sent has its reply (the child is killed after
        ``timeout_s``)."""
        with self._lock:
            answer_now = bool(self._in_flight) and self.broken is None
        if answer_now:  # no more frames are coming: the child need not wait for them
            try:  # (never blocking: a child that reads nothing is timed out below)
                if select.select([], [self._tx.fileno()], [], 0)[1]:
                    self._tx.send(None)
            except OSError:  # the child is gone: its receiver says so
                pass
        with self._idle:
            done = self._idle.wait_for(lambda: not self._in_flight, timeout_s)
        if not done:
            self._child.kill()
            self._fail(errors.OutputError(
                f"the dataset writer process did not finish within {timeout_s:.0f} s"))

    def wait_room(self, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` until another frame may be sent (:data:`IN_FLIGHT`) or
        the child failed; whether it may."""
        with self._idle:
            self._idle.wait_for(lambda: len(self._in_flight) < IN_FLIGHT or
                                self.broken is not None, timeout_s)
            return len(self._in_flight) < IN_FLIGHT and self.broken is None

    def send(self, token: int, path: str, exporter: str, options: dict[str, Any],
             frame: dict[str, Any], dtype: Any, parts: list[dict[str, Any]]) -> None:
        """Send a frame to write: ``parts``, the columns of its chunks (each C-contiguous,
        of a plain dtype: :func:`sendable`), which the child joins into records of the
        structured ``dtype`` as :meth:`~lidarsim_core.io.points.PointSpool.records` does.
        The pipe holds :data:`PIPE_BYTES`, so the frames in flight are sent without
        waiting for the child unless they are larger."""
        with self._lock:
            if self.broken is not None:
                raise self.broken
            self._in_flight[token] = path
            self.sent += 1
        try:
            changed = self._dtype is None or self._dtype != dtype  # a run's spools share one
            self._dtype = None  # until the child has it
            layout, columns = _layout(parts)
            header = _framed((token, path, exporter, options, frame,
                              dtype if changed else None, layout))
            _write_all(self._tx.fileno(), [*header, *columns])  # one write, one wake-up
            self._dtype = dtype
        except BaseException as exc:  # the child is gone, or a frame half-sent: unusable
            code = self._child.poll()
            self._child.kill()
            # a child that died says so as the receiving thread would, whichever sees it first
            self._fail(errors.OutputError(
                f"the dataset writer process stopped (exit code {code})" if code is not None
                else f"cannot send a frame to the dataset writer process: {exc}", source=path))
            if isinstance(exc, Exception):
                raise self.broken from None
            raise

    # ---- the child's replies -----------------------------------------------------------------
    def _receive(self) -> None:
        while True:
            try:
                message = self._rx.recv()
            except (EOFError, OSError):
                code = self._child.poll()
                self._fail(errors.OutputError(
                    "the dataset writer process stopped"
                    + ("" if code is None else f" (exit code {code})")))
                return
            if message[0] == "ready":
                self.ready.set()
                continue
            with self._lock:
                reply = self._reply
                named = [(frame, self._in_flight.get(frame[0])) for frame in message[1]]
            for (token, result, paths, error), path in named:
                exc = None if error is None else _rebuilt(error, path)
                if reply is not None:
                    reply(token, result, paths, exc)
            self._in_flight_done([frame[0] for frame in message[1]])

    def _in_flight_done(self, tokens: list[int]) -> None:
        """The frames ``tokens`` are answered: room for as many more."""
        with self._idle:
            for token in tokens:
                self._in_flight.pop(token, None)
            self._idle.notify_all()

    def _fail(self, exc: BaseException) -> None:
        """Mark the child unusable; frames still in flight get ``exc`` as their reply."""
        with self._lock:
            if self.broken is None:
                self.broken = exc
            pending = list(self._in_flight)
            reply = self._reply
        for token in pending:
            if reply is not None:
                reply(token, None, [], self.broken)
        with self._idle:
            self._in_flight.clear()
            self._idle.notify_all()

    def cpu_seconds(self) -> float | None:
        """CPU time the child has used (user and system; Linux's ``/proc``, in clock ticks
        of 10 ms), or ``None`` where it cannot be read."""
        try:
            stat = Path(f"/proc/{self._child.pid}/stat").read_text(encoding="ascii")
            fields = stat.rsplit(")", 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
        except (OSError, ValueError, IndexError):
            return None

    def close(self) -> None:
        """Close the pipe (the child exits after the frames sent) and wait for it."""
        self._tx.close()
        try:
            self._child.wait(STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self._child.kill()
            self._child.wait()


def _rebuilt(error: tuple[str, str, str | None, str | None], path: str | None
             ) -> BaseException:
    """The child's exception as the parent raises it: a :class:`UserInputError` class of
    :mod:`lidarsim_core.base.errors` as itself (message, file and field), anything else as
    an :class:`~lidarsim_core.base.errors.OutputError` naming the frame's file."""
    name, message, source, field = error
    kind = getattr(errors, name, None)
    if isinstance(kind, type) and issubclass(kind, errors.UserInputError):
        return kind(message, source=source, field=field)
    return errors.OutputError(f"writing the frame failed ({name}: {message})", source=path)


#: Kinds of dtype whose columns go to the child as bytes (booleans, integers, floating and
#: complex numbers, fixed-size strings: what a buffer exports and ``dtype.str`` names).
_PLAIN_KINDS = frozenset("biufcSU")


def sendable(parts: list[dict[str, Any]]) -> bool:
    """Whether :meth:`WriterProcess.send` can send these chunks' columns as bytes: every one
    one-dimensional, C-contiguous and of a plain dtype (:data:`_PLAIN_KINDS`); other frames
    are written on a thread, as they always were."""
    return all(isinstance(values, np.ndarray) and values.ndim == 1 and
               values.flags.c_contiguous and values.dtype.kind in _PLAIN_KINDS
               for part in parts for values in part.values())


def _layout(parts: list[dict[str, Any]]) -> tuple[list[tuple[int, list[str]]], list[Any]]:
    """Each chunk's length and its columns' dtypes, and the columns in that order (not
    copied; :func:`_write_all` sends their bytes): what follows a frame's header down the
    pipe."""
    layout = [(len(next(iter(part.values()))), [v.dtype.str for v in part.values()])
              for part in parts]
    return layout, [values for part in parts for values in part.values()]


def joined_records(dtype: Any, layout: list[tuple[int, list[str]]], data: Any) -> Any:
    """The records of structured ``dtype`` that the columns in ``data`` make, chunk after
    chunk as ``layout`` lists them (each chunk's length, its columns' dtypes in the order of
    ``dtype``'s fields): each column converted as an assignment converts it, what
    :meth:`~lidarsim_core.io.points.PointSpool.records` does with the chunks themselves."""
    records = np.empty(sum(n for n, _ in layout), dtype=dtype)
    start = offset = 0
    for n, kinds in layout:
        for name, kind in zip(dtype.names, kinds):
            column = np.frombuffer(data, dtype=np.dtype(kind), count=n, offset=offset)
            records[name][start:start + n] = column
            offset += column.nbytes
        start += n
    return records


def _framed(message: Any) -> list[Any]:
    """``message`` as the child's :meth:`multiprocessing.connection.Connection.recv` reads
    it: pickled as ``Connection.send`` pickles, after its length as four big-endian bytes
    (the connection's framing of a message under 2 GiB), so that it goes down the pipe in
    the frame's one ``writev`` with the columns (a ``Connection.send`` of its own was a
    second system call, and a second wake-up of the child: ~30 µs a frame)."""
    data = ForkingPickler.dumps(message)
    if len(data) >= 2 ** 31 - 1:
        raise errors.OutputError("a frame's header is too large for the writer process")
    return [struct.pack("!i", len(data)), data]


def _write_all(fd: int, buffers: list[Any]) -> None:
    """Write ``buffers`` to ``fd`` in order, all of them (a pipe may take part of a large
    write)."""
    views = [memoryview(b).cast("B") for b in buffers]
    while views:
        written = os.writev(fd, views)
        while views and written >= views[0].nbytes:
            written -= views[0].nbytes
            views.pop(0)
        if views and written:
            views[0] = views[0][written:]


def _read_exact(fd: int, size: int) -> bytearray | None:
    """``size`` bytes from ``fd``, or ``None`` at the end of the pipe before them."""
    buffer = bytearray(size)
    view, got = memoryview(buffer), 0
    while got < size:
        count = os.readv(fd, [view[got:]])
        if count == 0:
            return None
        got += count
    return buffer


def _columns_size(layout: list[tuple[int, list[str]]]) -> int:
    """Bytes of the columns ``layout`` lists."""
    return sum(n * np.dtype(kind).itemsize for n, kinds in layout for kind in kinds)


_process: WriterProcess | None = None
_process_lock = threading.Lock()


def writer_process(*, start: bool = True) -> WriterProcess | None:
    """This process's writer child (started now if ``start`` and not yet started); ``None``
    where ``LIDARSIM_WRITER`` is ``threads``, or if it cannot start or has failed."""
    global _process
    if mode() != "process":
        return None
    with _process_lock:
        if _process is not None and (_process.pid != os.getpid() or _process.broken):
            _process = None  # a forked child's copy, or a failed one: start another
        if _process is None and start:
            try:
                _process = WriterProcess()
            except OSError:
                return None
            atexit.register(_process.close)
        return _process


# ---- the child --------------------------------------------------------------------------------
def serve(read_fd: int, write_fd: int) -> None:
    """The child's loop: write every frame received, reply, exit at the end of the pipe."""
    from multiprocessing.connection import Connection

    rx = Connection(read_fd, writable=False)
    tx = Connection(write_fd, readable=False)

    from ..base.atomic import deferred_sync
    from ..io.points import PointSpool
    from ..io.write import write_points_file
    from ..plugins.resolve import exporter_named
    from ..records.pointcloud import FrameInfo
    from .frames import make_parent

    parent = os.getppid()
    tx.send(("ready",))
    dtype = None  # the records' dtype, as last sent
    answers: list[tuple[Any, ...]] = []  # frames written and not yet answered
    while True:
        if answers and (len(answers) >= REPLY_FRAMES or answers[-1][3] is not None or
                        not select.select([read_fd], [], [], REPLY_WAIT_S)[0]):
            tx.send(("frames", answers))  # an error is answered at once
            answers = []
        try:
            header = rx.recv()
        except EOFError:  # the parent closed the pipe, or died
            header = ()
        if header is None:  # no more frames for now: answer those written
            if answers:
                tx.send(("frames", answers))
                answers = []
            continue
        data = _read_exact(read_fd, _columns_size(header[6])) if header else None
        if data is None:
            if answers:
                tx.send(("frames", answers))
            return
        token, path, exporter, options, frame, sent, layout = header
        dtype = dtype if sent is None else sent
        if os.getppid() != parent:  # killed (SIGKILL): its frames in the pipe stay unwritten,
            return  # as a thread's would, and a rerun does not meet this process writing
        paths: list[Path] = []
        try:
            records = joined_records(dtype, layout, data)
            spool = PointSpool.from_records(FrameInfo.from_dict(frame), records)
            target = Path(path)
            make_parent(target)
            with deferred_sync(paths):
                record = write_points_file(spool, target,
                                           exporter=exporter_named(exporter, options))
            result = {key: record[key] for key in ("file", "points", "bytes", "sha256")}
            answers.append((token, result, [os.fspath(p) for p in paths], None))
        except Exception as exc:  # noqa: BLE001 - every error goes back to the parent
            described = (type(exc).__name__, getattr(exc, "message", str(exc)),
                         getattr(exc, "source", None), getattr(exc, "field", None))
            answers.append((token, None, [], described))

