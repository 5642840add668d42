"""The seed paper's angular error (:class:`lidarsim_core.noise.gaussian.AngularError`) in numba.

Each ray is turned by ``a1`` about ``u`` and then by ``a2`` about ``v`` (``d, u, v`` a
right-handed orthonormal basis from :func:`lidarsim_core.noise.base.perpendicular_basis`).
The arithmetic is the NumPy code's, operation for operation, with the C library's sine and
cosine (which NumPy also calls for float64), so the two give the same bits.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(inline="always", cache=True)
def turn_ray(x, y, z, a1, a2):  # noqa: ANN001, ANN201
    """One direction turned by ``a1`` about u, then ``a2`` about v (the fast path's loops call
    it per ray, :func:`rotate_two_angles` over arrays)."""
    return turn_ray_with(x, y, z, math.cos(a1), math.sin(a1), math.cos(a2), math.sin(a2))


@njit(inline="always", cache=True)
def turn_ray_with(x, y, z, c1, s1, c2, s2):  # noqa: ANN001, ANN201
    """:func:`turn_ray` with the cosines and sines of ``a1`` and ``a2`` given (a loop that
    computes them first for a block of rays lets the C library's calls overlap)."""
    if abs(z) > 0.9:  # helper +Y near the vertical, else +Z
        ux, uy, uz = z, 0.0, -x
    else:
        ux, uy, uz = -y, x, 0.0
    norm = math.sqrt(ux * ux + uy * uy + uz * uz)
    ux /= norm
    uy /= norm
    uz /= norm
    vx, vy, vz = y * uz - z * uy, z * ux - x * uz, x * uy - y * ux
    cc, cs = c1 * c2, c1 * s2
    return (cc * x + cs * ux - s1 * vx, cc * y + cs * uy - s1 * vy, cc * z + cs * uz - s1 * vz)


@njit(nogil=True, cache=True)
def rotate_two_angles(directions, angles):  # noqa: ANN001, ANN201
    """(N, 3) directions turned by ``angles[:, 0]`` about u, then ``angles[:, 1]`` about v."""
    n = directions.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        out[i, 0], out[i, 1], out[i, 2] = turn_ray(directions[i, 0], directions[i, 1],
                                                   directions[i, 2], angles[i, 0], angles[i, 1])
    return out
