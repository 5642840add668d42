"""Built-in plugin: the seed paper's rose (petal) pattern, r = A·sin(B·φ).

The paper models the Livox MID-70's non-repetitive petal scan with the polar rose of its
Eq. 1. Here ``r`` is the off-axis angle of the ray (so a circular FOV of half-angle A is filled
exactly) and ``φ`` is the roll angle about the boresight. ``φ`` advances uniformly in time,
one full turn (2π) every ``turn_period_s``; after each full turn the whole rosette is rotated
about the boresight by ``rotation_per_turn_deg`` (paper: 5°), so successive rosettes fill the
FOV.

Petal count: for integer B the classic rose has B petals when B is odd (each traced twice per
turn) and 2B petals when B is even (each traced once).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from pydantic import Field

from .. import kernels
from ..base.components import ComponentOptions
from ..hookspecs import hookimpl
from .base import DirectionGroups, RayBatch, ScanPattern, cycle_groups, power_of_two_above
from .geometry import directions_from_off_axis


#: Rays per group of :meth:`RosePattern.direction_groups` (the MID-70 rose's group spans
#: 0.16 ms; its rays stay within 1.8° of the middle one).
GROUP_RAYS = 16


class RoseOptions(ComponentOptions):
    """Options of the rose pattern."""

    b: int = Field(4, ge=1, le=1000, description="B of r = A·sin(B·φ) (integer).")
    a_deg: float | None = Field(
        None, gt=0, lt=90, description="A of Eq. 1 as an off-axis angle (deg); default: half "
                                       "the datasheet's horizontal FOV.")
    turn_period_s: float = Field(0.04014, gt=0,
                                 description="Time for φ to make one full turn (s).")
    rotation_per_turn_deg: float = Field(5.0, description="Rotation of the rosette after each "
                                                          "full turn (deg; paper: 5).")
    phase_deg: float = Field(0.0, description="Rotation of the first rosette (deg).")


class RosePattern(ScanPattern):
    """Polar rose r = A·sin(B·φ), rotated after every turn (seed paper, Eq. 1)."""

    name = "rose"
    Options = RoseOptions
    options: RoseOptions

    @property
    def amplitude_rad(self) -> float:
        """A in radians."""
        a_deg = self.options.a_deg
        return math.radians(a_deg) if a_deg is not None else self.sensor.half_fov_h_rad

    @property
    def petals_per_turn(self) -> int:
        """Distinct petals drawn in one turn of φ."""
        b = self.options.b
        return b if b % 2 else 2 * b

    def phi_and_turn(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """φ (rad, within the current turn) and the turn number at times ``t``."""
        turns = np.asarray(t, dtype=np.float64) / self.options.turn_period_s
        turn_number = np.floor(turns)
        return 2.0 * np.pi * (turns - turn_number), turn_number.astype(np.int64)

    def rays_for_indices(self, index: np.ndarray) -> RayBatch:
        index = np.asarray(index, dtype=np.int64)
        if kernels.enabled() and type(self).time_of_index is ScanPattern.time_of_index:
            from ..kernels.rose import rose_directions

            o = self.options
            t, direction = rose_directions(np.ascontiguousarray(index), float(self.rate_hz),
                                           float(o.b), self.amplitude_rad, o.turn_period_s,
                                           o.rotation_per_turn_deg, o.phase_deg)
            return RayBatch(index, t, direction, np.zeros(len(index), dtype=np.int16))
        t = self.time_of_index(index)
        phi, turn = self.phi_and_turn(t)
        r = self.amplitude_rad * np.sin(self.options.b * phi)
        roll = phi + np.radians(self.options.phase_deg + self.options.rotation_per_turn_deg * turn)
        # a negative r is the point on the opposite side: (|r|, roll + π)
        direction = directions_from_off_axis(np.abs(r), roll + np.where(r < 0, np.pi, 0.0))
        return RayBatch(index, t, direction, np.zeros(len(index), dtype=np.int16))

    def max_off_axis_rad(self) -> float:
        return self.amplitude_rad

    def max_turn_rate(self) -> float:
        """An upper bound of how fast a ray's direction turns (rad/s): ``2π·A·B / T``.

        The direction ``(cos r, sin r cos ψ, sin r sin ψ)``, with the signed ``r = A sin(Bφ)``
        and ``ψ = φ +`` the rosette's rotation, moves on the unit sphere at ``|u'|² = r'² +
        sin²r ψ'² <= (2π/T)² (A²B² cos²Bφ + A² sin²Bφ) <= (2πAB/T)²`` (``|sin r| <= |r|``,
        ``B >= 1``), and it is continuous where a turn ends and the rosette rotates: ``r = 0``
        there, the boresight whatever the roll."""
        return 2.0 * math.pi * self.amplitude_rad * self.options.b / self.options.turn_period_s

    def direction_groups(self, index: np.ndarray) -> DirectionGroups | None:
        """Groups of :data:`GROUP_RAYS` consecutive rays, each within ``max_turn_rate ·
        (GROUP_RAYS // 2) / rate`` of its middle ray (an arc on the sphere is no shorter
        than the angle between its ends), grown by the rounding of φ in long scans (a few
        ulp of the turn count) and a nanoradian. None when a subclass changes the emission
        times."""
        index = np.asarray(index, dtype=np.int64)
        if len(index) == 0 or type(self).time_of_index is not ScanPattern.time_of_index:
            return None
        # the turn count rounded up to a power of two, so that a scan's pieces share a few
        # angles (and the cull its cube maps: one per angle)
        turns = power_of_two_above(float(index[-1]) / self.rate_hz / self.options.turn_period_s)
        rounding = 2.0 * math.pi * (self.amplitude_rad * self.options.b + 1.0) * turns * 2.0 ** -50
        angle = self.max_turn_rate() * (GROUP_RAYS // 2) / self.rate_hz
        return cycle_groups(index, 1, GROUP_RAYS, angle, rounding)


@hookimpl
def lidarsim_register_scan_patterns(register: Any) -> None:
    """Register the rose pattern."""
    register(RosePattern)
