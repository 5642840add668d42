"""Firing cycles: when each globally indexed ray is emitted, and by which channel.

Many sensors do not fire one pulse every ``1 / point_rate`` seconds. A spinning head fires its
lasers in a fixed order and then recharges; a flash LiDAR fires every pixel of a frame at the
same instant; a raster scanner pauses at the end of each line. All of these are a *firing
cycle*: ``N`` slots, slot ``s`` fired at ``offsets_s[s]`` after the cycle start by channel
``channels[s]``, the cycle repeating every ``period_s``. Ray ``k`` is slot ``k mod N`` of cycle
``k div N``, so time and channel are pure functions of the index and any time interval maps to
one contiguous index range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import kernels
from ..base.arrays import take_rows
from ..base.errors import ConfigError
from .base import RayBatch, ScanPattern

#: Times closer than this fraction of a cycle to a cycle start count as that start, so that an
#: interval boundary written as e.g. ``0.3`` s lands exactly on frame 9 of a 30 Hz sensor.
_SNAP = 1e-9


@dataclass(frozen=True)
class FiringCycle:
    """A repeating firing schedule.

    Parameters
    ----------
    period_s
        Duration of one cycle (s), > 0.
    offsets_s
        (N,) emission time of each slot after the cycle start (s): non-decreasing, in
        ``[0, period_s)``.
    channels
        (N,) channel id of each slot (fits int16).
    """

    period_s: float
    offsets_s: np.ndarray
    channels: np.ndarray
    _size: int = field(init=False, repr=False)

    def __post_init__(self) -> None:
        offsets = np.ascontiguousarray(self.offsets_s, dtype=np.float64).reshape(-1)
        channels = np.ascontiguousarray(self.channels).reshape(-1)
        if not (math.isfinite(self.period_s) and self.period_s > 0):
            raise ConfigError(f"firing cycle period must be > 0 s, got {self.period_s}")
        if len(offsets) == 0 or len(offsets) != len(channels):
            raise ConfigError("a firing cycle needs as many channels as slots (at least one)")
        if not np.all(np.isfinite(offsets)) or offsets[0] < 0 or np.any(np.diff(offsets) < 0):
            raise ConfigError("firing offsets must be finite, >= 0 and non-decreasing")
        if offsets[-1] >= self.period_s:
            raise ConfigError(f"the last firing ({offsets[-1]:.9g} s) is not before the end of "
                              f"the cycle ({self.period_s:.9g} s)")
        if channels.min() < 0 or channels.max() > np.iinfo(np.int16).max:
            raise ConfigError("channel ids must lie in 0..32767")
        object.__setattr__(self, "offsets_s", offsets)
        object.__setattr__(self, "channels", channels.astype(np.int16))
        object.__setattr__(self, "_size", len(offsets))

    @property
    def size(self) -> int:
        """Rays per cycle ``N``."""
        return self._size

    @property
    def mean_rate_hz(self) -> float:
        """Average rays per second, ``N / period_s``."""
        return self._size / self.period_s

    def count_before(self, t: float) -> int:
        """Number of rays emitted strictly before ``t`` seconds (0 for ``t <= 0``)."""
        if t <= 0:
            return 0
        u = t / self.period_s
        cycle = math.floor(u)
        if abs(u - round(u)) < _SNAP:
            cycle, rest = round(u), 0.0
        else:
            rest = t - cycle * self.period_s
        return cycle * self._size + int(np.searchsorted(self.offsets_s, rest, side="left"))

    def index_range(self, t_start: float, t_stop: float) -> tuple[int, int]:
        """Indices ``[k0, k1)`` of the rays emitted in ``[t_start, t_stop)``."""
        k0 = self.count_before(t_start)
        return k0, max(k0, self.count_before(t_stop))

    def slot(self, index: np.ndarray) -> np.ndarray:
        """Slot within its cycle of every ray ``index``."""
        return np.asarray(index, dtype=np.int64) % self._size

    def time(self, index: np.ndarray) -> np.ndarray:
        """Emission time (s) of every ray ``index``."""
        index = np.asarray(index, dtype=np.int64)
        cycle = index // self._size
        return cycle * self.period_s + self.offsets_s[index % self._size]

    def channel(self, index: np.ndarray) -> np.ndarray:
        """Channel id (int16) of every ray ``index``."""
        return self.channels[self.slot(index)]

    def rays(self, index: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Time (s), slot and channel of every ray ``index`` at once (one pass, compiled
        when the kernels are in use; the same values as :meth:`time`, :meth:`slot` and
        :meth:`channel`)."""
        index = np.asarray(index, dtype=np.int64)
        if kernels.enabled():
            from ..kernels.patterns import cycle_rays

            return cycle_rays(np.ascontiguousarray(index), self._size, float(self.period_s),
                              self.offsets_s, self.channels)
        slot = self.slot(index)
        return self.time(index), slot, self.channels[slot]


class CycleTimedPattern(ScanPattern):
    """A scan pattern whose timing is a :class:`FiringCycle` (built once, in ``__init__``).

    Subclasses implement :meth:`build_cycle` and either set :attr:`slot_directions` (a fixed
    direction per firing slot: flash pixels, raster positions) or implement
    :meth:`rays_for_indices`; they use :attr:`cycle` for the time, slot and channel of each
    index.
    """

    #: (slots, 3) unit direction of each firing slot when it never changes (None: the
    #: subclass computes directions in :meth:`rays_for_indices`).
    slot_directions: np.ndarray | None = None

    #: Relative excess of the schedule's mean rate over the datasheet point rate still accepted
    #: (datasheet rates are rounded figures).
    RATE_TOLERANCE = 1e-3

    def __init__(self, options: Any = None, sensor: Any = None) -> None:
        super().__init__(options, sensor)
        self.cycle = self.build_cycle()
        limit = self.sensor.point_rate_hz * (1 + self.RATE_TOLERANCE)
        if self.cycle.mean_rate_hz > limit:
            raise ConfigError(
                f"{self.name}: the firing schedule emits {self.cycle.mean_rate_hz:,.1f} rays/s, "
                f"more than the datasheet point_rate_hz {self.sensor.point_rate_hz:,.1f}",
                field="scan_pattern.options")

    def build_cycle(self) -> FiringCycle:
        """The firing schedule of this pattern (called once by ``__init__``)."""
        raise NotImplementedError

    @property
    def mean_rate_hz(self) -> float:
        """Average rays emitted per second."""
        return self.cycle.mean_rate_hz

    @property
    def rays_per_cycle(self) -> int:
        """Rays in one firing cycle."""
        return self.cycle.size

    def index_range(self, t_start: float, t_stop: float) -> tuple[int, int]:
        return self.cycle.index_range(t_start, t_stop)

    def time_of_index(self, index: np.ndarray) -> np.ndarray:
        return self.cycle.time(index)

    def nominal_az_el(self, batch: RayBatch, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """With fixed slot directions: each slot's azimuth and elevation computed once per
        pattern and gathered by slot (NumPy's ``arctan2`` and ``hypot`` work element by
        element, so the values are those of the directions gathered first), unless a
        subclass makes its own directions."""
        if self.slot_directions is None or \
                type(self).rays_for_indices is not CycleTimedPattern.rays_for_indices:
            return super().nominal_az_el(batch, rows)
        table = self.__dict__.get("_slot_az_el")
        if table is None or table[0] is not self.slot_directions:
            from .geometry import az_el_from_directions

            table = (self.slot_directions, *az_el_from_directions(self.slot_directions))
            self.__dict__["_slot_az_el"] = table
        slot = self.cycle.slot(take_rows(batch.index, rows))
        return np.take(table[1], slot), np.take(table[2], slot)

    def rays_for_indices(self, index: np.ndarray) -> RayBatch:
        if self.slot_directions is None:
            raise NotImplementedError(f"{type(self).__name__} sets no slot_directions and "
                                      "does not implement rays_for_indices()")
        index = np.asarray(index, dtype=np.int64)
        t, slot, channel = self.cycle.rays(index)
        return RayBatch(index, t, take_rows(self.slot_directions, slot), channel)
