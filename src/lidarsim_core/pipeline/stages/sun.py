r"""The Sun: shadows, solar background false alarms and blinding (docs/realism.md, "The Sun").

**Background.** A pulse's footprint on a surface of diffuse reflectivity ρ_d, lit by the Sun at
incidence θ_s, sends the receiver in-band background light; where a shadow ray from the hit
toward the Sun meets any target (cast through the same backend) the footprint is dark. The
background's shot noise adds to the receiver's own Gaussian noise σ_n of the link budget:

.. math::  σ^2 = σ_n^2 (1 + B), \qquad
           B = \frac{ρ_d \cos θ_s\, E_λ Δλ}{E_\mathrm{eq}}

with E_λ the solar spectral irradiance at the sensor's wavelength, Δλ the receiver's optical
filter width and E_eq the *noise-equivalent irradiance*: the in-band irradiance on a white
Lambertian surface filling the receiver's view whose background noise equals the receiver's
own. With divergence, B is the energy-weighted mean over the pulse's sub-rays.

**False alarms.** The threshold T = TNR σ_n stays where the link budget put it, so one range
cell of width ΔR (the range resolution) crosses it by noise alone with probability
``p(B) = Q(TNR / √(1 + B))`` (Q: the standard normal tail), and a pulse whose range gate holds
``N = (R_max − R_min) / ΔR`` cells has ``P(B) = 1 − (1 − p(B))^N``. The Sun adds
``P(B) − P(0)`` per pulse: the receiver's dark false alarms (B = 0) remain the ``false_alarms``
noise model's business. A solar false alarm lies at a uniform range in the gate, with the
threshold signal (S = 1), like any false alarm.

**Direction.** Either fixed (``direction``, scene frame) or from an orbit and an epoch
(``orbit``): the scene frame is then the target's LVLH frame on a circular orbit
(:mod:`lidarsim_core.trajectories.orbit`: +x radial, +y along-track, +z orbit normal), the Sun's
inertial direction comes from the Astronomical Almanac's low-precision solar coordinates
(about 0.01°) at each pulse's time, and in the Earth's (cylindrical) shadow there is no Sun.

**Detection.** The same noise lowers the detection probability of the pulse's real returns,
``P_d = Φ(TNR (S − 1) / √(1 + B))``: sunlit surfaces are seen less far.

**The Earth** (scenario block ``earth``, with ``orbit``): pulses whose rays meet no target
but the sunlit Earth get its background too (:mod:`.earth`), added to the surfaces' before
the false alarms are drawn.

**Blinding.** Pulses whose flown direction lies within ``blinding_angle_deg`` of the Sun are
blinded (the Sun floods the receiver): they report nothing. The default is the Sun's angular
radius (0.2666°) plus the receiver's acceptance half-angle: the solar disc inside the
receiver's view.

Reads ``piece.hits`` (with normals), ``piece.scene`` and ``piece.cand``; writes ``piece.cand``
(blinded pulses' candidates removed, solar false alarms added) and ``piece.noise_scale``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from ...base.errors import ConfigError
from ...geometry.frames import rotate, to_body
from ...geometry.vec3 import rowdot
from ...instrument.returns import Candidates
from ...noise.rng import ray_uniforms
from .base import Piece
from .bounces import BOUNCE_OFFSET_M
from .earth import EarthBackground

if TYPE_CHECKING:
    from .candidates import CandidateStage
from ...scenario.sun import DEFAULT_FILTER_WIDTH_NM, SunConfig, SunOrbit
from ..context import RunContext

#: Solar effective temperature (K): IAU 2015 Resolution B3 nominal value.
SUN_TEMPERATURE_K = 5772.0


#: Total solar irradiance at 1 au (W/m²): Kopp & Lean, GRL 2011 (SORCE/TIM), 1360.8 ± 0.5.
SOLAR_CONSTANT_W_M2 = 1361.0


#: The Sun's angular radius seen from 1 au (deg): 695 700 km (IAU nominal) / 1 au.
SUN_ANGULAR_RADIUS_DEG = 0.2666




#: Random stream of the solar false alarms.
SUN_STREAM = "sun"


_H, _C, _K = 6.62607015e-34, 299792458.0, 1.380649e-23


_SIGMA = 5.670374419e-8


def solar_spectral_irradiance(wavelength_nm: float) -> float:
    """E_λ at 1 au (W m⁻² nm⁻¹): a 5772 K blackbody normalised to the solar constant.

    An approximation of the measured AM0 spectrum (ASTM E-490), smooth where the real one has
    absorption lines; give ``sun.spectral_irradiance_w_m2_nm`` to use a measured value.
    """
    lam = wavelength_nm * 1e-9
    planck = 2.0 * _H * _C ** 2 / lam ** 5 / math.expm1(_H * _C / (lam * _K * SUN_TEMPERATURE_K))
    # π B_λ is the exitance; scaled so that its integral σT⁴ becomes the solar constant
    return math.pi * planck * SOLAR_CONSTANT_W_M2 / (_SIGMA * SUN_TEMPERATURE_K ** 4) * 1e-9


def sun_direction_eci(unix_s: np.ndarray) -> np.ndarray:
    """(N, 3) unit vectors toward the Sun in the mean equatorial frame of date (Earth-centred
    inertial), from the Astronomical Almanac's low-precision formulas (about 0.01°)."""
    days = (np.asarray(unix_s, dtype=np.float64) / 86400.0 + 2440587.5) - 2451545.0
    mean_longitude = np.radians(280.460 + 0.9856474 * days)
    anomaly = np.radians(357.528 + 0.9856003 * days)
    ecliptic = mean_longitude + np.radians(1.915 * np.sin(anomaly)
                                           + 0.020 * np.sin(2.0 * anomaly))
    obliquity = np.radians(23.439 - 4e-7 * days)
    return np.stack([np.cos(ecliptic), np.cos(obliquity) * np.sin(ecliptic),
                     np.sin(obliquity) * np.sin(ecliptic)], axis=1)


def sun_in_lvlh(orbit: SunOrbit, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sun direction in the target's LVLH frame at times ``t`` (s from the epoch), and whether
    the target is in the Earth's cylindrical shadow."""
    from ...trajectories.orbit import R_EARTH_M, mean_motion_from_altitude

    t = np.asarray(t, dtype=np.float64)
    sun = sun_direction_eci(orbit.epoch.timestamp() + t)
    n = mean_motion_from_altitude(orbit.altitude_km)
    u = math.radians(orbit.argument_of_latitude_deg) + n * t
    # perifocal → inertial: R3(−Ω) R1(−i)
    frame = Rotation.from_euler("ZX", [orbit.raan_deg, orbit.inclination_deg], degrees=True)
    zeros = np.zeros_like(u)
    radial = frame.apply(np.stack([np.cos(u), np.sin(u), zeros], axis=1))
    along = frame.apply(np.stack([-np.sin(u), np.cos(u), zeros], axis=1))
    normal = frame.apply(np.array([0.0, 0.0, 1.0]))
    lvlh = np.stack([rowdot(sun, radial), rowdot(sun, along), sun @ normal], axis=1)
    a = R_EARTH_M + 1000.0 * orbit.altitude_km
    along_sun = a * rowdot(radial, sun)
    eclipse = (along_sun < 0) & (a * a - along_sun * along_sun < R_EARTH_M ** 2)
    return lvlh, eclipse


def false_alarm_probability(background: np.ndarray, threshold_to_noise: float,
                            cells: float) -> np.ndarray:
    """P(B) = 1 − (1 − Q(TNR/√(1+B)))^N: probability that noise crosses the threshold in one
    of a pulse's N range cells."""
    from scipy.special import ndtr

    p_cell = ndtr(-threshold_to_noise / np.sqrt(1.0 + np.asarray(background, dtype=np.float64)))
    return -np.expm1(cells * np.log1p(-p_cell))


class SunStage:
    """Solar background false alarms and blinding (see the module docstring)."""

    name = "sun"

    def __init__(self, ctx: RunContext, config: SunConfig, candidates: "CandidateStage"
                 ) -> None:
        from ...scenario.sensor import MultipathConfig
        from .bounces import acceptance_deg

        src, sheet = ctx.scenario.source, ctx.sensor
        if ctx.link is None:
            raise ConfigError("the Sun's false alarms come from the link budget's receiver "
                              "model; add 'detection: {}' to the sensor", source=src,
                              field="sun")
        if ctx.range_resolution_m is None:
            raise ConfigError(f"false alarms are counted per range cell and datasheet "
                              f"'{sheet.name}' gives no range_resolution_m; give "
                              "sensor.returns.range_resolution_m", source=src, field="sun")
        irradiance = config.spectral_irradiance_w_m2_nm
        if irradiance is None:
            if sheet.wavelength_nm is None:
                raise ConfigError(f"datasheet '{sheet.name}' gives no wavelength_nm to find "
                                  "the solar irradiance at; give it here", source=src,
                                  field="sun.spectral_irradiance_w_m2_nm")
            irradiance = solar_spectral_irradiance(sheet.wavelength_nm)
        self.irradiance = irradiance
        self.filter_width_nm = (config.filter_width_nm or sheet.optical_filter_nm
                                or DEFAULT_FILTER_WIDTH_NM)
        #: B of a white Lambertian surface facing the Sun.
        self.white_background = irradiance * self.filter_width_nm \
            / config.noise_equivalent_irradiance_w_m2
        self.orbit = config.orbit
        #: The fixed direction toward the Sun (scene frame), None when it follows an orbit.
        self.direction: np.ndarray | None = None
        if config.direction is not None:
            direction = np.asarray(config.direction, dtype=np.float64)
            self.direction = direction / np.linalg.norm(direction)
        blinding = config.blinding_angle_deg
        if blinding is None:
            multipath = ctx.scenario.sensor.multipath or MultipathConfig()
            blinding = SUN_ANGULAR_RADIUS_DEG + acceptance_deg(multipath,
                                                               sheet.beam_divergence_deg)
        self.blinding_deg = blinding
        self.cos_blinding = math.cos(math.radians(blinding))
        self.threshold_to_noise = ctx.link.threshold_to_noise
        self.range_min_m, self.range_limit = sheet.range_min_m, ctx.range_limit
        self.cells = (self.range_limit - self.range_min_m) / ctx.range_resolution_m
        self.dark = float(false_alarm_probability(0.0, self.threshold_to_noise, self.cells))
        self.seed = ctx.scenario.seed
        self.backend, self.targets, self.materials = ctx.backend, ctx.targets, ctx.materials
        self.sub_rays = ctx.sub_rays
        self.candidates = candidates
        #: The Earth as a background source (scenario block ``earth``), or None.
        self.earth: EarthBackground | None = None
        if ctx.scenario.earth is not None:
            if self.orbit is None:
                raise ConfigError("the Earth's place and its sunlit side follow the target's "
                                  "orbit and epoch; give sun: {orbit: ...} instead of a fixed "
                                  "direction", source=src, field="earth")
            self.earth = EarthBackground(ctx.scenario.earth, self.orbit.altitude_km,
                                         self.white_background)

    def info(self) -> dict:
        """Frame metadata: direction or orbit, irradiance, filter, white background, blinding."""
        return {"direction": None if self.direction is None else self.direction.tolist(),
                "orbit": None if self.orbit is None else self.orbit.model_dump(mode="json"),
                "spectral_irradiance_w_m2_nm": self.irradiance,
                "filter_width_nm": self.filter_width_nm,
                "white_background": self.white_background,
                "blinding_angle_deg": self.blinding_deg,
                **({} if self.earth is None else {"earth": self.earth.info()})}

    def probability(self, background: np.ndarray) -> np.ndarray:
        """Solar false alarms per pulse: P(B) − P(0)."""
        return np.maximum(false_alarm_probability(background, self.threshold_to_noise,
                                                  self.cells) - self.dark, 0.0)

    def sun_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) directions toward the Sun (scene frame) at pulse times ``t`` and whether the
        Sun shines there (False in the Earth's shadow)."""
        if self.direction is not None:
            return np.broadcast_to(self.direction, (len(t), 3)), np.ones(len(t), dtype=bool)
        direction, eclipse = sun_in_lvlh(self.orbit, t)
        return direction, ~eclipse

    def run(self, piece: Piece) -> None:
        batch, hits, scene = piece.batch, piece.hits, piece.scene
        k = 1 if self.sub_rays is None else self.sub_rays.count
        n = len(batch)
        sun, shining = self.sun_at(batch.t)
        # blinding: the flown direction (scene frame) within the angle of the Sun
        blinded = shining & (rowdot(scene.vectors[0], sun) >= self.cos_blinding)
        background = self.background(hits, scene, k, n, sun) * shining
        if self.earth is not None:  # lit even while the target is in the Earth's shadow
            background = background + self.earth_background(hits, scene, k, n, sun)
        piece.noise_scale = np.sqrt(1.0 + background)
        u = ray_uniforms(self.seed, piece.frame, SUN_STREAM, batch.index, 2)
        alarm = np.flatnonzero((u[:, 0] < self.probability(background)) & ~blinded)
        rng = self.range_min_m + u[alarm, 1] * (self.range_limit - self.range_min_m)
        cand = piece.cand
        if blinded.any():
            keep = np.flatnonzero(~blinded[cand.pulse])
            cand = Candidates(**{key: None if v is None else v[keep]
                                 for key, v in cand.__dict__.items()})
        piece.cand = Candidates.concatenate([cand, self.candidates.spurious_candidates(alarm,
                                                                                         rng)])

    def background(self, hits, scene, k: int, n: int, sun: np.ndarray) -> np.ndarray:
        """B of every pulse: sunlit footprint share × ρ_d cos θ_s × B_white (energy-weighted
        over sub-rays)."""
        ray = np.flatnonzero(hits.target >= 0)
        pulse = ray // k
        d_all = scene.vectors[0] if self.sub_rays is None else \
            self.sub_rays.directions(*scene.vectors)
        origin = scene.origin if len(scene.origin) == 1 else scene.origin[pulse]
        direction = d_all[ray]
        point = origin + direction * hits.distance[ray][:, None]
        target = hits.target[ray]
        normal = np.empty((len(ray), 3))
        for j in np.unique(target):
            sel = np.flatnonzero(target == j)
            normal[sel] = rotate(scene.target_poses[j].take(pulse[sel]), hits.normal[ray[sel]])
        # the side of the surface the sensor sees
        normal *= -np.sign(rowdot(normal, direction))[:, None]
        sun_ray = sun[pulse]
        cos_sun = rowdot(normal, sun_ray)
        lit = np.flatnonzero(cos_sun > 0)
        shadowed = self._shadowed(point[lit], sun_ray[lit], pulse[lit], scene.target_poses,
                                  hits.distance[ray[lit]], target[lit], hits.face[ray[lit]])
        lit = lit[~shadowed]
        weight = np.full(len(ray), 1.0 / k) if self.sub_rays is None else \
            self.sub_rays.weights[ray % k]
        contribution = np.zeros(len(ray))
        contribution[lit] = (weight[lit] * self.materials.diffuse[hits.part[ray[lit]]]
                             * cos_sun[lit] * self.white_background)
        return np.bincount(pulse, weights=contribution, minlength=n)

    def earth_background(self, hits, scene, k: int, n: int, sun: np.ndarray) -> np.ndarray:
        """B of every pulse from the sunlit Earth, seen by its (sub-)rays that meet no
        target (:class:`~.earth.EarthBackground`)."""
        ray = np.flatnonzero(hits.target < 0)
        pulse = ray // k
        d_all = scene.vectors[0] if self.sub_rays is None else \
            self.sub_rays.directions(*scene.vectors)
        origin = scene.origin if len(scene.origin) == 1 else scene.origin[pulse]
        weight = np.full(len(ray), 1.0 / k) if self.sub_rays is None else \
            self.sub_rays.weights[ray % k]
        return self.earth.background(origin, d_all[ray], pulse, weight, sun, n)

    def _shadowed(self, point: np.ndarray, sun: np.ndarray, pulse: np.ndarray,
                  target_poses: list, distance: np.ndarray, from_target: np.ndarray,
                  from_face: np.ndarray) -> np.ndarray:
        """Whether the shadow ray from each point toward the Sun meets any target."""
        blocked = np.zeros(len(point), dtype=bool)
        if not len(point):
            return blocked
        start = point + sun * (BOUNCE_OFFSET_M * (1.0 + distance))[:, None]
        for j, target in enumerate(self.targets):
            poses = target_poses[j].take(pulse)
            hits = self.backend.cast(target.mesh, to_body(poses, start),
                                     rotate(poses, sun, inverse=True))
            blocked |= hits.hit & ~((from_target == j) & (hits.face == from_face))
        return blocked
