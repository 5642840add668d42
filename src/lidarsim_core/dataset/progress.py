"""The progress of a dataset run: frames and points written, frames per second.

Drawing is the caller's: a *display* (the command line's rich bar,
:class:`lidarsim_core.cli.progress.FrameBar`) has ``start(total, already)``,
``update(written, frames_per_second)`` and ``stop()``.
"""

from __future__ import annotations

import time
from typing import Any


class FrameProgress:
    """Counts frames and points, and shows them on ``display`` (if any).

    Parameters
    ----------
    total
        Frames this run has to produce.
    display
        Draws the progress (None: nothing is drawn; the counts are still kept).
    already
        Frames found finished on disk (shown, not counted in the rate or time left).
    """

    def __init__(self, total: int, *, display: Any = None, already: int = 0) -> None:
        self.total = total
        self.already = already
        self.written = 0
        self.points = 0
        self.started = time.perf_counter()
        self._display = display

    def __enter__(self) -> "FrameProgress":
        if self._display is not None:
            self._display.start(self.total, self.already)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._display is not None:
            self._display.stop()

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
        if self._display is not None:
            rate = self.written / self.elapsed if self.elapsed > 0 else 0.0
            self._display.update(self.written, rate)
