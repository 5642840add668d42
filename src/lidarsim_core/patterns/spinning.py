"""Built-in plugin: a multi-channel spinning head (Velodyne, Ouster and similar).

The head turns about the sensor's +Z axis at ``rotation_hz``. Channel ``c`` points at a fixed
elevation ``elevations_deg[c]`` and at the head's azimuth plus ``azimuth_offsets_deg[c]``.
Within one *firing cycle* the channels fire in ``firing_order``, ``lasers_per_firing`` at a
time, successive firings ``firing_interval_s`` apart; the cycle repeats every
``cycle_period_s`` (which may include a recharge pause). Every ray's direction is computed at
its own firing time, so the small azimuth advance between the lasers of one cycle is exact.

Azimuth is measured from +X toward +Y (counter-clockwise seen from above); Velodyne heads turn
clockwise seen from above, which is the default.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from pydantic import Field, model_validator

from .. import kernels
from ..base.components import ComponentOptions
from ..hookspecs import hookimpl
from .base import DirectionGroups, RayBatch, cycle_groups
from .geometry import directions_from_az_el
from .timing import CycleTimedPattern, FiringCycle


#: Firing cycles per group of :meth:`SpinningPattern.direction_groups` (a VLP-16 group spans
#: about 0.8 ms, 3° of the head's turn at 10 Hz).
GROUP_CYCLES = 16


class SpinningOptions(ComponentOptions):
    """Options of the spinning multi-channel pattern."""

    elevations_deg: list[float] = Field(min_length=1, max_length=1024,
                                        description="Elevation of each channel (deg); the "
                                                    "channel id is the list position.")
    azimuth_offsets_deg: list[float] | None = Field(
        None, description="Azimuth offset of each channel from the head's azimuth (deg).")
    firing_order: list[int] | None = Field(
        None, description="Channel ids in the order they fire within a cycle (each once); "
                          "default: 0, 1, 2, ...")
    lasers_per_firing: int | None = Field(
        None, ge=1, description="Channels fired together at each firing (default 1; all "
                                "channels at once when firing_interval_s is 0).")
    firing_interval_s: float = Field(0.0, ge=0, description="Time between successive "
                                                            "firings within a cycle (s).")
    cycle_period_s: float | None = Field(
        None, gt=0, description="Time between cycle starts (s); default: channels / "
                                "point_rate_hz.")
    rotation_hz: float = Field(10.0, gt=0, le=100, description="Head rotation rate (Hz).")
    clockwise: bool = Field(True, description="Head turns clockwise seen from above (+Z).")
    azimuth_start_deg: float = Field(0.0, description="Head azimuth at t = 0 (deg).")

    @model_validator(mode="after")
    def _consistent(self) -> "SpinningOptions":
        n = len(self.elevations_deg)
        if any(not -90 <= e <= 90 for e in self.elevations_deg):
            raise ValueError("elevations_deg must lie in [-90, 90]")
        if self.azimuth_offsets_deg is not None and len(self.azimuth_offsets_deg) != n:
            raise ValueError(f"azimuth_offsets_deg has {len(self.azimuth_offsets_deg)} values "
                             f"for {n} channels")
        if self.firing_order is not None and sorted(self.firing_order) != list(range(n)):
            raise ValueError(f"firing_order must list every channel id 0..{n - 1} exactly once")
        return self


class SpinningPattern(CycleTimedPattern):
    """Multi-channel rotating head with per-channel elevations, offsets and firing timing."""

    name = "spinning"
    Options = SpinningOptions
    options: SpinningOptions

    def __init__(self, options: Any = None, sensor: Any = None) -> None:
        super().__init__(options, sensor)
        opts = self.options
        n = len(opts.elevations_deg)
        self._elevation = np.radians(np.asarray(opts.elevations_deg, dtype=np.float64))
        offsets = opts.azimuth_offsets_deg or [0.0] * n
        self._az_offset = np.radians(np.asarray(offsets, dtype=np.float64))
        self._spin = (-1.0 if opts.clockwise else 1.0) * 2.0 * np.pi

    def build_cycle(self) -> FiringCycle:
        opts = self.options
        n = len(opts.elevations_deg)
        order = np.asarray(opts.firing_order if opts.firing_order is not None else range(n))
        if opts.lasers_per_firing is not None:
            group = opts.lasers_per_firing
        else:
            group = n if opts.firing_interval_s == 0 else 1
        offsets = (np.arange(n) // group) * opts.firing_interval_s
        period = opts.cycle_period_s or n / self.sensor.point_rate_hz
        return FiringCycle(period, offsets, order)

    def head_azimuth(self, t: np.ndarray) -> np.ndarray:
        """Azimuth (rad) of the head's zero direction at times ``t``."""
        turns = np.mod(self.options.rotation_hz * np.asarray(t, dtype=np.float64), 1.0)
        return math.radians(self.options.azimuth_start_deg) + self._spin * turns

    def rays_for_indices(self, index: np.ndarray) -> RayBatch:
        index = np.asarray(index, dtype=np.int64)
        t, _, channel = self.cycle.rays(index)
        if kernels.enabled():
            from ..kernels.patterns import spinning_directions

            direction = spinning_directions(
                t, channel, float(self.options.rotation_hz),
                math.radians(self.options.azimuth_start_deg), float(self._spin),
                np.ascontiguousarray(self._az_offset, dtype=np.float64),
                np.ascontiguousarray(self._elevation, dtype=np.float64))
        else:
            azimuth = self.head_azimuth(t) + self._az_offset[channel]
            direction = directions_from_az_el(azimuth, self._elevation[channel])
        return RayBatch(index, t, direction, channel)

    def direction_groups(self, index: np.ndarray) -> DirectionGroups | None:
        """A group per slot of the firing cycle and block of :data:`GROUP_CYCLES` cycles: its
        rays share a channel (elevation and offset) and differ only by the head's turn between
        their cycles, at most ``GROUP_CYCLES // 2`` periods from the middle one (the
        representative); two directions at one elevation ``e`` whose azimuths differ by ``Δ``
        are at most ``Δ cos e <= Δ`` apart."""
        angle = 2.0 * math.pi * self.options.rotation_hz * self.cycle.period_s * \
            (GROUP_CYCLES // 2)
        return cycle_groups(index, self.cycle.size, GROUP_CYCLES, angle)

    def max_off_axis_rad(self) -> float:
        return math.pi


@hookimpl
def lidarsim_register_scan_patterns(register: Any) -> None:
    """Register the spinning pattern."""
    register(SpinningPattern)
