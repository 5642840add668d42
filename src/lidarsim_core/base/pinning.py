"""Each thread of a worker pool kept on a CPU of its own (Linux).

A frame's pieces are handed to the pool's threads at once, but a scheduler that packs
runnable threads onto few CPUs may queue both behind each other on one CPU while the other
sleeps: measured on the two-vCPU development VM (a Firecracker guest whose kernel packs
threads onto vCPUs), two nogil loops of 1.5 ms submitted together after 0.5 s idle ran one
after the other (the second started 1.5 ms after the first, 1.0 core), and the tumbling
rose scene's frames used mostly 1.00-1.17 cores after idle. With each pool thread bound to its
own CPU the second loop started 0.3 ms after the first (the time to wake a halted vCPU), and
34 of 36 frames after idle used 1.43-1.51 cores; frames that follow each other were not
slowed (2.9-3.5 ms bound, 2.9-3.8 unbound).

Threads are bound only when the pool has no more threads than the CPUs the process may use
(``os.sched_getaffinity``): thread *i* to the *i*-th of them. A pool of more threads, or a
platform without ``sched_setaffinity``, is left to the scheduler.

Environment variables
---------------------
``LIDARSIM_PIN_THREADS``
    ``auto`` (default): bind as above; ``off``: leave every thread to the scheduler.
"""

from __future__ import annotations

import itertools
import os
import threading
from typing import Callable

from .limits import env_choice

#: ``LIDARSIM_PIN_THREADS`` values.
MODES = ("auto", "off")


def pin_mode() -> str:
    """``LIDARSIM_PIN_THREADS`` (``auto`` when unset or empty).

    Raises
    ------
    ConfigError
        If it is neither ``auto`` nor ``off``.
    """
    return env_choice("LIDARSIM_PIN_THREADS", MODES)


def pool_cpus(threads: int) -> list[int] | None:
    """The CPUs the threads of a pool of ``threads`` are bound to, in thread order (None: not
    bound; see the module docstring)."""
    if threads < 2 or pin_mode() == "off" or not hasattr(os, "sched_setaffinity"):
        return None
    try:
        allowed = sorted(os.sched_getaffinity(0))
    except OSError:
        return None
    return allowed[:threads] if threads <= len(allowed) else None


def pinning_initializer(cpus: list[int]) -> Callable[[], None]:
    """A pool initializer binding the pool's *i*-th started thread to ``cpus[i]`` (a refusal
    of the system, e.g. a CPU taken away meanwhile, leaves the thread unbound)."""
    order = itertools.count()
    lock = threading.Lock()

    def pin() -> None:
        with lock:
            cpu = cpus[next(order) % len(cpus)]
        try:
            os.sched_setaffinity(0, {cpu})  # 0: the calling thread
        except OSError:
            pass

    return pin
