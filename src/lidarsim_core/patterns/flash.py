"""Built-in plugin: a flash LiDAR, an ``rows × columns`` detector array lit by one pulse per frame.

Every pixel of a frame shares the frame's time (frames start every ``1 / frame_rate_hz``), so
a flash frame has no motion distortion within it. A simulated frame holds one flash (the
sensor's native frame) whatever ``scan.duration_s`` spans, unless ``flashes_per_frame`` says
otherwise; a sequence of flashes is a sequence of frames (``scan.frame_rate_hz``). Ray ``k`` is pixel ``k mod (rows·columns)``
of frame ``k div (rows·columns)``, pixels in row-major order from the top-left pixel (highest
elevation, +Y side) as seen from behind the sensor. There is one emitter: every ray has
channel 0.

Pixel directions follow either a pinhole (focal-plane) model, where pixel centres are equally
spaced in the tangent plane and the array spans the datasheet's horizontal and vertical FOV
edge to edge, or an equal-angle grid in azimuth and elevation.
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from pydantic import Field

from ..base.components import ComponentOptions
from ..hookspecs import hookimpl
from .geometry import directions_from_az_el
from .timing import CycleTimedPattern, FiringCycle


class FlashOptions(ComponentOptions):
    """Options of the flash-array pattern."""

    rows: int = Field(gt=0, le=4096, description="Detector rows (vertical).")
    columns: int = Field(gt=0, le=4096, description="Detector columns (horizontal).")
    frame_rate_hz: float | None = Field(
        None, gt=0, description="Frames per second; default: point_rate_hz / (rows·columns).")
    flashes_per_frame: int = Field(
        1, ge=1, description="Flashes in one simulated frame: the first ones that start within "
                             "the frame's duration_s (1: one flash, the sensor's native frame; "
                             "a sequence of flashes is scan.frames or scan.frame_rate_hz).")
    projection: Literal["pinhole", "equiangular"] = Field(
        "pinhole", description="'pinhole': equal steps in the focal plane; 'equiangular': "
                               "equal steps in azimuth and elevation.")


class FlashPattern(CycleTimedPattern):
    """An n × m detector array fired at the frame rate (all pixels of a frame share its time)."""

    name = "flash"
    Options = FlashOptions
    options: FlashOptions

    def __init__(self, options: Any = None, sensor: Any = None) -> None:
        super().__init__(options, sensor)
        self.slot_directions = self.pixel_directions()

    @property
    def frame_rate_hz(self) -> float:
        """Frames per second."""
        opts = self.options
        return opts.frame_rate_hz or self.sensor.point_rate_hz / (opts.rows * opts.columns)

    def frame_index_range(self, t_start: float, t_stop: float) -> tuple[int, int]:
        """The rays of the first ``flashes_per_frame`` flashes that start in the frame."""
        k0, k1 = self.index_range(t_start, t_stop)
        pixels = self.options.rows * self.options.columns
        return k0, min(k1, k0 + self.options.flashes_per_frame * pixels)

    def build_cycle(self) -> FiringCycle:
        n = self.options.rows * self.options.columns
        return FiringCycle(1.0 / self.frame_rate_hz, np.zeros(n), np.zeros(n, dtype=np.int16))

    def pixel_directions(self) -> np.ndarray:
        """(rows·columns, 3) unit direction of every pixel centre, row-major from the top left."""
        opts, sheet = self.options, self.sensor
        # pixel-centre fractions of the half-extent, from +1 (left / top) to -1
        u = 1.0 - (2.0 * np.arange(opts.columns) + 1.0) / opts.columns
        v = 1.0 - (2.0 * np.arange(opts.rows) + 1.0) / opts.rows
        vv, uu = np.meshgrid(v, u, indexing="ij")
        if opts.projection == "equiangular":
            return directions_from_az_el(uu.ravel() * sheet.half_fov_h_rad,
                                         vv.ravel() * sheet.half_fov_v_rad
                                         + math.radians(sheet.fov_v_center_deg))
        y = uu.ravel() * math.tan(sheet.half_fov_h_rad)
        z = vv.ravel() * math.tan(sheet.half_fov_v_rad)
        d = np.stack([np.ones_like(y), y, z], axis=1)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        pitch = math.radians(sheet.fov_v_center_deg)
        if pitch:
            # tilt the optical axis up by the FOV centre's elevation (rotation about -Y)
            c, s = math.cos(pitch), math.sin(pitch)
            d = np.stack([c * d[:, 0] - s * d[:, 2], d[:, 1], s * d[:, 0] + c * d[:, 2]], axis=1)
        return d


@hookimpl
def lidarsim_register_scan_patterns(register: Any) -> None:
    """Register the flash pattern."""
    register(FlashPattern)
