"""Built-in plugin: the rotating-prism (Risley) scanner of Livox-style LiDARs, traced exactly.

Geometry
--------
Each laser channel's beam enters the prism stack travelling along its own incident direction
(near the boresight +X). Each prism is a wedge of glass with one face perpendicular to the
optical axis and the other tilted by the *wedge angle*; ``wedge_face`` says which face is the
tilted one (``entrance`` or ``exit``). Prism ``i`` turns about +X at ``rotor_hz`` (positive:
counter-clockwise seen from behind the sensor, i.e. right-handed about +X), so at time ``t`` the
tilted face's normal leans by the wedge angle toward roll angle
``ψ_i(t) = phase_i + 2π·rotor_hz_i·t`` (roll measured from +Y toward +Z; a negative wedge
leans toward ``ψ + π``). At both faces of every prism the beam is refracted with the exact
vector form of Snell's law (:func:`~lidarsim_core.patterns.optics.refract`), air index 1.

The beam leaving the last prism is the emitted ray. Two counter-rotating prisms draw the
familiar rosette: the off-axis angle peaks whenever the two wedges line up, i.e. at the sum of
the rotor frequencies (MID-70: 77.7333 + 121.5667 = 199.3 petal tips per second).

Calibration
-----------
The published MID-70 model (wedges ∓29.7°, n = 1.5095) reproduces the datasheet's 70.4° FOV only
in one of the four classic face arrangements: prism 1 with its wedge on the exit face, prism 2
with its wedge on the entrance face (tilted faces facing each other). Its maximum deflection is
then 35.19°. The MID-40 (18.7481° / 17.9634°, n = 1.51) reaches the datasheet's 19.2° half-FOV
with both wedges on the entrance face (19.16°), and the Avia's three prisms reach 35.2° with all
wedges on the entrance face. The catalogue datasheets record these choices as estimates.
"""

from __future__ import annotations

import math
import threading
from functools import cached_property
from typing import Any, Literal

import numpy as np
from pydantic import Field

from .. import kernels
from ..base.components import ComponentOptions
from ..base.errors import ConfigError, PluginError
from ..hookspecs import hookimpl
from .base import DirectionGroups, RayBatch, cycle_groups, power_of_two_above
from .geometry import directions_from_az_el, off_axis_angle
from .optics import refract, tilted_normal
from .timing import CycleTimedPattern, FiringCycle

_AXIS = np.array([1.0, 0.0, 0.0])
#: Firing cycles per group of :meth:`RisleyPattern.direction_groups`, at most (a MID-70 group
#: spans 0.16 ms; its rays stay within 1.9° of the middle one), halved while a group's angle
#: exceeds :data:`GROUP_ANGLE` (the Avia's six channels: four cycles, 1.2°).
GROUP_CYCLES = 16
#: The angle (rad) above which the groups are made smaller: 2°.
GROUP_ANGLE = math.radians(2.0)
#: Grid steps per prism on which :meth:`RisleyPattern.max_turn_rate` samples the speed, by
#: the number of prisms (~65,000 prism angles per channel).
SPEED_STEPS = {1: 4096, 2: 256, 3: 32, 4: 16}
#: Largest correction for the grid's step, relative to the largest speed sampled, above which
#: the grid is judged too coarse for the prisms and the rays are not grouped.
SPEED_CORRECTION_LIMIT = 0.25
#: :meth:`RisleyPattern.max_turn_rate` by the pattern's options (JSON), for this process.
_TURN_RATES: dict[str, float | None] = {}
_TURN_RATES_LOCK = threading.Lock()


class PrismSpec(ComponentOptions):
    """One rotating wedge prism, in the order the beam meets them."""

    wedge_deg: float = Field(gt=-60, lt=60, description="Wedge angle (deg); the sign turns the "
                                                        "wedge by 180° about the axis.")
    rotor_hz: float = Field(description="Rotation rate (Hz); positive is right-handed about +X.")
    phase_deg: float = Field(0.0, description="Roll angle of the tilted face's normal at t = 0 "
                                              "(deg, from +Y toward +Z).")
    wedge_face: Literal["entrance", "exit"] = Field(
        "exit", description="Which face is tilted; the other is perpendicular to the axis.")
    refractive_index: float | None = Field(
        None, gt=1, le=4, description="This prism's index; default: the pattern's.")


class RisleyChannel(ComponentOptions):
    """One laser channel: the direction of its beam before it enters the prisms."""

    azimuth_deg: float = Field(0.0, ge=-30, le=30, description="Incident azimuth (deg).")
    elevation_deg: float = Field(0.0, ge=-30, le=30, description="Incident elevation (deg).")


class RisleyOptions(ComponentOptions):
    """Options of the Risley-prism pattern."""

    prisms: list[PrismSpec] = Field(min_length=1, max_length=4,
                                    description="The prisms in beam order (usually 2 or 3).")
    refractive_index: float = Field(1.51, gt=1, le=4, description="Index of the prism glass.")
    channels: list[RisleyChannel] = Field(
        default_factory=lambda: [RisleyChannel()], min_length=1, max_length=64,
        description="Laser channels, each with its incident beam; ids are list positions.")
    channel_firing: Literal["interleaved", "simultaneous"] = Field(
        "interleaved", description="'interleaved': channels fire in turn, one ray every "
                                   "1/point_rate; 'simultaneous': all channels fire together "
                                   "every n_channels/point_rate.")


class RisleyPattern(CycleTimedPattern):
    """Rotating wedge prisms (Risley scanner) with exact vector refraction (Livox MID/Avia)."""

    name = "risley"
    Options = RisleyOptions
    options: RisleyOptions

    #: Grid steps per prism used to look for total internal reflection when building.
    _CHECK_STEPS = 24

    def __init__(self, options: Any = None, sensor: Any = None) -> None:
        super().__init__(options, sensor)
        opts = self.options
        self._incident = directions_from_az_el(
            np.radians([c.azimuth_deg for c in opts.channels]),
            np.radians([c.elevation_deg for c in opts.channels]))
        self._index = [p.refractive_index or opts.refractive_index for p in opts.prisms]
        self._check_transmission()

    def build_cycle(self) -> FiringCycle:
        n = len(self.options.channels)
        dt = 1.0 / self.sensor.point_rate_hz
        offsets = np.arange(n) * dt if self.options.channel_firing == "interleaved" \
            else np.zeros(n)
        return FiringCycle(n * dt, offsets, np.arange(n))

    # ---- optics --------------------------------------------------------------------------
    def trace(self, incident: np.ndarray, rolls: np.ndarray) -> np.ndarray:
        """Trace beams through the prism stack.

        Parameters
        ----------
        incident
            (N, 3) unit beam directions before the first prism.
        rolls
            (N, P) roll angle (rad) of each prism's tilted-face normal.

        Returns
        -------
        numpy.ndarray
            (N, 3) unit emitted directions (NaN rows where a beam is totally reflected).
        """
        d = incident
        for i, prism in enumerate(self.options.prisms):
            tilted = tilted_normal(math.radians(prism.wedge_deg), rolls[:, i])
            entrance, exit_ = (tilted, _AXIS) if prism.wedge_face == "entrance" else \
                (_AXIS, tilted)
            n = self._index[i]
            d = refract(d, entrance, 1.0 / n)
            d = refract(d, exit_, n)
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    def prism_rolls(self, t: np.ndarray) -> np.ndarray:
        """(N, P) roll angle (rad) of each prism at times ``t`` (s)."""
        t = np.asarray(t, dtype=np.float64)
        cols = []
        for prism in self.options.prisms:
            turns = np.mod(prism.rotor_hz * t, 1.0)  # keep the phase exact for long scans
            cols.append(2.0 * np.pi * turns + math.radians(prism.phase_deg))
        return np.stack(cols, axis=1)

    def _check_transmission(self) -> None:
        rolls, channel = self._roll_grid(self._CHECK_STEPS)
        out = self.trace(self._incident[channel], rolls)
        if not np.all(np.isfinite(out)):
            raise ConfigError(f"{self.name}: some prism angles totally reflect the beam inside "
                              "a prism; reduce the wedge angles or the refractive index",
                              field="scan_pattern.options.prisms")

    def _roll_grid(self, steps: int) -> tuple[np.ndarray, np.ndarray]:
        """Every combination of prism rolls on a ``steps``-per-turn grid, for every channel."""
        p = len(self.options.prisms)
        axes = [np.linspace(0, 2 * np.pi, steps, endpoint=False)] * p
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, p)
        n_ch = len(self.options.channels)
        return np.tile(grid, (n_ch, 1)), np.repeat(np.arange(n_ch), len(grid))

    # ---- the pattern ---------------------------------------------------------------------
    def rays_for_indices(self, index: np.ndarray) -> RayBatch:
        index = np.asarray(index, dtype=np.int64)
        t, _, channel = self.cycle.rays(index)
        if kernels.enabled():  # the same optics, compiled (kernels.risley)
            from ..kernels.risley import risley_directions

            direction, bad = risley_directions(np.ascontiguousarray(t, dtype=np.float64),
                                               np.ascontiguousarray(channel, dtype=np.int16),
                                               self._incident, *self._kernel_prisms)
        else:
            direction = self.trace(self._incident[channel], self.prism_rolls(t))
            bad = not np.all(np.isfinite(direction))
        if bad:
            raise PluginError(f"{self.name}: a beam was totally reflected inside a prism")
        return RayBatch(index, t, direction, channel)

    @cached_property
    def _kernel_prisms(self) -> tuple[np.ndarray, ...]:
        """The prisms as :func:`lidarsim_core.kernels.risley.risley_directions` takes them:
        wedge sines and cosines, rotor rates (Hz), phases (rad), whether the tilted face is
        the entrance, refractive indices."""
        prisms = self.options.prisms
        wedge = np.radians([p.wedge_deg for p in prisms])
        return (np.sin(wedge), np.cos(wedge),
                np.array([p.rotor_hz for p in prisms], dtype=np.float64),
                np.array([math.radians(p.phase_deg) for p in prisms]),
                np.array([p.wedge_face == "entrance" for p in prisms]),
                np.array(self._index, dtype=np.float64))

    @cached_property
    def _max_off_axis(self) -> float:
        from scipy.optimize import minimize

        steps = 90 if len(self.options.prisms) <= 2 else 40
        rolls, channel = self._roll_grid(steps)
        theta = off_axis_angle(self.trace(self._incident[channel], rolls))
        best = float(np.nanmax(theta))
        # polish the few best grid points: the maximum is smooth, the grid is coarse
        for k in np.argsort(np.nan_to_num(theta, nan=-1.0))[-4:]:
            beam = self._incident[channel[k]][None, :]

            def neg(x: np.ndarray, beam: np.ndarray = beam) -> float:
                value = off_axis_angle(self.trace(beam, x[None, :]))[0]
                return -float(value) if np.isfinite(value) else 0.0

            res = minimize(neg, rolls[k], method="Nelder-Mead",
                           options={"xatol": 1e-7, "fatol": 1e-12, "maxiter": 2000})
            best = max(best, -float(res.fun))
        return best

    def max_off_axis_rad(self) -> float:
        """Largest off-axis angle any channel reaches at any prism angles (rad)."""
        return self._max_off_axis

    @cached_property
    def _turn_rate(self) -> float | None:
        # the options decide the bound: patterns built again for the same sensor (a dataset's
        # sequences, the workers' copies) look it up
        key = self.options.model_dump_json()
        with _TURN_RATES_LOCK:
            if key in _TURN_RATES:
                return _TURN_RATES[key]
        rate = self._sampled_turn_rate()
        with _TURN_RATES_LOCK:
            if len(_TURN_RATES) >= 64:
                _TURN_RATES.clear()
            _TURN_RATES[key] = rate
        return rate

    def _sampled_turn_rate(self) -> float | None:
        prisms = self.options.prisms
        omega = 2.0 * np.pi * np.array([p.rotor_hz for p in prisms])
        if not np.any(omega):
            return 0.0
        steps = SPEED_STEPS[len(prisms)]
        axes = [np.arange(steps) * (2.0 * np.pi / steps)] * len(prisms)
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(prisms))
        tau = 1e-5 / float(np.abs(omega).max())  # a step of at most 10 µrad of any prism
        worst = 0.0
        for incident in self._incident:
            beam = np.broadcast_to(incident, (len(grid), 3))
            ahead = self.trace(beam, grid + omega * tau)
            behind = self.trace(beam, grid - omega * tau)
            speed = np.linalg.norm(ahead - behind, axis=1) / (2.0 * tau)
            if not np.all(np.isfinite(speed)):
                return None
            speed = speed.reshape((steps,) * len(prisms))
            largest = float(speed.max())
            # any prism angles are within half a step of a grid point along each of the P
            # axes, where the speed changes by about half the largest change between
            # neighbours: P · change / 2, doubled
            change = max(float(np.abs(np.roll(speed, -1, axis=k) - speed).max())
                         for k in range(len(prisms)))
            correction = change * len(prisms)
            if correction > SPEED_CORRECTION_LIMIT * largest:
                return None
            worst = max(worst, largest + correction)
        return worst * 1.01  # the chord of the finite difference is shorter than the arc

    def max_turn_rate(self) -> float | None:
        """An upper bound of how fast a ray's direction turns (rad/s), or None where none is
        trusted.

        A beam's direction is a smooth function of the prisms' roll angles, which turn at
        ``ω = 2π · rotor_hz``. The speed ``|d/dt F(ψ + ω t)|`` is sampled on a grid of
        :data:`SPEED_STEPS` roll angles per prism (every channel; central differences of
        :meth:`trace`), and grown by the grid's step: every roll is within half a step of a
        grid point along each of the P axes, where the speed differs by about half the largest
        change between neighbouring grid points; that ``P · change / 2`` is doubled, and the
        whole grown by 1 %. None (no grouping) when the correction exceeds
        :data:`SPEED_CORRECTION_LIMIT` of the speed (a grid too coarse for the prisms, e.g.
        near total internal reflection). Computed once per pattern (0.04–0.07 s for two
        prisms and one channel, 0.2 s for the Avia's three prisms and six channels)."""
        return self._turn_rate

    def direction_groups(self, index: np.ndarray) -> DirectionGroups | None:
        """A group per slot of the firing cycle and block of ``C`` cycles (:data:`GROUP_CYCLES`,
        halved while the angle below exceeds :data:`GROUP_ANGLE`): its rays share a channel
        and are at most ``C // 2`` periods from the middle one (the representative), so
        within ``max_turn_rate · period · C // 2`` of it (an arc on the sphere is no shorter
        than the angle between its ends), grown by the rounding of the roll angles in long
        scans and a nanoradian. None when no bound is trusted or a subclass changes the
        firing schedule."""
        index = np.asarray(index, dtype=np.int64)
        if len(index) == 0 or type(self).build_cycle is not RisleyPattern.build_cycle:
            return None
        rate = self.max_turn_rate()
        if rate is None:
            return None
        # the rolls' mod(rate · t, 1): a few ulp of t, t rounded up to a power of two so that
        # a scan's pieces share a few angles (and the cull its cube maps: one per angle)
        last = power_of_two_above(abs(float(self.time_of_index(index[-1:])[0])))
        rounding = rate * last * 2.0 ** -48
        cycles = GROUP_CYCLES
        while cycles > 2 and rate * self.cycle.period_s * (cycles // 2) > GROUP_ANGLE:
            cycles //= 2
        angle = rate * self.cycle.period_s * (cycles // 2)
        return cycle_groups(index, self.cycle.size, cycles, angle, rounding)


@hookimpl
def lidarsim_register_scan_patterns(register: Any) -> None:
    """Register the Risley-prism pattern."""
    register(RisleyPattern)
