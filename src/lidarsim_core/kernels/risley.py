"""The Risley-prism pattern's directions (:class:`lidarsim_core.patterns.risley.RisleyPattern`)
in numba.

The same vector Snell's law through every face of every prism, in the order of the NumPy code
(:meth:`~lidarsim_core.patterns.risley.RisleyPattern.trace`), with :func:`.trig.sincos` for the
prisms' roll angles: within a few ulp of the NumPy directions, without the (N, 3) temporaries
of the eight vectorised refractions.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .trig import sincos, sincos_reduced


@njit(inline="always", error_model="numpy", cache=True)
def _refract(dx, dy, dz, nx, ny, nz, eta):  # noqa: ANN001, ANN202
    """:func:`lidarsim_core.patterns.optics.refract` for one ray (NaN on total reflection),
    without branches."""
    cos_i = dx * nx + dy * ny + dz * nz
    sign = -1.0 if cos_i < 0 else 1.0
    nx, ny, nz, cos_i = nx * sign, ny * sign, nz * sign, cos_i * sign
    sin2_t = eta * eta * (1.0 - cos_i * cos_i)
    k = np.sqrt(1.0 - sin2_t) - eta * cos_i  # NaN on total internal reflection
    return eta * dx + k * nx, eta * dy + k * ny, eta * dz + k * nz


@njit(nogil=True, error_model="numpy", cache=True)
def risley_directions(t, channel, incident, sin_wedge, cos_wedge, rotor_hz, phase_rad,
                      entrance, index):  # noqa: ANN001, ANN201
    """(N, 3) emitted directions at times ``t`` of ``channel``'s beams (``incident`` (C, 3))
    through prisms with wedge sine/cosine, rotor rates (Hz), phases (rad), whether the tilted
    face is the entrance, and refractive indices (all (P,)). One prism at a time over every
    ray, so that the loops vectorise."""
    n = t.shape[0]
    d = np.empty((3, n))
    for i in range(n):
        c = channel[i]
        d[0, i], d[1, i], d[2, i] = incident[c, 0], incident[c, 1], incident[c, 2]
    for p in range(rotor_hz.shape[0]):
        rate, phase, eta = rotor_hz[p], phase_rad[p], index[p]
        inv_eta = 1.0 / eta
        sw, cw, first = sin_wedge[p], cos_wedge[p], entrance[p]
        small = abs(phase) < 1e5  # roll angles within the branch-free sine's range
        for i in range(n):
            x = rate * t[i]
            turns = x - math.floor(x)  # NumPy's mod(x, 1): the phase stays exact
            roll = 2.0 * np.pi * turns + phase
            if small:
                sin_r, cos_r = sincos_reduced(roll)
            else:
                sin_r, cos_r = sincos(roll)
            tx, ty, tz = cw, sw * cos_r, sw * sin_r
            dx, dy, dz = d[0, i], d[1, i], d[2, i]
            if first:
                dx, dy, dz = _refract(dx, dy, dz, tx, ty, tz, inv_eta)
                dx, dy, dz = _refract(dx, dy, dz, 1.0, 0.0, 0.0, eta)
            else:
                dx, dy, dz = _refract(dx, dy, dz, 1.0, 0.0, 0.0, inv_eta)
                dx, dy, dz = _refract(dx, dy, dz, tx, ty, tz, eta)
            d[0, i], d[1, i], d[2, i] = dx, dy, dz
    out = np.empty((n, 3))
    for i in range(n):
        dx, dy, dz = d[0, i], d[1, i], d[2, i]
        norm = math.sqrt(dx * dx + dy * dy + dz * dz)
        out[i, 0] = dx / norm
        out[i, 1] = dy / norm
        out[i, 2] = dz / norm
    return out
