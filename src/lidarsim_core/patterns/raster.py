"""Built-in plugin: a scanning raster (two-axis mirror or gimbal) with line and frame timing.

The FOV rectangle (datasheet ``fov_h_deg × fov_v_deg`` about ``fov_v_center_deg``) is divided
into ``columns × rows`` equal-angle cells in azimuth and elevation and a pulse is aimed at each
cell centre. Counts come either directly (``rows``/``columns``) or from angular steps
(``row_step_deg``/``column_step_deg``: as many whole steps as fit, centred).

Lines run along ``line_axis`` (``horizontal``: along azimuth, left to right as seen from behind
the sensor, lines from top to bottom; ``vertical``: along elevation, top to bottom, lines from
left to right). With ``bidirectional`` (boustrophedon) every other line runs backwards. Pulses
along a line are ``1 / point_rate_hz`` apart; each line is followed by ``line_retrace_s`` and
each frame by ``frame_retrace_s`` (or the pause that makes frames start at ``frame_rate_hz``).
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from pydantic import Field, model_validator

from ..base.components import ComponentOptions
from ..base.errors import ConfigError
from ..hookspecs import hookimpl
from .geometry import directions_from_az_el
from .timing import CycleTimedPattern, FiringCycle


class RasterOptions(ComponentOptions):
    """Options of the raster pattern."""

    rows: int | None = Field(None, gt=0, le=100_000, description="Cells in elevation.")
    columns: int | None = Field(None, gt=0, le=100_000, description="Cells in azimuth.")
    row_step_deg: float | None = Field(None, gt=0, description="Elevation step (deg), instead "
                                                               "of rows.")
    column_step_deg: float | None = Field(None, gt=0, description="Azimuth step (deg), instead "
                                                                  "of columns.")
    line_axis: Literal["horizontal", "vertical"] = Field(
        "horizontal", description="Direction of the fast scan lines.")
    bidirectional: bool = Field(True, description="Boustrophedon: every other line reversed.")
    line_retrace_s: float = Field(0.0, ge=0, description="Pause after each line (s).")
    frame_retrace_s: float | None = Field(None, ge=0, description="Pause after each frame (s).")
    frame_rate_hz: float | None = Field(None, gt=0, description="Frame rate; sets the frame "
                                                                "pause (instead of "
                                                                "frame_retrace_s).")

    @model_validator(mode="after")
    def _one_of_each(self) -> "RasterOptions":
        if (self.rows is None) == (self.row_step_deg is None):
            raise ValueError("give exactly one of rows or row_step_deg")
        if (self.columns is None) == (self.column_step_deg is None):
            raise ValueError("give exactly one of columns or column_step_deg")
        if self.frame_retrace_s is not None and self.frame_rate_hz is not None:
            raise ValueError("give frame_retrace_s or frame_rate_hz, not both")
        return self


def _cell_centres(extent_rad: float, count: int | None, step_deg: float | None) -> np.ndarray:
    """Cell-centre angles (rad) across ``extent_rad``, centred on 0, from + to -."""
    if count is None:
        step = math.radians(step_deg)
        count = max(1, math.floor(extent_rad / step + 1e-9))
    else:
        step = extent_rad / count
    return ((count - 1) / 2.0 - np.arange(count)) * step


class RasterPattern(CycleTimedPattern):
    """Raster scan: rows × columns, uni- or bidirectional lines, line and frame timing."""

    name = "raster"
    Options = RasterOptions
    options: RasterOptions

    def __init__(self, options: Any = None, sensor: Any = None) -> None:
        super().__init__(options, sensor)
        az, el = self._grid()
        self.slot_directions = directions_from_az_el(az, el)

    def _axes(self) -> tuple[np.ndarray, np.ndarray]:
        opts, sheet = self.options, self.sensor
        az = _cell_centres(math.radians(sheet.fov_h_deg), opts.columns, opts.column_step_deg)
        el = _cell_centres(math.radians(sheet.fov_v_deg), opts.rows, opts.row_step_deg)
        return az, el + math.radians(sheet.fov_v_center_deg)

    def _grid(self) -> tuple[np.ndarray, np.ndarray]:
        """Azimuth and elevation (rad) of every slot, in firing order."""
        az, el = self._axes()
        fast, slow = (az, el) if self.options.line_axis == "horizontal" else (el, az)
        lines = np.tile(fast, (len(slow), 1))
        if self.options.bidirectional:
            lines[1::2] = lines[1::2, ::-1]
        slow_col = np.repeat(slow, len(fast))
        fast_col = lines.ravel()
        return (fast_col, slow_col) if self.options.line_axis == "horizontal" else \
            (slow_col, fast_col)

    def build_cycle(self) -> FiringCycle:
        opts = self.options
        az, el = self._axes()
        fast, slow = (len(az), len(el)) if opts.line_axis == "horizontal" else \
            (len(el), len(az))
        dt = 1.0 / self.sensor.point_rate_hz
        line_time = fast * dt + opts.line_retrace_s
        offsets = (np.repeat(np.arange(slow), fast) * line_time
                   + np.tile(np.arange(fast), slow) * dt)
        active = offsets[-1] + dt
        if opts.frame_rate_hz is not None:
            period = 1.0 / opts.frame_rate_hz
            if period < active * (1 - 1e-12):
                raise ConfigError(
                    f"raster: a frame of {slow} lines × {fast} pulses takes {active:.6g} s, "
                    f"longer than 1/frame_rate_hz = {period:.6g} s",
                    field="scan_pattern.options.frame_rate_hz")
            period = max(period, active)
        else:
            period = active + (opts.frame_retrace_s or 0.0)
        return FiringCycle(period, offsets, np.zeros(len(offsets), dtype=np.int16))

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, columns)`` of the raster."""
        az, el = self._axes()
        return len(el), len(az)


@hookimpl
def lidarsim_register_scan_patterns(register: Any) -> None:
    """Register the raster pattern."""
    register(RasterPattern)
