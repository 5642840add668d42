"""The progress bar of a dataset run: frames, frames per second and time left (rich)."""

from __future__ import annotations

import time
from typing import Any


class FrameProgress:
    """Counts frames and points; draws a rich progress bar on stderr unless ``quiet``.

    Parameters
    ----------
    total
        Frames this run has to produce.
    quiet
        Draw nothing (for scripts); the counts are still kept.
    already
        Frames found finished on disk (shown, not counted in the rate or time left).
    """

    def __init__(self, total: int, *, quiet: bool = False, already: int = 0) -> None:
        self.total = total
        self.already = already
        self.written = 0
        self.points = 0
        self.started = time.perf_counter()
        self._progress: Any = None
        self._task: Any = None
        if not quiet:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._progress = Progress(
                TextColumn("[bold]frames"), BarColumn(), MofNCompleteColumn(),
                TextColumn("{task.fields[rate]} frames/s"), TimeElapsedColumn(),
                TextColumn("ETA"), TimeRemainingColumn(),
                console=Console(stderr=True), transient=False)

    def __enter__(self) -> "FrameProgress":
        if self._progress is not None:
            self._progress.start()
            self._task = self._progress.add_task("frames", total=self.total, rate="-")
            if self.already:
                self._progress.console.print(f"{self.already} frames already done; "
                                             f"{self.total} to go")
        return self

    def __exit__(self, *exc: object) -> None:
        if self._progress is not None:
            self._progress.stop()

    @property
    def elapsed(self) -> float:
        """Seconds since the run started."""
        return time.perf_counter() - self.started

    def frame_done(self, points: int) -> None:
        """A frame was written with ``points`` points."""
        self.written += 1
        self.points += points
        self._draw()

    def points_per_second(self) -> float:
        """Points written per second of this run."""
        return self.points / self.elapsed if self.elapsed > 0 else 0.0

    def _draw(self) -> None:
        if self._progress is not None:
            rate = self.written / self.elapsed if self.elapsed > 0 else 0.0
            self._progress.update(self._task, completed=self.written, rate=f"{rate:.2f}")
