"""Embree's ray cast called from numba, with the float64 arithmetic around it in the same loop.

The functions ``rtcIntersect1`` and ``rtcIntersect4/8/16`` of the Embree 4 library are called
through their addresses, which the caller passes at run time together with the scene pointer
(:mod:`lidarsim_core.backends.embree4` loads the library and checks its ray/hit layout):
numba would refuse to cache a function that refers to a ctypes function pointer, and a
kernel that is not cached is compiled again in every process. The call itself is an
``inttoptr`` of the address in an intrinsic, so these kernels are cached on disk like the
others.

The ray/hit structure is a buffer of 4-byte words: a packet of width N (1 for a single ray)
stores field ``k`` of lane ``i`` at word ``k * N + i`` (org x/y/z, tnear, dir x/y/z, time,
tfar, mask, id, flags, Ng x/y/z, u, v, primID, geomID, then the instance stacks); the caller
passes the number of fields of its Embree build (``12 + RayHitLayout.hit_fields``). Every ray
is set up as embreex's ``EmbreeScene.run`` sets it up (tnear 0, tfar float32(1e37), time 0,
mask all ones, flags 0, invalid geometry and primitive IDs), so the hits are the same.

:func:`cast_refined` does what :class:`~lidarsim_core.backends.embree_backend.EmbreeBackend`
did around an embreex call with :func:`lidarsim_core.kernels.raycast.embree_rays` and
:func:`~lidarsim_core.kernels.raycast.refine_hits`, the same operations in the same order, for
one ray (or one packet) at a time: no float32 copies of the rays, no face array in between.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from .raycast import refined_distance, store_hit

_INVALID = np.uint32(0xFFFFFFFF)
_MASK_ALL = np.uint32(0xFFFFFFFF)
_TFAR = np.float32(1e37)
_ZERO_U = np.uint32(0)
_ZERO_F = np.float32(0.0)


def _pointer_args(builder, values):  # noqa: ANN001, ANN202
    i8p = ir.IntType(8).as_pointer()
    return [builder.inttoptr(v, i8p) for v in values]


@intrinsic
def _intersect1(typingctx, function, scene, rayhit):  # noqa: ANN001, ANN202
    """``rtcIntersect1(scene, rayhit, NULL)`` through the address ``function``."""
    if not all(isinstance(t, types.Integer) for t in (function, scene, rayhit)):
        return None
    signature = types.void(function, scene, rayhit)

    def codegen(context, builder, sig, args):  # noqa: ANN001, ANN202
        i8p = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [i8p, i8p, i8p])
        callee = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(callee, [*_pointer_args(builder, args[1:]), ir.Constant(i8p, None)])
        return context.get_dummy_value()

    return signature, codegen


@intrinsic
def _intersect_packet(typingctx, function, valid, scene, rayhit):  # noqa: ANN001, ANN202
    """``rtcIntersectN(valid, scene, rayhit, NULL)`` through the address ``function``."""
    if not all(isinstance(t, types.Integer) for t in (function, valid, scene, rayhit)):
        return None
    signature = types.void(function, valid, scene, rayhit)

    def codegen(context, builder, sig, args):  # noqa: ANN001, ANN202
        i8p = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [i8p, i8p, i8p, i8p])
        callee = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(callee, [*_pointer_args(builder, args[1:]), ir.Constant(i8p, None)])
        return context.get_dummy_value()

    return signature, codegen


@njit(nogil=True, cache=True)
def _aligned_words(words, alignment):  # noqa: ANN001, ANN202
    """``words`` zeroed uint32 words starting at a multiple of ``alignment`` bytes."""
    raw = np.zeros(words + alignment // 4, dtype=np.uint32)
    skip = ((alignment - raw.ctypes.data % alignment) % alignment) // 4
    return raw[skip:skip + words]


@njit(nogil=True, cache=True)
def _rayhit_buffer(width, fields):  # noqa: ANN001, ANN202
    """A ray/hit structure of ``width`` lanes set up as embreex sets up its rays (all but the
    origin and direction), as uint32 words, and the same memory as float32."""
    words = (fields + 3) // 4 * 4 if width == 1 else fields * width
    buf = _aligned_words(words, max(16, 4 * width))
    flt = buf.view(np.float32)
    for lane in range(width):
        flt[3 * width + lane] = _ZERO_F  # tnear
        flt[7 * width + lane] = _ZERO_F  # time
        buf[9 * width + lane] = _MASK_ALL  # mask
        buf[10 * width + lane] = _ZERO_U  # id
        buf[11 * width + lane] = _ZERO_U  # flags
        for field in range(17, fields):  # primID, geomID, instance stacks
            buf[field * width + lane] = _INVALID
    return buf, flt


# The helpers below are ordinary compiled functions (LLVM inlines them): numba's
# ``inline="always"`` made the refinement loop 20 times slower (60 ns per ray instead of 3).
@njit(nogil=True, cache=True)
def _set_ray(buf, flt, width, lane, ox, oy, oz, dx, dy, dz):  # noqa: ANN001, ANN202
    """Lane ``lane``'s origin and direction (rounded to float32 here), and what a hit
    overwrote and the next ray needs reset: tfar, primID, geomID."""
    flt[lane] = ox
    flt[width + lane] = oy
    flt[2 * width + lane] = oz
    flt[4 * width + lane] = dx
    flt[5 * width + lane] = dy
    flt[6 * width + lane] = dz
    flt[8 * width + lane] = _TFAR
    buf[17 * width + lane] = _INVALID
    buf[18 * width + lane] = _INVALID


@njit(nogil=True, cache=True)
def _shifted_ray(buf, flt, width, lane, origins, directions, i, centre, radius,
                 epsilon):  # noqa: ANN001, ANN202
    """Ray ``i`` moved to just before the bounding sphere, relative to its centre (float64,
    as :func:`lidarsim_core.kernels.raycast.embree_rays`), into lane ``lane``."""
    rx = origins[i, 0] + -centre[0]
    ry = origins[i, 1] + -centre[1]
    rz = origins[i, 2] + -centre[2]
    dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
    shift = max(-(rx * dx + ry * dy + rz * dz) - radius, epsilon)
    _set_ray(buf, flt, width, lane, rx + dx * shift, ry + dy * shift, rz + dz * shift,
             dx, dy, dz)


@njit(cache=True)
def _face(prim):  # noqa: ANN001, ANN202
    """Embree's primitive ID as a face index, -1 for none."""
    return np.int64(-1) if prim == _INVALID else np.int64(prim)


@njit(nogil=True, cache=True)
def cast_faces(intersect, scene, width, fields, origins, directions, out):  # noqa: ANN001, ANN201
    """Write into ``out`` the face each float32 ray (origins, directions: (N, 3) float32) hits
    first, -1 for a miss: embreex's ``EmbreeScene.run`` through ``intersect`` (the address of
    ``rtcIntersect1``, or of ``rtcIntersect{width}`` for packets of ``width`` rays)."""
    buf, flt = _rayhit_buffer(width, fields)
    n = origins.shape[0]
    if width == 1:
        address = buf.ctypes.data
        for i in range(n):
            _set_ray(buf, flt, 1, 0, origins[i, 0], origins[i, 1], origins[i, 2],
                     directions[i, 0], directions[i, 1], directions[i, 2])
            _intersect1(intersect, scene, address)
            prim = buf[17]
            out[i] = -1 if prim == _INVALID else np.int32(prim)
        return
    valid = _aligned_words(width, max(16, 4 * width)).view(np.int32)
    for start in range(0, n, width):
        count = min(width, n - start)
        for lane in range(width):
            if lane < count:
                i = start + lane
                _set_ray(buf, flt, width, lane, origins[i, 0], origins[i, 1], origins[i, 2],
                         directions[i, 0], directions[i, 1], directions[i, 2])
            valid[lane] = -1 if lane < count else 0
        _intersect_packet(intersect, valid.ctypes.data, scene, buf.ctypes.data)
        for lane in range(count):
            prim = buf[17 * width + lane]
            out[start + lane] = -1 if prim == _INVALID else np.int32(prim)


@njit(nogil=True, cache=True)
def cast_refined(intersect, scene, width, fields, origins, directions, centre, radius, epsilon,
                 first_vertex, normals, face_out, distance_out, normal_out, lo, hi):  # noqa: ANN001, ANN201
    """Cast rays ``lo:hi`` (float64 origins and unit directions in the mesh's frame) and write
    their first hit's face, float64 distance and normal (-1, NaN, NaN for a miss).

    Each ray's origin is moved along it to just before the bounding sphere (``centre``,
    ``radius``; never before ``epsilon``) and expressed relative to ``centre``, both vectors
    go to float32 for Embree, and on a hit the distance to the found face's plane
    (``first_vertex``, ``normals``) is recomputed from the original float64 ray; a refined
    distance at or below ``epsilon`` (a grazing float32 artefact) counts as a miss."""
    buf, flt = _rayhit_buffer(width, fields)
    address = buf.ctypes.data
    valid = _aligned_words(width, max(16, 4 * width)).view(np.int32)
    for start in range(lo, hi, width):
        count = min(width, hi - start)
        for lane in range(width):
            if lane < count:
                _shifted_ray(buf, flt, width, lane, origins, directions, start + lane, centre,
                             radius, epsilon)
            valid[lane] = -1 if lane < count else 0
        if width == 1:
            _intersect1(intersect, scene, address)
        else:
            _intersect_packet(intersect, valid.ctypes.data, scene, address)
        for lane in range(count):
            row, f, distance = start + lane, _face(buf[17 * width + lane]), np.nan
            if f >= 0:
                distance = refined_distance(f, origins[row, 0], origins[row, 1],
                                            origins[row, 2], directions[row, 0],
                                            directions[row, 1], directions[row, 2], epsilon,
                                            first_vertex, normals)
            store_hit(row, f, distance, normals, face_out, distance_out, normal_out)
