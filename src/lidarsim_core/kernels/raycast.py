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


# A row's refinement is two small functions of few arrays, the distance called for hits
# only: one function taking the seven arrays of a row's inputs and outputs cost ~100 ns a
# call (the binding's cast ran at 110-120 ns per ray instead of ~25 on the bench's static demo
# rays, of which ~18 are Embree's), one returning a (face, distance) tuple ~20 ns, and a call
# for every ray, misses included, ~20 ns.
@njit(nogil=True, cache=True)
def refined_distance(f, ox, oy, oz, dx, dy, dz, epsilon, first_vertex, normals):  # noqa: ANN001, ANN201
    """The float64 distance along the ray ``(o, d)`` to the plane of the face ``f`` (≥ 0)
    that Embree found; NaN for a refined distance at or below ``epsilon`` (a grazing float32
    artefact, counted as a miss). Callers test ``f`` first: a miss then costs no call."""
    distance = plane_distance(f, ox, oy, oz, dx, dy, dz, first_vertex, normals)
    return distance if distance > epsilon else np.nan


@njit(nogil=True, cache=True)
def store_hit(row, f, distance, normals, face_out, distance_out, normal_out):  # noqa: ANN001, ANN201
    """Write row ``row`` of a cast's outputs from :func:`refined_distance`: the face ``f``,
    the distance and the face's normal, or -1 and NaN where the distance is NaN."""
    hit = distance == distance
    face_out[row] = f if hit else -1
    distance_out[row] = distance
    for k in range(3):
        normal_out[row, k] = normals[f, k] if hit else np.nan


@njit(nogil=True, cache=True)
def refine_hits(face32, origins, directions, first_vertex, normals, epsilon, face_out,
                distance_out, normal_out, offset):  # noqa: ANN001, ANN201
    """Write rays ``offset + i`` (:func:`refined_distance`, :func:`store_hit`) for the
    faces ``face32`` that Embree found."""
    for i in range(face32.shape[0]):
        row, f = offset + i, face32[i]
        distance = np.nan
        if f >= 0:
            distance = refined_distance(f, origins[row, 0], origins[row, 1], origins[row, 2],
                                        directions[row, 0], directions[row, 1],
                                        directions[row, 2], epsilon, first_vertex, normals)
        store_hit(row, f, distance, normals, face_out, distance_out, normal_out)
