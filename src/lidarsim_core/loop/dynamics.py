"""The chaser's translational state between steps: Hill–Clohessy–Wiltshire motion in the
target's LVLH frame, with an impulse at a step's start or a constant acceleration over it.

Natural motion is the closed form the ``hcw`` trajectory flies
(:func:`lidarsim_core.trajectories.orbit.hcw_propagate`), evaluated for one state
(:func:`hcw_step`). A constant acceleration ``a`` (LVLH, m/s²) held over a step
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
from typing import Any

import numpy as np

from ..trajectories.orbit import hcw_state


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
    motion (:func:`hcw_step`) plus a constant ``acceleration`` (either, both or neither).

    Returns
    -------
    position, velocity
        Two (3,) arrays (m, m/s).
    """
    v0 = [float(v) for v in velocity]
    if delta_v is not None:
        v0 = [v0[i] + float(delta_v[i]) for i in range(3)]
    p, v = hcw_step(position, v0, n, tau)
    if acceleration is not None:
        dp, dv = hcw_forced(np.asarray(acceleration, dtype=np.float64), n, tau)
        return np.array(p) + dp, np.array(v) + dv
    return np.array(p), np.array(v)

def hcw_step(position: Any, velocity: Any, n: float, tau: float
             ) -> tuple[list[float], list[float]]:
    """:func:`~lidarsim_core.trajectories.orbit.hcw_propagate` of one state over one
    interval, in plain floating point (:func:`~lidarsim_core.trajectories.orbit.hcw_state`:
    the same closed form and bits, ~15 times faster for one row)."""
    pos, vel = hcw_state(position, velocity, n, tau)
    return list(pos), list(vel)
