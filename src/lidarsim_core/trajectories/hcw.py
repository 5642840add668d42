"""Built-in plugin: chaser motion relative to the target from the HCW equations (``kind: hcw``).

The scene frame is the target's LVLH frame (see :mod:`.orbit`: +x R-bar away from the Earth,
+y V-bar along the orbital velocity, +z H-bar along the orbital angular momentum), origin at
the target's centre of mass, on a circular orbit given by ``orbit``. The chaser starts from
``position_m`` / ``velocity_m_s`` at ``t_ref_s`` and then flies ``segments`` in order:

``coast``
    Natural (unforced) HCW motion for ``duration_s``, after an optional impulse
    ``delta_v_m_s`` at its start.
``hold``
    Forced station keeping at the current position for ``duration_s``, at rest. (On V-bar a
    hold is a natural equilibrium; elsewhere, e.g. on R-bar, it needs thrust.)
``straight``
    Forced straight-line motion at constant velocity to ``to_m`` (a V-bar or R-bar approach
    when ``to_m`` lies on that axis), taking ``duration_s`` or moving at ``speed_m_s``;
    the chaser arrives at rest.
``fly_around``
    An impulse onto the natural-motion ellipse centred on the target through the current
    position (``vx = n·y/2``, ``vy = -2n·x``), then natural motion for ``orbits`` target
    orbits or ``duration_s``. In the orbit plane this is the 2:1 ellipse (along-track
    semi-axis twice the radial one); with ``out_of_plane: true`` the cross-track motion
    ``z = √3·x`` is added, which makes the range constant: a circular fly-around of radius
    ``sqrt(4x² + y²)`` in a plane tilted 60° from the orbit plane (start it where
    ``z = √3·x``, e.g. on V-bar). The sense of travel is fixed by orbital mechanics: from
    ahead of the target (+V-bar) the chaser rises to +R-bar, then passes behind it.

Before ``t_ref_s`` and after the last segment the chaser moves naturally. The attitude
follows ``attitude`` (default: boresight +X at the target's centre, sensor +Z toward +H-bar).

YAML (V-bar approach from 250 m to 20 m; ``altitude_km`` or ``mean_motion_rad_s``)::

    trajectory:
      kind: hcw
      orbit: {altitude_km: 780}
      position_m: [0, 250, 0]
      segments:
        - {type: straight, to_m: [0, 100, 0], speed_m_s: 0.5}
        - {type: hold, duration_s: 60}
        - {type: straight, to_m: [0, 20, 0], speed_m_s: 0.2}
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Annotated, Any, Literal, Mapping, Union

import numpy as np
from pydantic import ConfigDict, Field, model_validator

from ..base.components import ComponentOptions
from ..base.errors import ConfigError
from ..base.validation import validate_model
from ..geometry.poses import Poses
from ..geometry.posing import PoseMatrices
from ..hookspecs import hookimpl
from .attitude import AttitudeConfig, LookAtAttitude
from .base import Trajectory
from .orbit import OrbitConfig, hcw_positions, hcw_propagate, hcw_state

Vec3 = tuple[float, float, float]
_ZERO3: Vec3 = (0.0, 0.0, 0.0)


class _Segment(ComponentOptions):
    model_config = ConfigDict(allow_inf_nan=False)


class CoastSegment(_Segment):
    """Natural motion, after an optional impulse."""

    type: Literal["coast"]
    duration_s: float = Field(gt=0, description="Length of the coast (s).")
    delta_v_m_s: Vec3 = Field(_ZERO3, description="Impulse at the start, LVLH (m/s).")


class HoldSegment(_Segment):
    """Forced hold at the current position, at rest."""

    type: Literal["hold"]
    duration_s: float = Field(gt=0, description="Length of the hold (s).")


class StraightSegment(_Segment):
    """Forced straight line at constant velocity to a point, arriving at rest."""

    type: Literal["straight"]
    to_m: Vec3 = Field(description="End point, LVLH (m).")
    duration_s: float | None = Field(None, gt=0, description="Time taken (s).")
    speed_m_s: float | None = Field(None, gt=0, description="Constant speed (m/s).")

    @model_validator(mode="after")
    def _one_timing(self) -> "StraightSegment":
        if (self.duration_s is None) == (self.speed_m_s is None):
            raise ValueError("give exactly one of duration_s or speed_m_s")
        return self


class FlyAroundSegment(_Segment):
    """Impulse onto the centred natural-motion ellipse, then natural motion."""

    type: Literal["fly_around"]
    orbits: float | None = Field(None, gt=0, description="Length in target orbits.")
    duration_s: float | None = Field(None, gt=0, description="Length (s).")
    out_of_plane: bool = Field(False, description="Add z = √3·x: constant-range circle.")

    @model_validator(mode="after")
    def _one_length(self) -> "FlyAroundSegment":
        if (self.orbits is None) == (self.duration_s is None):
            raise ValueError("give exactly one of orbits or duration_s")
        return self


Segment = Annotated[Union[CoastSegment, HoldSegment, StraightSegment, FlyAroundSegment],
                    Field(discriminator="type")]


class HCWOptions(ComponentOptions):
    """Initial LVLH state, orbit and manoeuvre segments of an HCW trajectory."""

    model_config = ConfigDict(allow_inf_nan=False)

    orbit: OrbitConfig = Field(description="The target's circular orbit.")
    position_m: Vec3 = Field(description="Chaser position at t_ref_s, LVLH (m).")
    velocity_m_s: Vec3 = Field(_ZERO3, description="Chaser velocity at t_ref_s, LVLH (m/s).")
    t_ref_s: float = Field(0.0, description="Time of the initial state (s from the epoch).")
    segments: list[Segment] = Field(default_factory=list,
                                    description="Manoeuvres flown in order from t_ref_s.")
    attitude: AttitudeConfig = Field(default_factory=LookAtAttitude,
                                     description="Attitude law (default: look at the origin).")


@dataclass(frozen=True)
class _Piece:
    """A span of the trajectory: natural motion, a hold, or a straight line."""

    t0: float
    t1: float
    kind: str  # "natural" | "hold" | "straight"
    p0: np.ndarray
    v0: np.ndarray


class HCWTrajectory(Trajectory):
    """Relative orbital motion of a chaser about the target (Hill–Clohessy–Wiltshire).

    Attributes
    ----------
    impulses
        ``(t_s, delta_v_m_s)`` of every velocity change the segments imply (forced segments'
        starts and stops, coast impulses, fly-around insertions).
    """

    name = "hcw"
    Options = HCWOptions
    options: HCWOptions

    def __init__(self, options: HCWOptions | None = None, *, source: str | None = None,
                 field: str = "options") -> None:
        super().__init__(options)
        self.n = self.options.orbit.mean_motion
        self.impulses: list[tuple[float, np.ndarray]] = []
        self._pieces = self._plan(source, field)
        self._starts = np.array([p.t0 for p in self._pieces])
        self._start_list = [float(p.t0) for p in self._pieces]  # for one time (bisect)

    @classmethod
    def from_config(cls, options: Mapping[str, Any] | None, *, source: str | None = None,
                    field: str = "options") -> "HCWTrajectory":
        """Validate ``options`` and plan the segments (errors name ``source`` and the field)."""
        opts = validate_model(cls.Options, dict(options or {}), source=source, prefix=field)
        return cls(opts, source=source, field=field)

    def _kick(self, t: float, v_before: np.ndarray, v_after: np.ndarray) -> None:
        dv = v_after - v_before
        if np.linalg.norm(dv) > 0:
            self.impulses.append((t, dv))

    def _plan(self, source: str | None, field: str) -> list[_Piece]:
        opts, n = self.options, self.n
        t = opts.t_ref_s
        p = np.asarray(opts.position_m, dtype=np.float64)
        v = np.asarray(opts.velocity_m_s, dtype=np.float64)
        pieces = [_Piece(-math.inf, t, "natural", p, v)]
        for i, seg in enumerate(opts.segments):
            if isinstance(seg, CoastSegment):
                v_new = v + np.asarray(seg.delta_v_m_s)
                self._kick(t, v, v_new)
                pieces.append(_Piece(t, t + seg.duration_s, "natural", p, v_new))
                p, v = (a[0] for a in hcw_propagate(p, v_new, n, np.array([seg.duration_s])))
                t += seg.duration_s
            elif isinstance(seg, HoldSegment):
                self._kick(t, v, np.zeros(3))
                pieces.append(_Piece(t, t + seg.duration_s, "hold", p, np.zeros(3)))
                v = np.zeros(3)
                t += seg.duration_s
            elif isinstance(seg, StraightSegment):
                to = np.asarray(seg.to_m, dtype=np.float64)
                length = float(np.linalg.norm(to - p))
                duration = seg.duration_s if seg.duration_s is not None else \
                    length / seg.speed_m_s
                if duration <= 0:
                    raise ConfigError("the straight segment starts at its end point 'to_m'",
                                      source=source, field=f"{field}.segments.{i}.to_m")
                v_line = (to - p) / duration
                self._kick(t, v, v_line)
                pieces.append(_Piece(t, t + duration, "straight", p, v_line))
                self._kick(t + duration, v_line, np.zeros(3))
                p, v = to, np.zeros(3)
                t += duration
            else:
                if seg.out_of_plane and not math.isclose(p[2], math.sqrt(3.0) * p[0],
                                                         rel_tol=1e-9, abs_tol=1e-6):
                    raise ConfigError(
                        f"an out-of-plane (circular) fly-around must start where z = √3·x; it "
                        f"starts at x = {p[0]:g} m, z = {p[2]:g} m (start it on V-bar, or set "
                        "out_of_plane: false)", source=source, field=f"{field}.segments.{i}")
                vx = n * p[1] / 2.0
                vz = math.sqrt(3.0) * vx if seg.out_of_plane else 0.0
                v_new = np.array([vx, -2.0 * n * p[0], vz])
                self._kick(t, v, v_new)
                duration = seg.duration_s if seg.duration_s is not None else \
                    seg.orbits * 2.0 * math.pi / n
                pieces.append(_Piece(t, t + duration, "natural", p, v_new))
                p, v = (a[0] for a in hcw_propagate(p, v_new, n, np.array([duration])))
                t += duration
        pieces.append(_Piece(t, math.inf, "natural", p, v))
        return pieces

    def states_at(self, t: np.ndarray, *, velocities: bool = True
                  ) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) LVLH positions (m) and velocities (m/s) at times ``t`` (s from the epoch);
        without ``velocities`` the second array is left unset (the poses need none)."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        if len(t) == 1:  # one time (culling asks per piece): plain floats, the same bits
            return self._state_at(float(t[0]), velocities)
        # the first piece starts at -inf; a time on a boundary belongs to the later piece
        which = np.searchsorted(self._starts, t, side="right") - 1
        pos = np.empty((len(t), 3))
        vel = np.empty((len(t), 3))
        one = len(t) > 0 and which[0] == which[-1] and bool((which == which[0]).all())
        for k in (which[:1] if one else np.unique(which)):
            piece = self._pieces[k]
            sel = slice(None) if one else which == k  # usually every time in one piece
            anchor = piece.t1 if piece.t0 == -math.inf else piece.t0
            tau = t[sel] - anchor
            if piece.kind == "natural" and not velocities:
                pos[sel] = hcw_positions(piece.p0, piece.v0, self.n, tau)
            elif piece.kind == "natural":
                pos[sel], vel[sel] = hcw_propagate(piece.p0, piece.v0, self.n, tau)
            elif piece.kind == "hold":  # p0 + τ·0 is p0, bit for bit
                pos[sel], vel[sel] = piece.p0, 0.0
            else:
                pos[sel] = piece.p0 + tau[:, None] * piece.v0
                vel[sel] = piece.v0
        return pos, vel

    def _state_at(self, t: float, velocities: bool) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`states_at` of one time: the same piece (``bisect_right`` is
        ``searchsorted(side="right")``) and operations (:func:`.orbit.hcw_state`)."""
        piece = self._pieces[bisect.bisect_right(self._start_list, t) - 1]
        tau = t - (piece.t1 if piece.t0 == -math.inf else piece.t0)
        vel = np.empty((1, 3))
        if piece.kind == "natural":
            position, velocity = hcw_state(piece.p0, piece.v0, self.n, tau)
            if velocities:
                vel[0] = velocity
            return np.array([position]), vel
        if piece.kind == "hold":
            vel[0] = 0.0
            return piece.p0[None, :].astype(np.float64), vel
        vel[0] = piece.v0
        return (piece.p0 + tau * piece.v0)[None, :], vel

    def motion_rates(self, t0: float, t1: float) -> tuple[float, float] | None:
        """The largest speed of the pieces flown in ``[t0, t1]`` (a natural piece's velocity
        components are ``a sin nτ + b cos nτ + c``: at most ``√(a² + b²) + |c|`` each), and
        the attitude law's bound on its turn (:meth:`.LookAtAttitude.rate_bound`)."""
        n = self.n
        first, last = (bisect.bisect_right(self._start_list, t) - 1 for t in (t0, t1))
        speed = 0.0
        for piece in self._pieces[first:last + 1]:
            if piece.kind == "straight":
                speed = max(speed, float(np.linalg.norm(piece.v0)))
            elif piece.kind == "natural":
                x0, z0 = piece.p0[0], piece.p0[2]
                vx, vy, vz = piece.v0
                bound = (math.hypot(3.0 * n * x0 + 2.0 * vy, vx),
                         math.hypot(6.0 * n * x0 + 4.0 * vy, 2.0 * vx)
                         + abs(6.0 * n * x0 + 3.0 * vy),
                         math.hypot(n * z0, vz))
                speed = max(speed, math.sqrt(sum(b * b for b in bound)))
        speed *= 1.0 + 1e-9  # the rounding of the bound itself
        if speed == 0.0:
            return 0.0, 0.0
        middle = 0.5 * (t0 + t1)
        position, _ = self.states_at(np.array([middle]), velocities=False)
        turn = self.options.attitude.rate_bound(position[0], speed, max(middle - t0, t1 - middle))
        return None if turn is None else (turn, speed)

    @property
    def end_time_s(self) -> float:
        """When the last segment ends (s from the epoch)."""
        return self._pieces[-1].t0

    def poses_at(self, t: np.ndarray) -> Poses:
        position, _ = self.states_at(t)
        return Poses(position, self.options.attitude.rotations(position))

    def pose_matrices(self, t: np.ndarray) -> PoseMatrices:
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        if len(t) > 1:
            which = np.searchsorted(self._starts, [t.min(), t.max()], side="right") - 1
            if which[0] == which[-1] and self._pieces[which[0]].kind == "hold":
                # every time in one hold: one pose, shared by every ray (the same bits)
                position = self._pieces[which[0]].p0[None, :].astype(np.float64)
                return PoseMatrices(position, self.options.attitude.matrices(position))
        position, _ = self.states_at(t, velocities=False)
        return PoseMatrices(position, self.options.attitude.matrices(position))


@hookimpl
def lidarsim_register_trajectories(register: Any) -> None:
    """Register the HCW relative-motion trajectory."""
    register(HCWTrajectory)
