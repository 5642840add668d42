"""Direction conventions of the sensor frame (+X boresight, +Y left, +Z up).

* azimuth: angle from +X toward +Y, in the XY plane (rad);
* elevation: angle above the XY plane toward +Z (rad);
* off-axis angle θ and roll angle φ: polar coordinates about the boresight, φ measured from +Y
  toward +Z (used by circular-FOV scanners such as Livox's).
"""

from __future__ import annotations

import numpy as np


def directions_from_az_el(azimuth: np.ndarray, elevation: np.ndarray) -> np.ndarray:
    """Unit (N, 3) directions from azimuth and elevation (rad)."""
    cos_el = np.cos(elevation)
    return np.stack([cos_el * np.cos(azimuth), cos_el * np.sin(azimuth), np.sin(elevation)],
                    axis=-1)


def az_el_from_directions(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth and elevation (rad) of (N, 3) unit directions."""
    x, y, z = directions[:, 0], directions[:, 1], directions[:, 2]
    return np.arctan2(y, x), np.arctan2(z, np.hypot(x, y))


def directions_from_off_axis(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit (N, 3) directions at off-axis angle ``theta`` and roll ``phi`` about +X (rad)."""
    sin_t = np.sin(theta)
    return np.stack([np.cos(theta), sin_t * np.cos(phi), sin_t * np.sin(phi)], axis=-1)


def off_axis_angle(directions: np.ndarray) -> np.ndarray:
    """Angle (rad) between (N, 3) unit directions and the boresight +X."""
    return np.arctan2(np.hypot(directions[:, 1], directions[:, 2]), directions[:, 0])
