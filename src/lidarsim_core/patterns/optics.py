"""Exact vector refraction (Snell's law in 3-D) and wedge-prism face normals, vectorised."""

from __future__ import annotations

import numpy as np


def refract(direction: np.ndarray, normal: np.ndarray, eta: float | np.ndarray) -> np.ndarray:
    """Refract unit rays through surfaces with the exact vector form of Snell's law.

    Parameters
    ----------
    direction
        (N, 3) unit propagation directions of the incident rays.
    normal
        (N, 3) or (3,) unit surface normals. Either orientation is accepted; the normal is
        flipped where needed so that it points along the propagation.
    eta
        Ratio ``n_incident / n_transmitted`` of refractive indices (scalar or (N,)).

    Returns
    -------
    numpy.ndarray
        (N, 3) unit transmitted directions; rows are NaN where the ray is totally internally
        reflected (``eta · sin θ_i > 1``).

    Notes
    -----
    With ``n`` oriented along the propagation and ``cos θ_i = d·n``, the transmitted direction
    is ``t = η d + (cos θ_t − η cos θ_i) n`` with ``cos θ_t = sqrt(1 − η² (1 − cos² θ_i))``.
    It satisfies ``n_i sin θ_i = n_t sin θ_t`` and lies in the plane of incidence.
    """
    d = np.asarray(direction, dtype=np.float64)
    n = np.broadcast_to(np.asarray(normal, dtype=np.float64), d.shape)
    cos_i = np.einsum("ij,ij->i", d, n)
    sign = np.where(cos_i < 0, -1.0, 1.0)
    n = n * sign[:, None]
    cos_i = cos_i * sign
    eta = np.asarray(eta, dtype=np.float64)
    sin2_t = eta**2 * (1.0 - cos_i**2)
    with np.errstate(invalid="ignore"):
        cos_t = np.sqrt(1.0 - sin2_t)  # NaN on total internal reflection
    eta_col = eta[:, None] if eta.ndim else eta
    return eta_col * d + (cos_t - eta * cos_i)[:, None] * n


def tilted_normal(tilt_rad: float, roll_rad: np.ndarray) -> np.ndarray:
    """Unit normals tilted from +X by ``tilt_rad`` toward roll angle ``roll_rad`` about +X.

    The roll angle is measured from +Y toward +Z (the sensor frame's convention for polar
    angles about the boresight). A negative tilt leans the normal toward ``roll + π``.

    Returns
    -------
    numpy.ndarray
        (N, 3) unit normals ``(cos t, sin t cos ψ, sin t sin ψ)``.
    """
    roll = np.asarray(roll_rad, dtype=np.float64)
    s = np.sin(tilt_rad)
    return np.stack([np.full(roll.shape, np.cos(tilt_rad)), s * np.cos(roll), s * np.sin(roll)],
                    axis=-1)
