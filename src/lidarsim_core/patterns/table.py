"""Built-in plugin: a scan pattern read from a vendor file (Livox scan-mode CSV, generic CSV/NPY).

The table's rows are the rays of one period, in firing order, at their own times (relative to
the first row); the table repeats every ``period_s`` (default: its time span plus the median
spacing between rows). See :mod:`lidarsim_core.patterns.table_io` for the file formats.

Relative paths are resolved against the current working directory; ``pkg:MODULE/path`` names a
file shipped inside an installed Python package (useful for plugin distributions).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field

from ..base.components import ComponentOptions
from ..base.errors import PatternFileError
from ..hookspecs import hookimpl
from .base import RayBatch
from .geometry import directions_from_az_el
from .table_io import TableFormat, read_pattern_table, resolve_table_path
from .timing import CycleTimedPattern, FiringCycle


class TableOptions(ComponentOptions):
    """Options of the table pattern."""

    path: str = Field(min_length=1, description="Pattern file (.csv or .npy), or "
                                                "pkg:MODULE/relative/path.")
    format: TableFormat = Field("auto", description="'livox', 'generic' or 'auto'.")
    period_s: float | None = Field(None, gt=0, description="Repeat period of the table (s); "
                                                           "default: span + median spacing.")


class TablePattern(CycleTimedPattern):
    """A pattern read from a file: Livox scan-mode CSV or a generic CSV/NPY table, repeated."""

    name = "table"
    Options = TableOptions
    options: TableOptions

    #: Rays may lie this far (rad) outside the datasheet FOV (file values are rounded).
    FOV_TOLERANCE_RAD = 1e-6

    def __init__(self, options: Any = None, sensor: Any = None) -> None:
        self._path = resolve_table_path(options.path if options is not None else "")
        self.table = read_pattern_table(self._path, options.format if options else "auto")
        super().__init__(options, sensor)
        self._directions = directions_from_az_el(self.table.azimuth, self.table.elevation)
        outside = np.flatnonzero(~self.inside_fov(self._directions, self.FOV_TOLERANCE_RAD))
        if len(outside):
            k = outside[0]
            raise PatternFileError(
                f"row {k} (azimuth {np.degrees(self.table.azimuth[k]):.4g}°, elevation "
                f"{np.degrees(self.table.elevation[k]):.4g}°) is outside the datasheet's FOV "
                f"of sensor '{self.sensor.name}'", source=self._path)

    def build_cycle(self) -> FiringCycle:
        t = self.table.t
        span = float(t[-1])
        if self.options.period_s is not None:
            period = self.options.period_s
            if period <= span:
                raise PatternFileError(f"period_s {period:g} s must exceed the table's time "
                                       f"span {span:g} s", source=self._path)
        else:
            steps = np.diff(t)
            steps = steps[steps > 0]
            step = float(np.median(steps)) if len(steps) else 1.0 / self.sensor.point_rate_hz
            period = span + step
        return FiringCycle(period, t, self.table.channel)

    def rays_for_indices(self, index: np.ndarray) -> RayBatch:
        index = np.asarray(index, dtype=np.int64)
        slot = self.cycle.slot(index)
        return RayBatch(index, self.cycle.time(index), self._directions[slot],
                        self.cycle.channels[slot])


@hookimpl
def lidarsim_register_scan_patterns(register: Any) -> None:
    """Register the table pattern."""
    register(TablePattern)
