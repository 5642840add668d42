"""The fast path's cast inside its compiled loop: body-frame rays, Embree's packet cast, the
float64 refinement and the closest target, per block of rays, for one target at a time.

:func:`cast_closest` replaces, for a backend that gives a compiled cast
(:meth:`lidarsim_core.backends.base.RayBackend.compiled_cast`: Embree through its binding),
the three steps :func:`lidarsim_core.kernels.fused.body_rays` → the backend's ``cast`` →
:func:`lidarsim_core.kernels.fused.closest_hit`: for every packet of ``width`` rays, each ray's
origin and direction in the target's body frame are computed in registers, shifted to just
before the mesh's bounding sphere and handed to ``rtcIntersect{width}`` (through its address,
passed at run time so that the kernel is cached on disk, see :mod:`.embree_cast`); each hit's
distance is recomputed in float64 on the face's plane and kept if it is the closest target so
far. No (N, 3) body arrays, no face array in between, no Python between the targets' rays.

Every operation is the one of those three steps (``matvec``'s summation order, the shift and
the refinement of :func:`lidarsim_core.kernels.embree_cast.cast_refined`, ``closest_hit``'s
comparison and incidence cosine), without fused multiply-adds, so the hits are the same bits.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .embree_cast import _aligned_words, _intersect1, _intersect_packet, _rayhit_buffer, _set_ray
from .fused import matvec
from .raycast import plane_distance

_INVALID = np.uint32(0xFFFFFFFF)


@njit(nogil=True, cache=True)
def cast_closest(intersect, scene, width, fields, directions, sensor_position, position,
                 matrix, centre, radius, epsilon, first_vertex, normals, face_part,
                 part_offset, target, best, best_target, best_face, best_part,
                 cos_incidence):  # noqa: ANN001, ANN201
    """Cast scene-frame rays on one target and keep its hits closer than the best so far.

    Parameters
    ----------
    intersect, scene, width, fields
        Address of ``rtcIntersect1`` (``width`` 1) or ``rtcIntersect{width}``, the committed
        scene's handle, the packet width and the number of 4-byte fields of the ray/hit
        structure (:class:`lidarsim_core.backends.embree4.RayHitLayout`).
    directions
        (N, 3) scene-frame directions (:func:`lidarsim_core.kernels.fused.ray_stage`).
    sensor_position, position, matrix
        (1 or N, 3) the sensor's position, (1 or N, 3) and (1 or N, 3, 3) the target's pose;
        a single row serves every ray.
    centre, radius, epsilon
        The mesh's box centre (its Embree scene is relative to it), bounding-sphere radius and
        the backend's smallest distance.
    first_vertex, normals
        (F, 3) first vertex and unit normal of every face (float64).
    face_part, part_offset, target
        The face → part map, the target's first part number and its index in the scenario.
    best, best_target, best_face, best_part, cos_incidence
        (N,) the closest hit so far (updated in place, as ``closest_hit``).
    """
    buf, flt = _rayhit_buffer(width, fields)
    address = buf.ctypes.data
    valid = _aligned_words(width, max(16, 4 * width)).view(np.int32)
    valid_address = valid.ctypes.data
    body = np.empty((width, 6))
    n = directions.shape[0]
    one_matrix = matrix.shape[0] == 1
    # one pose for every ray (a still scene): the body-frame origin is the same for all
    still = sensor_position.shape[0] == 1 and position.shape[0] == 1 and one_matrix
    cx, cy, cz = -centre[0], -centre[1], -centre[2]
    sx, sy, sz = matvec(matrix, 0, sensor_position[0, 0] - position[0, 0],
                        sensor_position[0, 1] - position[0, 1],
                        sensor_position[0, 2] - position[0, 2], True)
    for start in range(0, n, width):
        count = min(width, n - start)
        for lane in range(count):
            i = start + lane
            if still:
                ox, oy, oz = sx, sy, sz
                dx, dy, dz = matvec(matrix, 0, directions[i, 0], directions[i, 1],
                                    directions[i, 2], True)
            else:
                s = 0 if sensor_position.shape[0] == 1 else i
                p = 0 if position.shape[0] == 1 else i
                k = 0 if one_matrix else i
                ox, oy, oz = matvec(matrix, k, sensor_position[s, 0] - position[p, 0],
                                    sensor_position[s, 1] - position[p, 1],
                                    sensor_position[s, 2] - position[p, 2], True)
                dx, dy, dz = matvec(matrix, k, directions[i, 0], directions[i, 1],
                                    directions[i, 2], True)
            body[lane, 0], body[lane, 1], body[lane, 2] = ox, oy, oz
            body[lane, 3], body[lane, 4], body[lane, 5] = dx, dy, dz
            rx, ry, rz = ox + cx, oy + cy, oz + cz
            shift = max(-(rx * dx + ry * dy + rz * dz) - radius, epsilon)
            _set_ray(buf, flt, width, lane, rx + dx * shift, ry + dy * shift, rz + dz * shift,
                     dx, dy, dz)
            valid[lane] = -1
        for lane in range(count, width):
            valid[lane] = 0
        if width == 1:
            _intersect1(intersect, scene, address)
        else:
            _intersect_packet(intersect, valid_address, scene, address)
        for lane in range(count):
            prim = buf[17 * width + lane]
            if prim == _INVALID:
                continue
            i = start + lane
            f = np.int64(prim)
            nx, ny, nz = normals[f, 0], normals[f, 1], normals[f, 2]
            dx, dy, dz = body[lane, 3], body[lane, 4], body[lane, 5]
            distance = plane_distance(f, body[lane, 0], body[lane, 1], body[lane, 2],
                                      dx, dy, dz, first_vertex, normals)
            if distance > epsilon and distance < best[i]:
                best[i] = distance
                best_target[i] = target
                best_face[i] = f
                best_part[i] = face_part[f] + part_offset
                cos_incidence[i] = abs((nx * dx + ny * dy) + nz * dz)
