"""The chaser's attitude at a step's end, from the attitude law of its trajectory.

A step needs one rotation; SciPy's rotation objects and the vectorised laws of
:mod:`lidarsim_core.trajectories.attitude` cost ~0.2 ms for a single row, a tenth of a short
frame's simulation. The laws are evaluated here for that one row in plain floating point:
``look_at`` (the same construction as :func:`~lidarsim_core.trajectories.attitude.look_at_matrices`,
its degenerate cases included) and ``fixed``; the rotation matrix becomes a quaternion by
Shepperd's method. The recorded keyframe holds this quaternion, so the replay flies the very
rotation the loop flew, whatever rounding made it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..trajectories.attitude import FixedAttitude, LookAtAttitude


def _unit(v: list[float]) -> list[float] | None:
    norm = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return None if norm < 1e-300 else [v[0] / norm, v[1] / norm, v[2] / norm]


def look_at_columns(position: Any, point: Any, up: Any) -> tuple[list[float], ...]:
    """Columns (boresight, left, up) of the look-at rotation for one position."""
    x = [float(point[i]) - float(position[i]) for i in range(3)]
    norm = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
    x = [1.0, 0.0, 0.0] if norm < 1e-12 else [x[0] / norm, x[1] / norm, x[2] / norm]
    u = _unit([float(v) for v in up]) or [0.0, 0.0, 1.0]
    d = u[0] * x[0] + u[1] * x[1] + u[2] * x[2]
    z = [u[i] - d * x[i] for i in range(3)]
    if math.sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2]) < 1e-9:
        axis = min(range(3), key=lambda i: abs(x[i]))  # least aligned with the boresight
        alt = [1.0 if i == axis else 0.0 for i in range(3)]
        z = [alt[i] - x[axis] * x[i] for i in range(3)]
    z = _unit(z) or [0.0, 0.0, 1.0]
    y = [z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]]
    return x, y, z


def quaternion_from_columns(x: list[float], y: list[float], z: list[float]) -> np.ndarray:
    """Scalar-last unit quaternion of the rotation matrix with columns ``x, y, z``
    (Shepperd's method: the largest of the four squared components first)."""
    m00, m01, m02 = x[0], y[0], z[0]
    m10, m11, m12 = x[1], y[1], z[1]
    m20, m21, m22 = x[2], y[2], z[2]
    trace = m00 + m11 + m22
    if trace >= max(m00, m11, m22):
        s = 2.0 * math.sqrt(1.0 + trace)
        q = (( m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, 0.25 * s)
    elif m00 >= m11 and m00 >= m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        q = (0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s)
    elif m11 >= m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        q = ((m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        q = ((m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s)
    return np.array(q)


class Pointing:
    """The attitude law of a steered chaser, evaluated one position at a time.

    Parameters
    ----------
    attitude
        A ``look_at`` or ``fixed`` attitude law (any other law with a ``rotations`` method
        is evaluated through it).
    """

    def __init__(self, attitude: Any) -> None:
        self.attitude = attitude
        self._fixed = attitude.rotation().as_quat() if isinstance(attitude, FixedAttitude) \
            else None

    def quaternion(self, position: np.ndarray) -> np.ndarray:
        """(4,) scalar-last body → scene quaternion at ``position``."""
        law = self.attitude
        if self._fixed is not None:
            return self._fixed.copy()
        if isinstance(law, LookAtAttitude):
            return quaternion_from_columns(*look_at_columns(position, law.point_m, law.up))
        return law.rotations(np.asarray(position, dtype=np.float64)[None, :]).as_quat()[0]
