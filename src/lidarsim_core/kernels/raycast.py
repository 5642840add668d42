"""The float64 arithmetic around an Embree ray cast, in numba (see
:mod:`lidarsim_core.backends.embree_backend` for why it is done).

Before the cast, each ray's origin is moved along the ray to just before the mesh's bounding
sphere and expressed relative to the sphere's centre, and both vectors go to float32. After
it, the distance to the plane of the face Embree found is recomputed in float64. Same
operations, same order as the NumPy code (:func:`lidarsim_core.backends.base.refine_on_faces`).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def embree_rays(origins, directions, centre, radius, epsilon):  # noqa: ANN001, ANN201
    """float32 (N, 3) origins relative to ``centre`` (moved to just before the bounding
    sphere of ``radius``, never before ``epsilon`` along the ray) and float32 directions."""
    n = origins.shape[0]
    o32 = np.empty((n, 3), dtype=np.float32)
    d32 = np.empty((n, 3), dtype=np.float32)
    for i in range(n):
        rx = origins[i, 0] + -centre[0]
        ry = origins[i, 1] + -centre[1]
        rz = origins[i, 2] + -centre[2]
        dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
        shift = max(-(rx * dx + ry * dy + rz * dz) - radius, epsilon)
        o32[i, 0] = rx + dx * shift
        o32[i, 1] = ry + dy * shift
        o32[i, 2] = rz + dz * shift
        d32[i, 0] = dx
        d32[i, 1] = dy
        d32[i, 2] = dz
    return o32, d32


@njit(nogil=True, cache=True)
def plane_distance(f, ox, oy, oz, dx, dy, dz, first_vertex, normals):  # noqa: ANN001, ANN201
    """The float64 distance along the ray ``(o, d)`` to the plane of face ``f`` (through its
    first vertex, with its unit normal): the one refinement every Embree path shares."""
    nx, ny, nz = normals[f, 0], normals[f, 1], normals[f, 2]
    denom = dx * nx + dy * ny + dz * nz
    vx = first_vertex[f, 0] - ox
    vy = first_vertex[f, 1] - oy
    vz = first_vertex[f, 2] - oz
    return (vx * nx + vy * ny + vz * nz) / denom


@njit(nogil=True, cache=True)
def refine_row(f, row, origins, directions, epsilon, first_vertex, normals, face_out,
               distance_out, normal_out):  # noqa: ANN001, ANN201
    """Write ray ``row``: face ``f`` that Embree found (negative: a miss), the float64
    distance to its plane and its normal; a miss (or a refined distance at or below
    ``epsilon``, a grazing float32 artefact) leaves face -1 and NaN."""
    face_out[row] = -1
    distance_out[row] = np.nan
    normal_out[row, 0] = np.nan
    normal_out[row, 1] = np.nan
    normal_out[row, 2] = np.nan
    if f < 0:
        return
    distance = plane_distance(f, origins[row, 0], origins[row, 1], origins[row, 2],
                              directions[row, 0], directions[row, 1], directions[row, 2],
                              first_vertex, normals)
    if distance > epsilon:
        face_out[row] = f
        distance_out[row] = distance
        normal_out[row, 0] = normals[f, 0]
        normal_out[row, 1] = normals[f, 1]
        normal_out[row, 2] = normals[f, 2]


@njit(nogil=True, cache=True)
def refine_hits(face32, origins, directions, first_vertex, normals, epsilon, face_out,
                distance_out, normal_out, offset):  # noqa: ANN001, ANN201
    """Write rays ``offset + i`` (:func:`refine_row`) for the faces ``face32`` that Embree
    found."""
    for i in range(face32.shape[0]):
        refine_row(face32[i], offset + i, origins, directions, epsilon, first_vertex, normals,
                   face_out, distance_out, normal_out)
