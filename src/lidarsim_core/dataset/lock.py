"""One run per dataset directory at a time, and no stale temporary files after a crash.

The lock is an advisory ``flock`` on ``DIR/.lidarsim-dataset.lock``: the kernel drops it when
the process dies, however it dies, so a killed run never blocks the next one. Holding it makes
it safe to delete the hidden ``.*.part`` files that a killed run's atomic writes left behind.
"""

from __future__ import annotations

import os
import shutil
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator

from ..base.errors import OutputError
from .layout import LOCK

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: no advisory locks, runs are not guarded
    fcntl = None  # type: ignore[assignment]


@contextmanager
def dataset_lock(root: Path) -> Iterator[None]:
    """Hold the directory's lock for the duration of the block; the lock file is removed when
    the block ends (a finished run leaves no empty ``.lidarsim-dataset.lock`` behind).

    Raises
    ------
    OutputError
        If another process holds it.
    """
    path = root / LOCK
    for _ in range(_ATTEMPTS):
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        if fcntl is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                raise OutputError("another 'lidarsim dataset' run is writing this directory",
                                  source=root) from None
        if _is_current(fd, path):
            break
        os.close(fd)  # the run before removed the file we opened: lock the new one
    else:  # pragma: no cover - only under a storm of runs starting and ending at once
        raise OutputError("could not take the dataset lock: other runs keep replacing it",
                          source=root)
    try:
        yield
    finally:
        try:
            path.unlink()  # while still holding it: a run waiting on it then sees a new file
        except OSError:
            pass
        os.close(fd)  # closing releases the lock


#: How often :func:`dataset_lock` retries when the lock file was removed under it.
_ATTEMPTS = 20


def _is_current(fd: int, path: Path) -> bool:
    """Whether the open file ``fd`` is still the file at ``path`` (not removed, not replaced)."""
    try:
        now = os.stat(path)
    except FileNotFoundError:
        return False
    held = os.fstat(fd)
    return (held.st_dev, held.st_ino) == (now.st_dev, now.st_ino)


def remove_stale_parts(directories: Iterable[Path]) -> int:
    """Delete leftover ``.*.part`` files of interrupted atomic writes; returns how many."""
    removed = 0
    for directory in directories:
        if not directory.is_dir():
            continue
        for path in directory.glob(".*.part"):
            if path.is_dir() and not path.is_symlink():  # a bag's working directory
                shutil.rmtree(path, ignore_errors=True)
            else:
                path.unlink(missing_ok=True)
            removed += 1
    return removed
