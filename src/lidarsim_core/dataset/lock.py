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
    """Hold the directory's lock for the duration of the block.

    Raises
    ------
    OutputError
        If another process holds it.
    """
    fd = os.open(root / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        if fcntl is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise OutputError("another 'lidarsim dataset' run is writing this directory",
                                  source=root) from None
        yield
    finally:
        os.close(fd)  # closing releases the lock


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
