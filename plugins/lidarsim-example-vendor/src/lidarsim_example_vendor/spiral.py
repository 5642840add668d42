"""An Archimedean spiral scan: from the boresight out to the FOV edge, once per frame.

In frame ``f`` (``frame_rate_hz`` frames per second) at fraction ``u ∈ [0, 1)`` of the frame,
the beam is at off-axis angle ``A·u`` and roll ``2π·turns·u + f·frame_roll_deg``: ``turns``
evenly spaced rings from the centre to the edge, each frame rotated a little more.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from lidarsim_core.base.components import ComponentOptions
from lidarsim_core.patterns.base import RayBatch, ScanPattern
from lidarsim_core.patterns.geometry import directions_from_off_axis


class SpiralOptions(ComponentOptions):
    """Options of the spiral pattern."""

    turns: int = Field(50, ge=1, le=100_000, description="Spiral turns per frame.")
    frame_rate_hz: float = Field(10.0, gt=0, description="Frames (spirals) per second.")
    frame_roll_deg: float = Field(3.7, description="Extra roll of each frame (deg).")
    amplitude_deg: float | None = Field(None, gt=0, lt=90, description="Off-axis angle at the "
                                                                      "end of a frame (deg); "
                                                                      "default: half the FOV.")


class SpiralPattern(ScanPattern):
    """Archimedean spiral from the boresight to the FOV edge, one per frame (example plugin)."""

    name = "example-spiral"
    Options = SpiralOptions
    options: SpiralOptions

    @property
    def amplitude_rad(self) -> float:
        """Off-axis angle reached at the end of a frame (rad)."""
        a = self.options.amplitude_deg
        return math.radians(a) if a is not None else self.sensor.half_fov_h_rad

    def rays_for_indices(self, index: np.ndarray) -> RayBatch:
        index = np.asarray(index, dtype=np.int64)
        t = self.time_of_index(index)
        frames = t * self.options.frame_rate_hz
        frame = np.floor(frames)
        u = frames - frame
        roll = 2 * np.pi * self.options.turns * u + np.radians(self.options.frame_roll_deg) * frame
        direction = directions_from_off_axis(self.amplitude_rad * u, roll)
        return RayBatch(index, t, direction, np.zeros(len(index), dtype=np.int16))

    def max_off_axis_rad(self) -> float:
        return self.amplitude_rad
