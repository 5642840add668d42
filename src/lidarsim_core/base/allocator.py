"""Freed memory kept in the process for the next frame (glibc's ``malloc``).

A frame allocates arrays of megabytes (the rays, per-ray poses, hits and columns of each
piece) and frees them when it ends. With glibc's default settings a freed block that large is
handed back to the operating system (``munmap``, or a trim of the heap's top) and the next
frame's arrays fault their pages in again, zeroed by the kernel: measured on the bench
suite's scenes of 100,000 pulses, ~900 minor page faults per frame on the tumbling rose scene
and ~1,800 on the 256 × 256 flash, 20–30 % of the frame's CPU time on one thread (a static
scene whose blocks happen to stay below the threshold makes none). Raising the mmap
threshold to glibc's largest (32 MiB) and the trim threshold to 256 MiB keeps those blocks
in the heap, so a frame reuses the pages of the last one; the values computed do not change.

The settings are the process's (every thread's arena), made once, by the first
:class:`~lidarsim_core.pipeline.simulation.Simulation`. The cost: up to 256 MiB of freed
memory stays with the process instead of going back to the system (blocks above 32 MiB are
still mapped and unmapped one by one).

Environment variables
---------------------
``LIDARSIM_MALLOC``
    ``keep`` (default): the settings above, where the C library is glibc; ``system``: leave
    the C library's own settings.
"""

from __future__ import annotations

import ctypes
import sys
import threading

from .limits import env_choice

#: ``mallopt`` parameters (glibc's ``malloc.h``).
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
#: Blocks up to this size come from the heap (glibc's largest mmap threshold on 64-bit).
MMAP_THRESHOLD = 32 << 20
#: Free memory kept at the heap's top before it is handed back.
TRIM_THRESHOLD = 256 << 20
#: ``LIDARSIM_MALLOC`` values.
MODES = ("keep", "system")

_lock = threading.Lock()
_applied: list[bool] = []  # the outcome, once tried


def malloc_mode() -> str:
    """``LIDARSIM_MALLOC`` (``keep`` when unset or empty).

    Raises
    ------
    ConfigError
        If it is neither ``keep`` nor ``system``.
    """
    return env_choice("LIDARSIM_MALLOC", MODES)


def keep_freed_memory() -> bool:
    """Make glibc keep freed blocks of up to :data:`MMAP_THRESHOLD` for reuse (see the module
    docstring), once per process; True when the settings are in force. Nothing is done with
    ``LIDARSIM_MALLOC=system``, or where the C library is not glibc."""
    if malloc_mode() == "system":
        return False
    with _lock:
        if not _applied:
            _applied.append(_set_thresholds())
        return _applied[0]


def _set_thresholds() -> bool:
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None)  # the C library the interpreter runs on
        libc.gnu_get_libc_version  # noqa: B018 -- glibc's own symbol: not musl's mallopt stub
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and \
        bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
