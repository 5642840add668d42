"""The command line's progress bars (rich, on stderr): the displays that dataset generation,
bags and evaluation report their progress to."""

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


class FrameBar:
    """Frames written, frames per second and time left
    (a :class:`~lidarsim_core.dataset.progress.FrameProgress` display)."""

    def __init__(self) -> None:
        self._progress = Progress(
            TextColumn("[bold]frames"), BarColumn(), MofNCompleteColumn(),
            TextColumn("{task.fields[rate]} frames/s"), TimeElapsedColumn(),
            TextColumn("ETA"), TimeRemainingColumn(),
            console=Console(stderr=True), transient=False)
        self._task: Any = None

    def start(self, total: int, already: int) -> None:
        """Show the bar for ``total`` frames still to write (``already`` were done)."""
        self._progress.start()
        self._task = self._progress.add_task("frames", total=total, rate="-")
        if already:
            self._progress.console.print(f"{already} frames already done; {total} to go")

    def update(self, written: int, rate: float) -> None:
        """``written`` frames so far at ``rate`` frames per second."""
        self._progress.update(self._task, completed=written, rate=f"{rate:.2f}")

    def stop(self) -> None:
        """Leave the finished bar on the terminal."""
        self._progress.stop()


class EvaluateBar:
    """Frames evaluated, failures and time left (the display of ``lidarsim evaluate``)."""

    def __init__(self) -> None:
        self._progress = Progress(
            TextColumn("[bold]evaluate"), BarColumn(), MofNCompleteColumn(),
            TextColumn("{task.fields[failures]} failed"), TimeElapsedColumn(),
            TextColumn("ETA"), TimeRemainingColumn(), console=Console(stderr=True))
        self._task: Any = None

    def start(self, total: int, done: int) -> None:
        """Show the bar for ``total`` frames, ``done`` of them already evaluated."""
        self._progress.start()
        self._task = self._progress.add_task("frames", total=total, completed=done,
                                             failures=0)

    def advance(self, failures: int) -> None:
        """One more frame evaluated; ``failures`` so far."""
        self._progress.update(self._task, advance=1, failures=failures)

    def stop(self) -> None:
        """Leave the finished bar on the terminal."""
        self._progress.stop()


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
