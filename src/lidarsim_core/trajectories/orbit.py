"""The target-centred orbital frame (LVLH), circular-orbit mean motion and the HCW solution.

LVLH axes (Hill / RSW / "RIC" convention)
-----------------------------------------
The scene frame of a rendezvous scenario is the target's local-vertical/local-horizontal frame,
origin at the target's centre of mass, on a circular orbit:

* ``+x`` **R-bar**: radial, from the Earth's centre through the target, positive *away from*
  the Earth (zenith). A chaser at ``x < 0`` is below the target.
* ``+y`` **V-bar**: along-track, positive in the direction of the target's orbital velocity.
  A chaser at ``y > 0`` is ahead of the target, at ``y < 0`` behind it.
* ``+z`` **H-bar**: orbit normal, positive along the orbital angular momentum (``x × y``).

This frame rotates with respect to inertial space at the mean motion ``n`` about ``+z``.
The ISS/CCSDS "LVLH" frame (``z`` to nadir, ``x`` roughly along V-bar, ``y = -H``) is a
relabelling of it: ``x_ccsds = y``, ``y_ccsds = -z``, ``z_ccsds = -x``.

Hill–Clohessy–Wiltshire equations (circular target orbit, chaser close to the target)::

    x'' = 3 n² x + 2 n y'        y'' = -2 n x'        z'' = -n² z
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import ConfigDict, Field, model_validator
from scipy.spatial.transform import Rotation

from ..base.components import ComponentOptions

#: Earth's gravitational parameter GM (m³/s², IERS/WGS-84 value).
MU_EARTH_M3_S2 = 3.986004418e14
#: Earth's equatorial radius (m, WGS-84); altitudes are measured from it.
R_EARTH_M = 6_378_137.0


def mean_motion_from_altitude(altitude_km: float) -> float:
    """Mean motion ``n = sqrt(μ / a³)`` (rad/s) of a circular orbit at ``altitude_km``."""
    a = R_EARTH_M + 1000.0 * altitude_km
    return math.sqrt(MU_EARTH_M3_S2 / a ** 3)


class OrbitConfig(ComponentOptions):
    """The target's circular orbit, given by exactly one of altitude, mean motion or period."""

    model_config = ConfigDict(allow_inf_nan=False)

    altitude_km: float | None = Field(
        None, gt=0, description="Altitude above the Earth's equatorial radius (km).")
    mean_motion_rad_s: float | None = Field(
        None, gt=0, description="Mean motion n (rad/s).")
    period_s: float | None = Field(None, gt=0, description="Orbital period 2π/n (s).")

    @model_validator(mode="after")
    def _exactly_one(self) -> "OrbitConfig":
        given = [k for k in ("altitude_km", "mean_motion_rad_s", "period_s")
                 if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of altitude_km, mean_motion_rad_s or period_s"
                             + (f" (got {', '.join(given)})" if given else ""))
        return self

    @property
    def mean_motion(self) -> float:
        """Mean motion ``n`` (rad/s)."""
        if self.mean_motion_rad_s is not None:
            return self.mean_motion_rad_s
        if self.period_s is not None:
            return 2.0 * math.pi / self.period_s
        return mean_motion_from_altitude(self.altitude_km)

    @property
    def period(self) -> float:
        """Orbital period (s)."""
        return 2.0 * math.pi / self.mean_motion


def _position_terms(x0, y0, z0, vx, vy, vz, n, nt, c, s):  # noqa: ANN001, ANN202
    # the closed form's positions, for floats or arrays alike (the same operations, in the
    # same order, on each element)
    return ((4.0 - 3.0 * c) * x0 + s / n * vx + 2.0 / n * (1.0 - c) * vy,
            6.0 * (s - nt) * x0 + y0 - 2.0 / n * (1.0 - c) * vx + (4.0 * s - 3.0 * nt) / n * vy,
            c * z0 + s / n * vz)


def _velocity_terms(x0, z0, vx, vy, vz, n, c, s):  # noqa: ANN001, ANN202
    return (3.0 * n * s * x0 + c * vx + 2.0 * s * vy,
            6.0 * n * (c - 1.0) * x0 - 2.0 * s * vx + (4.0 * c - 3.0) * vy,
            -n * s * z0 + c * vz)


def _components(state: np.ndarray, rows: int) -> tuple[np.ndarray | float, ...]:
    """The three components of a (3,) state as floats (each combines with every row as the
    broadcast array would), or of an (N, 3) one as columns."""
    state = np.asarray(state, dtype=np.float64)
    if state.shape == (3,):
        return tuple(state.tolist())
    return tuple(np.broadcast_to(state, (rows, 3)).T)


def _hcw_positions(position: np.ndarray, velocity: np.ndarray, n: float, tau: np.ndarray
                   ) -> tuple[np.ndarray, tuple]:
    x0, y0, z0 = _components(position, len(tau))
    vx, vy, vz = _components(velocity, len(tau))
    nt = n * tau
    c, s = np.cos(nt), np.sin(nt)
    pos = np.empty((len(tau), 3))
    pos[:, 0], pos[:, 1], pos[:, 2] = _position_terms(x0, y0, z0, vx, vy, vz, n, nt, c, s)
    return pos, (x0, z0, vx, vy, vz, c, s)


def hcw_positions(position: np.ndarray, velocity: np.ndarray, n: float,
                  tau: np.ndarray) -> np.ndarray:
    """The positions of :func:`hcw_propagate` alone (the same arithmetic, the same bits)."""
    tau = np.atleast_1d(np.asarray(tau, dtype=np.float64))
    return _hcw_positions(position, velocity, n, tau)[0]


def hcw_state(position: np.ndarray, velocity: np.ndarray, n: float, tau: float
              ) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """:func:`hcw_propagate` of one (3,) state over one interval ``tau`` (s), in plain floats:
    the same operations with NumPy's own sine and cosine, so the same bits as a row of the
    arrays (``tests/test_trajectories_hcw.py``), in ~1.4 µs instead of ~22 for a one-row
    :func:`hcw_propagate`: the poses and rate bounds of one time that culling asks for per
    piece, and the control loop's steps."""
    x0, y0, z0 = np.asarray(position, dtype=np.float64).reshape(3).tolist()
    vx, vy, vz = np.asarray(velocity, dtype=np.float64).reshape(3).tolist()
    nt = n * float(tau)
    c, s = float(np.cos(nt)), float(np.sin(nt))
    return (_position_terms(x0, y0, z0, vx, vy, vz, n, nt, c, s),
            _velocity_terms(x0, z0, vx, vy, vz, n, c, s))


def hcw_propagate(position: np.ndarray, velocity: np.ndarray, n: float,
                  tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form HCW natural motion, vectorised.

    Parameters
    ----------
    position, velocity
        (3,) or (N, 3) LVLH state at ``tau = 0`` (m, m/s).
    n
        Mean motion (rad/s).
    tau
        (N,) time since that state (s); negative values propagate backwards.

    Returns
    -------
    position, velocity
        (N, 3) LVLH state at each ``tau``.
    """
    tau = np.atleast_1d(np.asarray(tau, dtype=np.float64))
    pos, (x0, z0, vx, vy, vz, c, s) = _hcw_positions(position, velocity, n, tau)
    vel = np.empty((len(tau), 3))
    vel[:, 0], vel[:, 1], vel[:, 2] = _velocity_terms(x0, z0, vx, vy, vz, n, c, s)
    return pos, vel


def lvlh_from_inertial(n: float, tau: np.ndarray) -> Rotation:
    """Rotations taking inertial components to LVLH components, ``tau`` s after the frames
    coincided (the LVLH frame turns at ``+n`` about ``+z`` relative to inertial space)."""
    tau = np.atleast_1d(np.asarray(tau, dtype=np.float64))
    return Rotation.from_rotvec(np.outer(-n * tau, [0.0, 0.0, 1.0]))
