"""The chaser's translational state between steps: Hill–Clohessy–Wiltshire motion in the
target's LVLH frame, with an impulse at a step's start or a constant acceleration over it.

Natural motion is :func:`lidarsim_core.trajectories.orbit.hcw_propagate`, the closed form
the ``hcw`` trajectory flies. A constant acceleration ``a`` (LVLH, m/s²) held over a step
adds the forced solution of

    x'' = 3 n² x + 2 n y' + a_x      y'' = -2 n x' + a_y      z'' = -n² z + a_z

from rest at the origin (``c = 1 - cos nτ`` is computed as ``2 sin²(nτ/2)``)::

    x = a_x c / n² + 2 a_y (nτ - sin nτ) / n²
    y = 2 a_x (sin nτ - nτ) / n² + a_y (4 c - 1.5 n²τ²) / n²
    z = a_z c / n²

added to the natural motion of the initial state (the equations are linear).
"""

from __future__ import annotations

import math

import numpy as np

from ..trajectories.orbit import hcw_propagate


def hcw_forced(acceleration: np.ndarray, n: float, tau: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity after ``tau`` s of constant LVLH ``acceleration`` from rest at
    the origin (the forced part of the HCW solution, see the module docstring).

    Parameters
    ----------
    acceleration
        (3,) constant acceleration in LVLH (m/s²).
    n
        Mean motion of the target's circular orbit (rad/s).
    tau
        Duration (s).

    Returns
    -------
    position, velocity
        Two (3,) arrays (m, m/s).
    """
    ax, ay, az = (float(v) for v in acceleration)
    nt = n * tau
    s = math.sin(nt)
    c = 2.0 * math.sin(0.5 * nt) ** 2  # 1 - cos nτ without cancellation
    n2 = n * n
    position = np.array([
        ax * c / n2 + 2.0 * ay * (nt - s) / n2,
        2.0 * ax * (s - nt) / n2 + ay * (4.0 * c - 1.5 * nt * nt) / n2,
        az * c / n2,
    ])
    velocity = np.array([
        ax * s / n + 2.0 * ay * c / n,
        -2.0 * ax * c / n + 4.0 * ay * s / n - 3.0 * ay * tau,
        az * s / n,
    ])
    return position, velocity


def propagate(position: np.ndarray, velocity: np.ndarray, n: float, tau: float, *,
              delta_v: np.ndarray | None = None, acceleration: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
    """The LVLH state ``tau`` s on: an impulse ``delta_v`` at the start, then natural HCW
    motion plus a constant ``acceleration`` (either, both or neither).

    Returns
    -------
    position, velocity
        Two (3,) arrays (m, m/s).
    """
    v0 = np.asarray(velocity, dtype=np.float64)
    if delta_v is not None:
        v0 = v0 + np.asarray(delta_v, dtype=np.float64)
    pos, vel = hcw_propagate(np.asarray(position, dtype=np.float64), v0, n,
                             np.array([tau], dtype=np.float64))
    p, v = pos[0], vel[0]
    if acceleration is not None:
        dp, dv = hcw_forced(np.asarray(acceleration, dtype=np.float64), n, tau)
        p, v = p + dp, v + dv
    return p, v
