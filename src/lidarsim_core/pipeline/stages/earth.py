"""The Earth behind the target: its sunlit disc as a background source (docs/realism.md,
"The Earth").

In low orbit the Earth fills much of the sky below the target. A pulse that meets no target
and whose ray meets the Earth returns nothing (the Earth is far beyond the range gate), but
its receiver looks at the Earth's surface, lit by the Sun at the solar zenith angle θ_s there.
Read as a Lambertian surface of reflectance ``albedo`` filling the receiver's view, that is
the background of a sunlit surface of the Sun stage, with the same formula:

.. math::  B = a\\, \\max(0, \\cos θ_s)\\, E_λ Δλ / E_\\mathrm{eq}

(energy-weighted over the pulse's sub-rays: those that hit a target see the target instead),
so the Earth raises the false-alarm probability ``P(B) − P(0)`` and lowers the detection
probability of the pulse's other returns exactly as sunlit surfaces do.

Geometry: the scene frame is the target's LVLH frame on the orbit of ``sun.orbit``
(:mod:`lidarsim_core.trajectories.orbit`), so the Earth's centre is at ``(−(R⊕ + h), 0, 0)``
and its radius is R⊕; the Sun's direction in that frame at each pulse's time comes from the
same ephemeris as the Sun stage's. A surface point with outward normal n is lit when n·s > 0
(the Sun's parallax across the Earth, 4·10⁻⁵ rad, is neglected), with cos θ_s = n·s.

The settings model :class:`~lidarsim_core.scenario.earth.EarthConfig` is the scenario's
``earth`` block; the background is computed by :class:`EarthBackground`, which the Sun stage adds to its own before it draws the
false alarms (one draw per pulse for the total background).
"""

from __future__ import annotations

import numpy as np

from ...geometry.vec3 import rowdot
from ...scenario.earth import EarthConfig
from ...trajectories.orbit import R_EARTH_M


class EarthBackground:
    """Background B of every pulse from the sunlit Earth seen past the targets.

    Parameters
    ----------
    config
        The ``earth`` block.
    altitude_km
        The target's altitude (``sun.orbit.altitude_km``).
    white_background
        B of a white Lambertian surface facing the Sun (``E_λ Δλ / E_eq``, the Sun stage's).
    """

    def __init__(self, config: EarthConfig, altitude_km: float,
                 white_background: float) -> None:
        self.albedo = config.albedo
        self.radius_m = R_EARTH_M
        self.centre_m = np.array([-(R_EARTH_M + 1000.0 * altitude_km), 0.0, 0.0])
        self.white_background = white_background

    def info(self) -> dict:
        """Frame metadata: albedo and B of the Earth under a zenith Sun."""
        return {"albedo": self.albedo,
                "background_zenith_sun": self.albedo * self.white_background}

    def surface(self, origin: np.ndarray, direction: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """Where rays from ``origin`` along unit ``direction`` (scene frame, (M, 3) each, or
        (1, 3) origin) meet the Earth: a (M,) mask and the (M, 3) outward unit normals there
        (rows without a hit hold NaN)."""
        p = origin - self.centre_m  # from the Earth's centre
        b = rowdot(direction, np.broadcast_to(p, direction.shape))
        # |p|² − R², written so the two ~10¹³ m² terms cancel exactly in the radial part
        px = p[..., 0]
        c = (px - self.radius_m) * (px + self.radius_m) + p[..., 1] ** 2 + p[..., 2] ** 2
        disc = b * b - c
        hit = disc >= 0.0
        t = np.where(hit, -b - np.sqrt(np.where(hit, disc, 0.0)), np.nan)
        hit &= t > 0.0  # in front of the sensor (the sensor is outside the Earth)
        normal = (np.broadcast_to(p, direction.shape) + direction * t[:, None]) / self.radius_m
        normal[~hit] = np.nan
        return hit, normal

    def background(self, origin: np.ndarray, direction: np.ndarray, pulse: np.ndarray,
                   weight: np.ndarray, sun: np.ndarray, n: int) -> np.ndarray:
        """(n,) B of each pulse from its (sub-)rays that meet no target.

        Parameters
        ----------
        origin
            (1, 3) or (M, 3) sensor position of each ray, scene frame.
        direction
            (M, 3) unit directions of the rays that meet no target, scene frame.
        pulse
            (M,) the pulse of each ray.
        weight
            (M,) each ray's share of its pulse's energy.
        sun
            (n, 3) unit direction toward the Sun of each pulse, scene frame.
        n
            Number of pulses.
        """
        if not len(direction):
            return np.zeros(n)
        hit, normal = self.surface(origin, direction)
        cos_sun = np.where(hit, rowdot(np.nan_to_num(normal), sun[pulse]), 0.0)
        contribution = weight * np.maximum(cos_sun, 0.0) * (self.albedo *
                                                            self.white_background)
        return np.bincount(pulse, weights=contribution, minlength=n)
