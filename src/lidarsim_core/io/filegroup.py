"""A few files written atomically one after another, in one compiled call where it can be.

:func:`write_files_atomic` writes each file as
:func:`~lidarsim_core.base.atomic.write_bytes_atomic` does (a hidden ``O_EXCL`` temporary file,
synced unless inside :func:`~lidarsim_core.base.atomic.deferred_sync`, renamed onto its
target). With the compiled kernels on (``LIDARSIM_KERNELS``) on Linux x86-64 or AArch64, the
files whose targets do not exist yet are written by :func:`lidarsim_core.kernels.oswrite.write_files`
with the interpreter lock released for all their system calls at once; a target that is
there, and any call that fails, go to ``write_bytes_atomic`` from that file on, so the checks,
the errors and the files are those of the usual path. A frame of a serial ``lidarsim
dataset`` (its file and sidecar) is written this way by the dataset's writer (a process of
its own, or a thread beside the simulation, where the usual path's ten lock hand-overs a
frame cost 0.30–0.44 ms against 0.16–0.27 ms: docs/performance.md, "In a writer process of
its own").
"""

from __future__ import annotations

import errno
import os
from pathlib import Path
from typing import Sequence

import numpy as np

from .. import kernels
from ..base.atomic import PART_FLAGS, PART_MODE, deferred_paths, part_name, write_bytes_atomic
from ..base.libc import AT_FDCWD, AT_SYMLINK_NOFOLLOW, file_functions

Data = bytes | bytearray | memoryview
#: Most bytes written by one compiled call: a signal (Ctrl-C) that arrives during the call is
#: handled when it returns, a few milliseconds later at most; larger files take the usual
#: path, where it stops the write at once.
COMPILED_BYTES = 2 ** 20


def write_files_atomic(items: Sequence[tuple[str | Path, Data]], *,
                       overwrite: bool | Sequence[bool] = True) -> list[Path]:
    """Write each ``(path, data)`` of ``items`` atomically, in order (see the module
    docstring); the same files, checks and errors as ``write_bytes_atomic`` on each.

    Parameters
    ----------
    items
        The files' paths and bytes.
    overwrite
        Whether an existing file may be replaced: for every file, or one flag per file.

    Returns
    -------
    list of Path
        The paths written.
    """
    paths = [Path(path) for path, _ in items]
    replace = [overwrite] * len(items) if isinstance(overwrite, bool) else list(overwrite)
    if len(replace) != len(items):
        raise ValueError("one overwrite flag per file")
    done = _write_compiled(paths, [data for _, data in items]) if items else 0
    deferred = deferred_paths()
    if deferred is not None:
        deferred.extend(paths[:done])
    for path, (_, data), flag in list(zip(paths, items, replace))[done:]:
        write_bytes_atomic(path, data, overwrite=flag)
    return paths


def _write_compiled(paths: list[Path], contents: list[Data]) -> int:
    """How many of the files the compiled loop wrote (0 where it is not used)."""
    functions = file_functions()
    if functions is None or sum(memoryview(d).nbytes for d in contents) > COMPILED_BYTES \
            or not kernels.enabled():
        return 0
    from ..kernels.oswrite import write_files  # numba: loaded with the first such write

    names = bytearray()
    plan = [deferred_paths() is None, *_OPTIONS, len(paths)]
    for path, data in zip(paths, contents):
        target = os.fsencode(path)
        if b"\0" in target:
            return 0  # left to the os calls, which refuse it
        temporary = os.fsencode(part_name(path, os.path.dirname(os.fspath(path))))
        view = np.frombuffer(data, dtype=np.uint8)  # bytes-like of one-byte items
        plan += [len(names), len(names) + len(temporary) + 1,
                 view.__array_interface__["data"][0], view.size]
        names += temporary + b"\0" + target + b"\0"
    written, _ = write_files(functions, np.frombuffer(names, dtype=np.uint8),
                             np.array(plan, dtype=np.int64))
    return int(written)


#: The kernel's options after ``sync`` (lidarsim_core.kernels.oswrite.PLAN_OPTIONS).
_OPTIONS = (PART_FLAGS, PART_MODE, AT_FDCWD, os.F_OK, AT_SYMLINK_NOFOLLOW, errno.ENOENT,
            errno.EINTR)

