"""Atomic files: a file is written under a temporary name and renamed when complete, so a
failed or interrupted run leaves the previous file or none, never a partial one."""

from __future__ import annotations

import os
import random
import secrets
import stat
import sys
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Iterator, Sequence

from .errors import OutputError, UserInputError
from .oserrors import describe_os_error


@contextmanager
def atomic_output(path: str | Path, *, overwrite: bool = True) -> Iterator[IO[bytes]]:
    """Open a temporary file beside ``path``; rename it onto ``path`` only on success.

    The file's data reach the disk (``fsync``) before the rename, unless the calling thread
    is inside :func:`deferred_sync`, which collects the path for a later :func:`sync_files`.
    The temporary file is hidden (``.NAME.RANDOM.part``) and never the target. It is removed
    whatever stops the body: an exception, Ctrl-C, or SIGTERM under the CLI (its name is
    chosen before the file is created, so even an interrupt arriving while it is being
    created cannot strand it). Only SIGKILL or a crash can leave one behind; ``lidarsim
    dataset`` removes such leftovers when it resumes.
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise OutputError("output path is a directory", source=path)
    if not parent.is_dir():
        raise OutputError(f"output directory does not exist: {parent}", source=path)
    if os.path.lexists(path) and not overwrite:  # a symbolic link, even a looping one, too
        raise OutputError("output file exists (use --overwrite to replace it)", source=path)
    from .outputs import check_replaceable

    check_replaceable(path)  # a device, FIFO or socket is never replaced by a regular file
    made: list[str] = []  # the temporary file's name, known before the file is created
    try:
        fd = _open_part(path, os.fspath(parent), made)
        deferred = deferred_paths()
        with os.fdopen(fd, "wb") as stream:
            yield stream
            stream.flush()
            if deferred is None:
                os.fsync(stream.fileno())
        os.replace(made[-1], path)
        if deferred is not None:
            deferred.append(path)
    except BaseException as exc:
        _discard(made)
        if isinstance(exc, UserInputError) and exc.source is None:
            # an exporter's complaint (a column that does not fit the format) names the file
            raise type(exc)(exc.message, source=path, field=exc.field) from None
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            # ENOSPC, EDQUOT, EIO...: one line naming the file, nothing left behind
            raise OutputError(f"cannot write: {describe_os_error(exc)}", source=path) from exc
        raise


def _check_existing(path: Path, overwrite: bool) -> bool:
    """The checks of :func:`atomic_output` on what is at ``path`` already, with one
    ``lstat`` (a second ``stat`` only for a symbolic link); whether something is there."""
    try:
        mode = os.lstat(path).st_mode
    except OSError:  # missing, or unreadable: left to the open that follows
        return False
    if stat.S_ISDIR(mode) or (stat.S_ISLNK(mode) and os.path.isdir(path)):
        raise OutputError("output path is a directory", source=path)
    if not overwrite:
        raise OutputError("output file exists (use --overwrite to replace it)", source=path)
    if not (stat.S_ISREG(mode) or stat.S_ISLNK(mode)):
        from .outputs import check_replaceable

        check_replaceable(path)  # names what the node is
    return True


def write_bytes_atomic(path: str | Path, data: bytes | bytearray | memoryview, *,
                       overwrite: bool = True) -> Path:
    """Write ``data`` to ``path`` as :func:`atomic_output` does (a hidden temporary file
    renamed onto ``path`` when complete, synced first unless inside :func:`deferred_sync`,
    removed whatever stops the write; the same checks and the same one-line errors), with the
    fewest system calls: one ``lstat`` of the target, then ``open``, ``write``, ``close`` and
    ``rename`` (no buffered file object, no per-check ``stat``).

    A dataset writes two such files per frame, on a thread that shares the interpreter with
    the simulation: every system call is a point where the threads hand the interpreter
    over, so fewer calls cost less than their own time.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    target = os.fspath(path)
    _check_existing(path, overwrite)
    parent = os.path.dirname(target)
    made: list[str] = []  # the temporary file's name, known before the file is created
    try:
        fd = _open_part(path, parent, made)
        deferred = deferred_paths()
        try:
            view = memoryview(data).cast("B")
            while view:
                view = view[os.write(fd, view):]
            if deferred is None:
                os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(made[-1], target)
        if deferred is not None:
            deferred.append(path)
    except BaseException as exc:
        _discard(made)
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise OutputError(f"cannot write: {describe_os_error(exc)}", source=path) from exc
        raise
    return path


def _open_part(path: Path, parent: str, made: list[str]) -> int:
    """A new hidden temporary file beside ``path`` in ``parent`` (``""``: the current
    directory), opened for writing: its descriptor. Its name is put in ``made`` before the
    file is created, so that an interrupt (Ctrl-C, SIGTERM under the CLI) arriving while it
    is created cannot strand it: the caller discards what ``made`` names. O_EXCL: a name
    that exists (a leftover) is never ours and is taken out of ``made`` and left alone,
    another is drawn; the mode is reduced by the umask as for any new file. Failures are the
    one-line :class:`OutputError` naming ``path``."""
    flags = PART_FLAGS
    attempts = 8
    try:
        while True:
            made.append(part_name(path, parent))
            try:
                return os.open(made[-1], flags, PART_MODE)
            except OSError as exc:
                made.pop()  # not created (an interrupt keeps the name: it may have been)
                if not isinstance(exc, FileExistsError):
                    raise
                attempts -= 1
                if not attempts:
                    raise
    except PermissionError:
        raise OutputError(f"output directory is not writable: {parent or '.'}",
                          source=path) from None
    except (FileNotFoundError, NotADirectoryError):
        raise OutputError(f"output directory does not exist: {parent or '.'}",
                          source=path) from None
    except OSError as exc:
        raise OutputError(f"cannot write here: {exc.strerror}", source=path) from None


#: How a temporary file is opened (it must be new: ``O_EXCL``), and its mode before the umask.
PART_FLAGS = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0)
PART_MODE = 0o666


def part_name(path: Path, parent: str) -> str:
    """A new name for a hidden temporary file beside ``path`` in ``parent`` (``""``: the
    current directory), as :func:`write_bytes_atomic` draws them: ``.NAME.RANDOM.part``."""
    return os.path.join(parent, f".{path.name}.{_token()}.part")


def deferred_paths() -> list[Path] | None:
    """The list this thread's :func:`deferred_sync` collects finished files in, or ``None``
    outside one (each file is then synced before its rename)."""
    return getattr(_local, "deferred", None)


def _discard(made: list[str]) -> None:
    """Remove the temporary file a failed write leaves (if it was created: ``made`` names it
    from just before its creation)."""
    for tmp in made:
        try:
            os.unlink(tmp)
        except OSError:  # not there (never created, or renamed): what stopped the write stands
            pass


_tokens = threading.local()


def _token() -> str:
    """12 random hex digits for a temporary name, without a system call each (as
    ``secrets.token_hex(6)`` makes): a generator seeded from the system once per thread and
    process."""
    pid = os.getpid()
    if getattr(_tokens, "pid", None) != pid:  # a forked child must not repeat its parent
        _tokens.pid, _tokens.random = pid, random.Random(secrets.token_bytes(16))
    return f"{_tokens.random.getrandbits(48):012x}"


def write_text_atomic(path: str | Path, text: str, *, overwrite: bool = True) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically (:func:`write_bytes_atomic`); returns the
    path."""
    return write_bytes_atomic(path, text.encode("utf-8"), overwrite=overwrite)


@contextmanager
def atomic_group(paths: list[Path], *, overwrite: bool = True) -> Iterator[list[IO[bytes]]]:
    """Temporary files beside every one of ``paths``, renamed onto them only when *all* are
    complete and flushed to disk: a failure (a full disk while the last is synced) leaves
    none of them, never the OBJ without its MTL.

    The renames themselves come last, one after the other; only a crash between two of them
    can leave part of the group.
    """
    from contextlib import ExitStack

    with ExitStack() as stack:
        temps: list[tuple[Path, Path]] = []
        streams: list[IO[bytes]] = []
        for path in paths:
            parent = Path(path).parent if str(Path(path).parent) else Path(".")
            tmp = parent / f".{Path(path).name}.{secrets.token_hex(6)}.part"
            streams.append(stack.enter_context(
                _group_member(path, tmp, overwrite, temps)))
        try:
            yield streams
            for stream in streams:
                stream.flush()
                os.fsync(stream.fileno())
        except BaseException as exc:
            for stream in streams:
                stream.close()
            for _, tmp in temps:
                try:
                    os.unlink(tmp)
                except FileNotFoundError:
                    pass
            if isinstance(exc, OSError) and not isinstance(exc, OutputError):
                raise OutputError(f"cannot write: {describe_os_error(exc)}",
                                  source=paths[-1]) from exc
            raise
        for stream in streams:
            stream.close()
        for path, tmp in temps:
            os.replace(tmp, path)


@contextmanager
def _group_member(path: Path, tmp: Path, overwrite: bool, temps: list[tuple[Path, Path]]
                  ) -> Iterator[IO[bytes]]:
    from .outputs import check_replaceable

    if Path(path).is_dir():
        raise OutputError("output path is a directory", source=path)
    if os.path.lexists(path) and not overwrite:
        raise OutputError("output file exists (use --overwrite to replace it)", source=path)
    check_replaceable(path)
    try:
        fd = os.open(tmp, PART_FLAGS, PART_MODE)
    except OSError as exc:
        raise OutputError(f"cannot write here: {describe_os_error(exc)}", source=path) from None
    temps.append((Path(path), tmp))
    with os.fdopen(fd, "wb") as stream:
        yield stream


_local = threading.local()


@contextmanager
def deferred_sync(paths: list[Path]) -> Iterator[list[Path]]:
    """Files that :func:`atomic_output` finishes on this thread inside the block are renamed
    into place without their ``fsync``; their paths are appended to ``paths``, to be made
    durable together by :func:`sync_files`.

    They are whole for every other process the moment they appear (the rename is atomic);
    only an operating-system crash or power loss before the :func:`sync_files` can lose or
    empty them, which a reader that checks sizes and checksums (a resumed ``lidarsim
    dataset``) notices.
    """
    before = getattr(_local, "deferred", None)
    _local.deferred = paths
    try:
        yield paths
    finally:
        _local.deferred = before


def sync_files(paths: Sequence[str | os.PathLike[str]]) -> None:
    """Make ``paths`` and their directory entries durable: on Linux one ``syncfs`` per file
    system they are on; elsewhere (or if ``syncfs`` fails, which is how a write error of
    the file system shows) an ``fsync`` of each file, whose error names the file
    (:class:`OutputError`), and of each directory."""
    if not paths:
        return
    directories = sorted({os.path.dirname(os.fspath(p)) or "." for p in paths})
    if sys.platform.startswith("linux") and _syncfs(directories):
        return
    for path in paths:
        try:
            fd = os.open(path, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        except OSError as exc:  # ENOSPC, EIO... surfacing at the sync: name the file
            raise OutputError(f"cannot write: {describe_os_error(exc)}", source=path) from exc
    for directory in directories:
        try:
            fd = os.open(directory, os.O_RDONLY)
        except OSError:  # a platform without directory handles (Windows)
            continue
        try:
            os.fsync(fd)
        except OSError:
            pass
        finally:
            os.close(fd)


def _syncfs(directories: list[str]) -> bool:
    """``syncfs`` once per file system holding ``directories``; False if it is unavailable
    or fails (the caller then syncs file by file)."""
    import ctypes

    try:
        call = ctypes.CDLL(None, use_errno=True).syncfs  # releases the GIL while it runs
    except (OSError, AttributeError):
        return False
    done: set[int] = set()
    for directory in directories:
        fd = os.open(directory, os.O_RDONLY)
        try:
            device = os.fstat(fd).st_dev
            if device in done:
                continue
            if call(fd) != 0:
                return False
            done.add(device)
        finally:
            os.close(fd)
    return True
