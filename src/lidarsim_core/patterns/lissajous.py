"""Built-in plugin: a Lissajous scan (resonant two-axis mirror, MEMS, RVS-class rendezvous LiDARs).

Both mirror axes oscillate sinusoidally::

    azimuth(t)   = A_az · sin(2π f_az t + φ_az)
    elevation(t) = el_c + A_el · sin(2π f_el t + φ_el)

with pulses every ``1 / point_rate_hz``. The amplitudes default to half the datasheet's FOV, so
the figure fills the FOV rectangle edge to edge. With integer frequencies the figure repeats
every ``1 / gcd(f_az, f_el)`` seconds; the ratio sets the line density.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from pydantic import Field

from .. import kernels
from ..base.components import ComponentOptions
from ..base.errors import ConfigError
from ..hookspecs import hookimpl
from .base import RayBatch, ScanPattern
from .geometry import directions_from_az_el


class LissajousOptions(ComponentOptions):
    """Options of the Lissajous pattern."""

    azimuth_hz: float = Field(gt=0, le=1e6, description="Azimuth-axis oscillation frequency.")
    elevation_hz: float = Field(gt=0, le=1e6, description="Elevation-axis oscillation "
                                                          "frequency.")
    azimuth_phase_deg: float = Field(0.0, description="φ_az (deg).")
    elevation_phase_deg: float = Field(90.0, description="φ_el (deg).")
    azimuth_amplitude_deg: float | None = Field(
        None, gt=0, description="A_az (deg); default: half the horizontal FOV.")
    elevation_amplitude_deg: float | None = Field(
        None, gt=0, description="A_el (deg); default: half the vertical FOV.")


class LissajousPattern(ScanPattern):
    """Two sinusoidally oscillating mirror axes (Lissajous figure), e.g. RVS-class or MEMS."""

    name = "lissajous"
    Options = LissajousOptions
    options: LissajousOptions

    def __init__(self, options: Any = None, sensor: Any = None) -> None:
        super().__init__(options, sensor)
        opts, sheet = self.options, self.sensor
        self._a_az = math.radians(opts.azimuth_amplitude_deg) \
            if opts.azimuth_amplitude_deg is not None else sheet.half_fov_h_rad
        self._a_el = math.radians(opts.elevation_amplitude_deg) \
            if opts.elevation_amplitude_deg is not None else sheet.half_fov_v_rad
        for label, amp, half in (("azimuth", self._a_az, sheet.half_fov_h_rad),
                                 ("elevation", self._a_el, sheet.half_fov_v_rad)):
            if amp > half * (1 + 1e-12):
                raise ConfigError(f"lissajous: the {label} amplitude "
                                  f"{math.degrees(amp):g}° exceeds half the datasheet FOV "
                                  f"({math.degrees(half):g}°)",
                                  field=f"scan_pattern.options.{label}_amplitude_deg")

    def angles(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Azimuth and elevation (rad) of the beam at times ``t`` (s)."""
        opts = self.options
        t = np.asarray(t, dtype=np.float64)
        phase_az = 2 * np.pi * np.mod(opts.azimuth_hz * t, 1.0) + math.radians(
            opts.azimuth_phase_deg)
        phase_el = 2 * np.pi * np.mod(opts.elevation_hz * t, 1.0) + math.radians(
            opts.elevation_phase_deg)
        return (self._a_az * np.sin(phase_az),
                math.radians(self.sensor.fov_v_center_deg) + self._a_el * np.sin(phase_el))

    def rays_for_indices(self, index: np.ndarray) -> RayBatch:
        index = np.asarray(index, dtype=np.int64)
        t = self.time_of_index(index)
        if kernels.enabled():
            from ..kernels.patterns import lissajous_directions

            opts = self.options
            direction = lissajous_directions(
                np.ascontiguousarray(t, dtype=np.float64), float(opts.azimuth_hz),
                math.radians(opts.azimuth_phase_deg), float(self._a_az),
                float(opts.elevation_hz), math.radians(opts.elevation_phase_deg),
                float(self._a_el), math.radians(self.sensor.fov_v_center_deg))
        else:
            direction = directions_from_az_el(*self.angles(t))
        return RayBatch(index, t, direction, np.zeros(len(index), dtype=np.int16))


@hookimpl
def lidarsim_register_scan_patterns(register: Any) -> None:
    """Register the Lissajous pattern."""
    register(LissajousPattern)
