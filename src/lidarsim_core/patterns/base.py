"""Base class of scan-pattern plugins and the ray batch they produce.

A pattern is a pure, vectorised function of the global ray index: ray ``k`` of a scan has a
fixed emission time, direction and channel. Generating ``[0, T)`` at once or in pieces
therefore gives identical rays.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np

from .. import kernels
from ..base.arrays import take_rows
from ..base.components import Component
from ..base.errors import UserInputError
from ..scenario.datasheet import SensorDatasheet
from .geometry import off_axis_angle


@dataclass(frozen=True)
class RayBatch:
    """Rays emitted by a sensor, in the sensor frame.

    Attributes
    ----------
    index
        (N,) int64 global ray index (emission order from scan start).
    t
        (N,) float64 emission time in seconds from scan start.
    direction
        (N, 3) float64 unit directions in the sensor frame (+X boresight, +Y left, +Z up).
    channel
        (N,) int16 emitter/channel id.
    poses
        The sensor's and targets' poses at these rays, once the pipeline has looked them up
        (:func:`lidarsim_core.pipeline.posing.with_piece_poses`), else None.
    """

    index: np.ndarray
    t: np.ndarray
    direction: np.ndarray
    channel: np.ndarray
    poses: Any = field(default=None, compare=False, repr=False)

    def __len__(self) -> int:
        return len(self.index)

    def take(self, rows: np.ndarray) -> "RayBatch":
        """The rays at ``rows`` (indices into this batch)."""
        return RayBatch(take_rows(self.index, rows), take_rows(self.t, rows),
                        take_rows(self.direction, rows), take_rows(self.channel, rows),
                        None if self.poses is None else self.poses.take(rows))


@dataclass(frozen=True)
class DirectionGroups:
    """Rays grouped by direction (:meth:`ScanPattern.direction_groups`): every ray of group
    ``g`` is within ``angle`` (rad) of the ray ``representative[g]``.

    Attributes
    ----------
    representative
        (G,) the index of one ray of each group.
    angle
        The largest angle (rad) between a ray and its group's representative.
    members
        ``members(groups)``: the indices (ascending) of the rays of the groups ``groups``
        (ascending positions in ``representative``).
    """

    representative: np.ndarray
    angle: float
    members: Callable[[np.ndarray], np.ndarray]


def cycle_groups(index: np.ndarray, size: int, cycles: int, angle: float,
                 rounding: float = 0.0) -> DirectionGroups | None:
    """Direction groups of a pattern that fires ``size`` slots per cycle (ray ``k`` in slot
    ``k mod size``): a group per slot and block of ``cycles`` cycles, its representative the
    middle ray, so no ray is more than ``cycles // 2`` cycles from it. ``angle`` bounds
    the angle between two rays of one slot that many cycles apart (the pattern's bound; see
    :meth:`ScanPattern.direction_groups`) and ``rounding`` how far the computed directions
    may stray from the exact ones; the groups' angle is ``angle`` grown by ``1e-9`` of it,
    ``rounding`` and a nanoradian. None unless ``index`` is consecutive. Made by
    :mod:`lidarsim_core.kernels.groups` where the kernels are on."""
    angle = angle * (1.0 + 1e-9) + rounding + 1e-9
    index = np.asarray(index, dtype=np.int64)
    n = len(index)
    if n == 0 or index[-1] - index[0] != n - 1:
        return None
    first, last = int(index[0]), int(index[-1])
    if kernels.enabled():
        from ..kernels.groups import group_members, slot_groups

        representative, low, high, slot = slot_groups(first, last, size, cycles)
        return DirectionGroups(representative, angle, lambda groups: group_members(
            low, high, slot, size, np.ascontiguousarray(groups, dtype=np.int64)))
    block0 = first // size // cycles
    blocks = last // size // cycles - block0 + 1
    block = np.repeat(np.arange(block0, block0 + blocks, dtype=np.int64), size)
    slot = np.tile(np.arange(size, dtype=np.int64), blocks)
    # the cycles of each (block, slot) whose ray lies in [first, last]
    low = np.maximum(block * cycles, -((slot - first) // size))
    high = np.minimum(block * cycles + cycles - 1, (last - slot) // size)
    present = low <= high
    low, high, slot = low[present], high[present], slot[present]

    def members(groups: np.ndarray) -> np.ndarray:
        count = high[groups] - low[groups] + 1
        starts = np.cumsum(count) - count
        cycle = np.repeat(low[groups] - starts, count) + np.arange(int(count.sum()))
        rays = cycle * size + np.repeat(slot[groups], count)
        return rays if size == 1 else np.sort(rays)

    return DirectionGroups((low + high) // 2 * size + slot, angle, members)


def power_of_two_above(x: float) -> float:
    """The least power of two ``>= x`` (1 for ``x <= 1``): a pattern's groups round the scan
    time in their angle's rounding term up to it, so that the pieces of a scan share a few
    angles, and the cull one cube map per angle."""
    return 2.0 ** max(0, math.ceil(math.log2(x))) if x > 1.0 else 1.0


class ScanPattern(Component):
    """A scan pattern bound to one sensor datasheet.

    Subclasses implement :meth:`rays_for_indices`; ones whose rays are not emitted one by one
    at the datasheet point rate (e.g. flash arrays) also override :meth:`index_range` and
    :meth:`time_of_index`.

    Parameters
    ----------
    options
        Validated pattern options.
    sensor
        The datasheet the pattern belongs to (FOV, point rate).
    """

    def __init__(self, options: Any = None, sensor: SensorDatasheet | None = None) -> None:
        super().__init__(options)
        if sensor is None:
            raise TypeError(f"{type(self).__name__} needs the sensor datasheet")
        self.sensor = sensor

    @classmethod
    def for_sensor(cls, sensor: SensorDatasheet, overrides: Mapping[str, Any] | None = None,
                   *, source: str | None = None) -> "ScanPattern":
        """Build the pattern from the datasheet's ``scan_pattern.options`` plus ``overrides``.

        Raises
        ------
        ConfigError
            Naming ``source`` and the option when an option is unknown or invalid.
        """
        from ..base.validation import validate_model

        options = {**sensor.scan_pattern.options, **(overrides or {})}
        opts = validate_model(cls.Options, options, source=source,
                              prefix="scan_pattern.options")
        try:
            return cls(opts, sensor)
        except UserInputError as exc:
            if exc.source or source is None:
                raise
            # a problem found while building (e.g. in a pattern file): say which scenario
            raise type(exc)(exc.message, source=source,
                            field=exc.field or "scan_pattern") from None

    @property
    def rate_hz(self) -> float:
        """Rays emitted per second."""
        return self.sensor.point_rate_hz

    def index_range(self, t_start: float, t_stop: float) -> tuple[int, int]:
        """Indices ``[k0, k1)`` of rays emitted in ``[t_start, t_stop)``."""
        def first_at_or_after(t: float) -> int:
            # round before ceil so that t * rate landing a hair above an integer is exact
            return max(0, math.ceil(round(t * self.rate_hz, 6)))

        return first_at_or_after(t_start), first_at_or_after(t_stop)

    def time_of_index(self, index: np.ndarray) -> np.ndarray:
        """Emission time (s) of global ray ``index``."""
        return np.asarray(index, dtype=np.float64) / self.rate_hz

    def frame_index_range(self, t_start: float, t_stop: float) -> tuple[int, int]:
        """Indices ``[k0, k1)`` of the rays of one frame spanning ``[t_start, t_stop)``: every
        ray emitted in it (:meth:`index_range`), unless the sensor has a native frame that is
        shorter (a flash LiDAR's frame is one flash)."""
        return self.index_range(t_start, t_stop)

    def rays(self, t_start: float, t_stop: float) -> RayBatch:
        """All rays emitted in ``[t_start, t_stop)`` seconds from scan start."""
        k0, k1 = self.index_range(t_start, t_stop)
        return self.rays_for_indices(np.arange(k0, k1, dtype=np.int64))

    @abstractmethod
    def rays_for_indices(self, index: np.ndarray) -> RayBatch:
        """The rays with global indices ``index`` ((N,) int64, non-negative)."""

    def nominal_az_el(self, batch: RayBatch, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Azimuth and elevation (rad) of the nominal directions of ``batch``'s rays at
        ``rows`` (the record's ``azimuth`` and ``elevation`` columns)."""
        from .geometry import az_el_from_directions

        return az_el_from_directions(take_rows(batch.direction, rows))

    def max_off_axis_rad(self) -> float:
        """Largest angle from the boresight any ray can have (for FOV checks)."""
        return math.hypot(self.sensor.half_fov_h_rad, self.sensor.half_fov_v_rad)

    def direction_groups(self, index: np.ndarray) -> "DirectionGroups | None":
        """Groups of the rays ``index`` (ascending, consecutive) that each stay near one of
        their rays, for culling before the directions are computed; None when the pattern
        gives no such bound (the default; :mod:`lidarsim_core.pipeline.cull` then computes
        every ray). Used only when defined by the class that defines
        :meth:`rays_for_indices` or a subclass, and only for patterns whose rays are emitted
        in the order of their indices."""
        return None

    def inside_fov(self, directions: np.ndarray, tol_rad: float = 1e-9) -> np.ndarray:
        """Whether each direction lies inside the datasheet FOV (shape-aware)."""
        sheet = self.sensor
        if sheet.fov_type == "circular":
            return off_axis_angle(directions) <= sheet.half_fov_h_rad + tol_rad
        from .geometry import az_el_from_directions

        az, el = az_el_from_directions(directions)
        el_ok = np.abs(el - math.radians(sheet.fov_v_center_deg)) <= sheet.half_fov_v_rad + tol_rad
        if sheet.fov_type == "panoramic" and sheet.fov_h_deg >= 360:
            return el_ok
        return el_ok & (np.abs(az) <= sheet.half_fov_h_rad + tol_rad)
