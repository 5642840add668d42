"""Addresses of the C library's file functions, for compiled loops that write files without
the interpreter lock (:mod:`lidarsim_core.kernels.oswrite`).

Each system call Python makes (``os.open``, ``os.write``, ``os.replace``...) releases the
interpreter lock and takes it back; on a thread that writes while the simulation runs on
others, every take-back waits for the lock and hands the others a pause. A dataset frame is
two files: ten such calls a frame, which cost the serial run more than the calls themselves
(docs/performance.md, "Datasets"). Through these addresses a numba loop makes the calls in
one stretch with the lock released.

Only on Linux on x86-64 and AArch64, whose calling conventions pass ``open``'s variadic
``mode`` in a register like a named argument; elsewhere :func:`file_functions` is ``None``
and files are written the usual way.
"""

from __future__ import annotations

import functools
import platform
import sys
from typing import Any

#: The functions, in the order of :func:`file_functions`' array (the kernel's indices).
NAMES = ("open", "write", "close", "rename", "unlink", "fsync", "faccessat",
         "__errno_location")
#: Machines whose C calling convention passes a variadic ``int`` as a named one.
MACHINES = ("x86_64", "amd64", "aarch64", "arm64")
#: ``AT_FDCWD`` and ``AT_SYMLINK_NOFOLLOW`` of Linux (not in :mod:`os`).
AT_FDCWD = -100
AT_SYMLINK_NOFOLLOW = 0x100


@functools.lru_cache(maxsize=1)
def file_functions() -> Any:
    """The addresses of :data:`NAMES` in the C library as a read-only ``int64`` array, or
    ``None`` where they are not used (another system or machine, or a C library without one
    of them)."""
    if not sys.platform.startswith("linux") or platform.machine().lower() not in MACHINES:
        return None
    import ctypes

    import numpy as np

    try:
        library = ctypes.CDLL(None)
        addresses = [ctypes.cast(getattr(library, name), ctypes.c_void_p).value
                     for name in NAMES]
    except (OSError, AttributeError):
        return None
    if not all(addresses):
        return None
    table = np.array(addresses, dtype=np.int64)
    table.flags.writeable = False
    return table
