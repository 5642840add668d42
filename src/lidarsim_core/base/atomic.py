"""Atomic files: a file is written under a temporary name and renamed when complete, so a
failed or interrupted run leaves the previous file or none, never a partial one."""

from __future__ import annotations

import os
import secrets
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Iterator

from .errors import OutputError, UserInputError
from .oserrors import describe_os_error


@contextmanager
def atomic_output(path: str | Path, *, overwrite: bool = True) -> Iterator[IO[bytes]]:
    """Open a temporary file beside ``path``; rename it onto ``path`` only on success.

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
    tmp: Path | None = parent / f".{path.name}.{secrets.token_hex(6)}.part"
    try:
        try:
            # O_EXCL: a name that exists is never ours (and is then left alone); the mode is
            # reduced by the umask as for any new file
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0),
                         0o666)
        except PermissionError:
            tmp = None
            raise OutputError(f"output directory is not writable: {parent}",
                              source=path) from None
        except OSError as exc:
            tmp = None
            raise OutputError(f"cannot write here: {exc.strerror}", source=path) from None
        with os.fdopen(fd, "wb") as stream:
            yield stream
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except FileNotFoundError:
                pass
        if isinstance(exc, UserInputError) and exc.source is None:
            # an exporter's complaint (a column that does not fit the format) names the file
            raise type(exc)(exc.message, source=path, field=exc.field) from None
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            # ENOSPC, EDQUOT, EIO...: one line naming the file, nothing left behind
            raise OutputError(f"cannot write: {describe_os_error(exc)}", source=path) from exc
        raise


def write_text_atomic(path: str | Path, text: str, *, overwrite: bool = True) -> Path:
    """Write UTF-8 ``text`` to ``path`` through :func:`atomic_output`; returns the path."""
    with atomic_output(path, overwrite=overwrite) as stream:
        stream.write(text.encode("utf-8"))
    return Path(path)


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
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0),
                     0o666)
    except OSError as exc:
        raise OutputError(f"cannot write here: {describe_os_error(exc)}", source=path) from None
    temps.append((Path(path), tmp))
    with os.fdopen(fd, "wb") as stream:
        yield stream
