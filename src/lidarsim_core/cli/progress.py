"""The command line's progress bars (rich, on stderr): the displays that dataset generation,
bags and evaluation report their progress to.

A bar is drawn only when stderr is a terminal: in a pipe, a log file or a CI job it would be
one more line around the error line (rich prints the final bar when the console is not
interactive), so there the displays stay silent."""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)


def _stderr_console() -> Console | None:
    """A console on stderr when it is a terminal, else ``None`` (no bar)."""
    console = Console(stderr=True)
    return console if console.is_terminal else None


class FrameBar:
    """Frames written, frames per second and time left
    (a :class:`~lidarsim_core.dataset.progress.FrameProgress` display); silent when stderr
    is not a terminal."""

    def __init__(self) -> None:
        self._console = _stderr_console()
        self._progress = Progress(
            TextColumn("[bold]frames"), BarColumn(), MofNCompleteColumn(),
            TextColumn("{task.fields[rate]} frames/s"), TimeElapsedColumn(),
            TextColumn("ETA"), TimeRemainingColumn(),
            console=self._console or Console(stderr=True), transient=False,
            disable=self._console is None)
        self._task: Any = None

    def start(self, total: int, already: int) -> None:
        """Show the bar for ``total`` frames still to write (``already`` were done)."""
        if self._console is None:
            return
        self._progress.start()
        self._task = self._progress.add_task("frames", total=total, rate="-")
        if already:
            self._progress.console.print(f"{already} frames already done; {total} to go")

    def update(self, written: int, rate: float) -> None:
        """``written`` frames so far at ``rate`` frames per second."""
        if self._task is None:
            return
        self._progress.update(self._task, completed=written, rate=f"{rate:.2f}")

    def stop(self) -> None:
        """Leave the finished bar on the terminal."""
        if self._task is not None:
            self._progress.stop()


class EvaluateBar:
    """Frames evaluated, failures and time left (the display of ``lidarsim evaluate``);
    silent when stderr is not a terminal."""

    def __init__(self) -> None:
        self._console = _stderr_console()
        self._progress = Progress(
            TextColumn("[bold]evaluate"), BarColumn(), MofNCompleteColumn(),
            TextColumn("{task.fields[failures]} failed"), TimeElapsedColumn(),
            TextColumn("ETA"), TimeRemainingColumn(),
            console=self._console or Console(stderr=True), disable=self._console is None)
        self._task: Any = None

    def start(self, total: int, done: int) -> None:
        """Show the bar for ``total`` frames, ``done`` of them already evaluated."""
        if self._console is None:
            return
        self._progress.start()
        self._task = self._progress.add_task("frames", total=total, completed=done,
                                             failures=0)

    def advance(self, failures: int) -> None:
        """One more frame evaluated; ``failures`` so far."""
        if self._task is None:
            return
        self._progress.update(self._task, advance=1, failures=failures)

    def stop(self) -> None:
        """Leave the finished bar on the terminal."""
        if self._task is not None:
            self._progress.stop()


class KernelBar:
    """The compiled kernels being compiled or loaded (a
    :data:`lidarsim_core.kernels.Display`): silent when stderr is not a terminal, and drawn
    only once a kernel has taken longer than :attr:`DELAY_S` (a process that loads them from
    numba's disk cache finishes in a fraction of a second and shows nothing; the first run on
    a machine, which compiles them, shows which kernel it is on and how many are left)."""

    #: Seconds of silence before the bar appears.
    DELAY_S = 0.5

    def __init__(self) -> None:
        import time

        self._clock = time.perf_counter
        self._console = _stderr_console()
        self._progress = Progress(
            TextColumn("[bold]compiling kernels[/] (once per install)"), BarColumn(),
            MofNCompleteColumn(), TextColumn("{task.fields[kernel]}"), TimeElapsedColumn(),
            console=self._console or Console(stderr=True), transient=True,
            disable=self._console is None)
        self._task: Any = None
        self._since: float | None = None

    def __call__(self, done: int, total: int, name: str) -> None:
        if self._console is None:
            return
        now = self._clock()
        if self._since is None:
            self._since = now
        if self._task is None and done < total and now - self._since > self.DELAY_S:
            self._progress.start()
            self._task = self._progress.add_task("kernels", total=total, kernel="")
        if self._task is not None:
            self._progress.update(self._task, completed=done, kernel=name)
            self._progress.refresh()  # numba holds the GIL while compiling: draw now
            if done >= total:
                self._progress.stop()


def warm_kernels() -> None:
    """Compile or load the compiled kernels up front with :class:`KernelBar`, when stderr is
    a terminal (elsewhere the kernels compile silently on first use, as the library does)."""
    from .. import kernels

    if _stderr_console() is not None and kernels.enabled():
        kernels.warm_up(display=KernelBar())


def prepare_long_run() -> None:
    """Before a command that runs for long (a dataset, a bag): the compiled kernels loaded
    up front (:func:`warm_kernels`'s bar on a terminal, silently elsewhere), then, when the
    app runs as the ``lidarsim`` process itself, every object made so far frozen out of the
    cyclic garbage collector's sight (:func:`gc.freeze`; they are still freed when their
    last reference goes). A full collection otherwise walks every object of the imports and
    the loaded kernels: 35–140 ms each time, two or three times in a 1,000-frame dataset
    (4–9 % of its run); with them frozen, one of 16–20 ms (docs/performance.md, "Datasets")."""
    import gc

    from .. import kernels
    from .app import STATE

    if _stderr_console() is not None:
        warm_kernels()
    elif kernels.enabled():
        kernels.warm_up()
    if STATE["own_process"]:  # a Python caller's process is its own to manage
        gc.freeze()


def status(line: str) -> None:
    """One progress line on stderr, ``lidarsim: <line>…``, when a step that takes a while
    starts; only when stderr is a terminal, like the progress bars (``cli.output``): a
    script reading stderr gets only the one ``error:`` line of a failure."""
    import sys

    try:
        if not sys.stderr.isatty():
            return
        sys.stderr.write(f"lidarsim: {line}…\n")
        sys.stderr.flush()
    except (BrokenPipeError, ValueError):  # nobody reads stderr any more
        pass
