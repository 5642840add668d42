"""Guards around a run: clean interrupts, plugins failing at run time, impossible geometry.

Three safety nets that keep a failing run from leaving wrong data or a traceback behind:

* :func:`sigterm_as_interrupt` turns ``SIGTERM`` into :class:`Terminated`, a
  :class:`KeyboardInterrupt`, so a terminated run cleans up exactly like one stopped with
  Ctrl-C (atomic writes remove their temporary file; the CLI prints one line and exits 143).
* :func:`guard_components` makes a third-party pattern, noise model, backend, trajectory or
  exporter that raises in the middle of a run fail with a :class:`~lidarsim_core.base.errors.PluginError`
  naming the component and the distribution that provides it.
* :func:`check_sensor_outside` refuses a frame whose sensor sits inside a closed target mesh
  (every point would lie on the inside of the hull: data that looks plausible and is wrong).
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager
from typing import Any, Iterator

#: Exit status of the CLI after SIGTERM (128 + signal number, the shell convention).
SIGTERM_EXIT_CODE = 128 + int(signal.SIGTERM)


class Terminated(KeyboardInterrupt):
    """The process received ``SIGTERM``; handled like Ctrl-C, reported as a termination."""


def _raise_terminated(signum: int, frame: Any) -> None:
    # later SIGTERMs must not interrupt the clean-up this one starts
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise Terminated()


@contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """While the block runs, ``SIGTERM`` raises :class:`Terminated` in the main thread.

    Outside the main thread (where Python cannot install signal handlers) this does nothing.
    The previous handler is restored on exit.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def interrupt_behind(exc: BaseException | None) -> KeyboardInterrupt | None:
    """The Ctrl-C or ``SIGTERM`` (:class:`Terminated`) behind ``exc``, if any.

    A signal handled while a compiled (numba) kernel is being called can surface as a
    ``SystemError`` ("returned a result with an exception set") whose cause is the
    interrupt; callers use this to report it as the interrupt it is.
    """
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None
