"""The seed paper's per-pulse model after culling, as compiled loops around the cast
(:mod:`lidarsim_core.pipeline.fused` decides when it applies and calls them).

A piece of pulses goes through three kernels and the backend's cast:

1. :func:`ray_stage`: the angular error of every ``angular`` model of the noise chain (Philox
   uniforms, inverse-CDF normals, the two rotations), then the flown direction turned into
   the scene frame by the sensor's pose;
2. :func:`body_rays`: per target, the sensor's origin and that direction in the target's body
   frame (the arrays the backend casts);
3. the cast (the backend's ``intersect``, per target);
4. :func:`closest_hit` (per target, in scenario order): the closest target wins, with its
   face, part and incidence cosine; :func:`measure`: the range gate, the range error of every
   ``range`` model, and the point-record columns of the pulses that return, written into
   arrays of their exact length.

Every operation is the NumPy reference's (:mod:`lidarsim_core.pipeline.cast`, the stages,
:func:`lidarsim_core.geometry.frames.rotate`), in the same order, without fused multiply-adds,
so the results are the same bits. The inverse normal CDF is Cephes' ``ndtri`` as SciPy
ships it (:func:`ndtri`: the same polynomials and the C library's ``log`` and ``sqrt``); the
tests compare it with ``scipy.special.ndtri`` on millions of uniforms. The kernels go over
blocks of :data:`BLOCK` rays, each step a loop of its own over the block (the Philox words,
the normals by :func:`ndtri_block`, the C library's sines and cosines, the turns), so that
the steps of neighbouring rays overlap where one ray at a time would wait on each operation
(the inverse CDF's Horner chains, the C library's calls); every ray still sees the same
operations in the same order.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .philox import philox_block, to_unit
from .rotation import turn_ray, turn_ray_with

# Cephes ndtri (scipy/xsf include/xsf/cephes/ndtri.h): rational approximations of the
# inverse normal CDF on |y - 1/2| <= 3/8, then on z = sqrt(-2 log y) in [2, 8) and [8, 64)
_P0 = (-5.99633501014107895267E1, 9.80010754185999661536E1, -5.66762857469070293439E1,
       1.39312609387279679503E1, -1.23916583867381258016E0)
_Q0 = (1.95448858338141759834E0, 4.67627912898881538453E0, 8.63602421390890590575E1,
       -2.25462687854119370527E2, 2.00260212380060660359E2, -8.20372256168333339912E1,
       1.59056225126211695515E1, -1.18331621121330003142E0)
_P1 = (4.05544892305962419923E0, 3.15251094599893866154E1, 5.71628192246421288162E1,
       4.40805073893200834700E1, 1.46849561928858024014E1, 2.18663306850790267539E0,
       -1.40256079171354495875E-1, -3.50424626827848203418E-2, -8.57456785154685413611E-4)
_Q1 = (1.57799883256466749731E1, 4.53907635128879210584E1, 4.13172038254672030440E1,
       1.50425385692907503408E1, 2.50464946208309415979E0, -1.42182922854787788574E-1,
       -3.80806407691578277194E-2, -9.33259480895457427372E-4)
_P2 = (3.23774891776946035970E0, 6.91522889068984211695E0, 3.93881025292474443415E0,
       1.33303460815807542389E0, 2.01485389549179081538E-1, 1.23716634817820021358E-2,
       3.01581553508235416007E-4, 2.65806974686737550832E-6, 6.23974539184983293730E-9)
_Q2 = (6.02427039364742014255E0, 3.67983563856160859403E0, 1.37702099489081330271E0,
       2.16236993594496635890E-1, 1.34204006088543189037E-2, 3.28014464682127739104E-4,
       2.89247864745380683936E-6, 6.79019408009981274425E-9)
_SQRT2PI = 2.50662827463100050242E0
_EXP_M2 = 0.13533528323661269189  # exp(-2)
#: Kinds of the return-stage range models :func:`measure` applies.
RANGE_GAUSSIAN, RANGE_SYSTEMATIC, RANGE_QUANTISED = 0, 1, 2


@njit(inline="always", cache=True)
def ndtri(y0):  # noqa: ANN001, ANN201
    """Inverse of the standard normal CDF for ``0 < y0 < 1`` (SciPy's ``ndtri``, bit for
    bit: the uniforms of :mod:`lidarsim_core.noise.rng` never reach 0 or 1).

    Cephes' Horner evaluations (``polevl``, and ``p1evl`` with its implied leading 1) are
    written out, in their order of operations.
    """
    negate = True
    y = y0
    if y > 1.0 - _EXP_M2:
        y = 1.0 - y
        negate = False
    if y > _EXP_M2:
        y = y - 0.5
        y2 = y * y
        p = ((((_P0[0] * y2 + _P0[1]) * y2 + _P0[2]) * y2 + _P0[3]) * y2 + _P0[4])
        x = y + y * (y2 * p / _p1evl8(y2, _Q0))
        return x * _SQRT2PI
    x = math.sqrt(-2.0 * math.log(y))
    x0 = x - math.log(x) / x
    z = 1.0 / x
    if x < 8.0:
        x1 = z * _polevl9(z, _P1) / _p1evl8(z, _Q1)
    else:
        x1 = z * _polevl9(z, _P2) / _p1evl8(z, _Q2)
    x = x0 - x1
    return -x if negate else x


@njit(inline="always", cache=True)
def _polevl9(x, c):  # noqa: ANN001, ANN202 - c0 x^8 + ... + c8, Cephes' Horner order
    a = c[0]
    a = a * x + c[1]
    a = a * x + c[2]
    a = a * x + c[3]
    a = a * x + c[4]
    a = a * x + c[5]
    a = a * x + c[6]
    a = a * x + c[7]
    return a * x + c[8]


@njit(inline="always", cache=True)
def _p1evl8(x, c):  # noqa: ANN001, ANN202 - x^8 + c0 x^7 + ... + c7 (leading 1 implied)
    a = x + c[0]
    a = a * x + c[1]
    a = a * x + c[2]
    a = a * x + c[3]
    a = a * x + c[4]
    a = a * x + c[5]
    a = a * x + c[6]
    return a * x + c[7]


#: Rays per block of :func:`ray_stage` and :func:`normals`: their uniforms and normals (a few
#: KiB) stay in the L1 cache between the loops.
BLOCK = 256


@njit(nogil=True, cache=True, error_model="numpy")
def ndtri_block(u, out, m):  # noqa: ANN001, ANN201
    """``out[j] = ndtri(u[j])`` for ``j < m``: the same bits as :func:`ndtri`, faster.

    One uniform at a time, :func:`ndtri` waits on each operation before the next: its central
    branch (three quarters of the uniforms) is two Horner chains and a division (~10 ns), a
    tail ``log``, ``sqrt``, ``log``, a division, two chains and a division (~55 ns). Here each
    step is a loop over the block, so the steps of neighbouring elements overlap: the central
    formula for every element in one branch-free loop that LLVM vectorises; then the tails'
    elements gathered, their ``sqrt(-2 log y)`` and ``log`` in two loops of C-library calls,
    the rational function of ``1/x`` in another vectorised loop. Every element gets exactly
    :func:`ndtri`'s operations on :func:`ndtri`'s values (the central formula on ``1 - y``
    above ``1 - exp(-2)``, as it does); the rare ``x >= 8`` (``y < 1.3e-14``) is
    :func:`ndtri` itself. (``error_model="numpy"``: no zero-division checks, which would
    keep the loops scalar.)"""
    high = 1.0 - _EXP_M2
    for j in range(m):
        y0 = u[j]
        y = 1.0 - y0 if y0 > high else y0
        y = y - 0.5
        y2 = y * y
        p = ((((_P0[0] * y2 + _P0[1]) * y2 + _P0[2]) * y2 + _P0[3]) * y2 + _P0[4])
        x = y + y * (y2 * p / _p1evl8(y2, _Q0))
        out[j] = x * _SQRT2PI
    rows = np.empty(m, dtype=np.int64)
    tail = np.empty(m)
    count = 0
    for j in range(m):
        y0 = u[j]
        y = 1.0 - y0 if y0 > high else y0
        if not y > _EXP_M2:
            rows[count] = j
            tail[count] = y
            count += 1
    root = np.empty(count)
    log_root = np.empty(count)
    for k in range(count):
        root[k] = math.sqrt(-2.0 * math.log(tail[k]))
    for k in range(count):
        log_root[k] = math.log(root[k])
    for k in range(count):
        x = root[k]
        x0 = x - log_root[k] / x
        z = 1.0 / x
        tail[k] = x0 - z * _polevl9(z, _P1) / _p1evl8(z, _Q1)
    for k in range(count):
        j = rows[k]
        if not root[k] < 8.0:
            out[j] = ndtri(u[j])
        elif u[j] > high:
            out[j] = tail[k]
        else:
            out[j] = -tail[k]


@njit(nogil=True, cache=True)
def normals(key, ray_index, draws):  # noqa: ANN001, ANN201
    """(N, draws) :func:`lidarsim_core.noise.rng.ray_normals` of a stream (its Philox
    ``key``), computed here (the reference for the tests of :func:`ndtri`)."""
    blocks = (draws + 3) // 4
    n = ray_index.shape[0]
    out = np.empty((n, draws))
    uniform = np.empty(n * draws)
    for row in range(n):
        base = np.uint64(ray_index[row]) * np.uint64(blocks) + np.uint64(1)
        for block in range(blocks):
            w = philox_block(base + np.uint64(block), key[0], key[1])
            for j in range(4):
                if 4 * block + j < draws:
                    uniform[row * draws + 4 * block + j] = to_unit(w[j])
    ndtri_block(uniform, out.reshape(n * draws), n * draws)
    return out


@njit(inline="always", cache=True)
def matvec(m, k, x, y, z, inverse):  # noqa: ANN001, ANN201
    """``M v`` (or ``Mᵀ v``) of the 3×3 matrix ``M = m[k]`` of an (N, 3, 3) array, summed as
    :func:`lidarsim_core.geometry.frames.rotate` does: ``(x·a + y·b) + z·c``. The matrix is
    read in place: a view ``m[k]`` per ray would cost a reference count in the loops."""
    if inverse:
        return ((x * m[k, 0, 0] + y * m[k, 1, 0]) + z * m[k, 2, 0],
                (x * m[k, 0, 1] + y * m[k, 1, 1]) + z * m[k, 2, 1],
                (x * m[k, 0, 2] + y * m[k, 1, 2]) + z * m[k, 2, 2])
    return ((x * m[k, 0, 0] + y * m[k, 0, 1]) + z * m[k, 0, 2],
            (x * m[k, 1, 0] + y * m[k, 1, 1]) + z * m[k, 1, 2],
            (x * m[k, 2, 0] + y * m[k, 2, 1]) + z * m[k, 2, 2])


@njit(nogil=True, cache=True)
def ray_stage(direction, ray_index, keys, sigmas, sensor_matrix, flown, scene):  # noqa: ANN001
    """Write the flown directions (sensor frame) and their scene-frame rotations.

    Parameters
    ----------
    direction
        (N, 3) nominal directions.
    ray_index
        (N,) int64 global ray indices.
    keys, sigmas
        (A, 2) uint64 Philox keys and (A,) σ (rad) of the chain's angular errors, in chain
        order (σ > 0).
    sensor_matrix
        (1 or N, 3, 3) the sensor's body→scene rotations.
    flown, scene
        (N, 3) outputs.
    """
    shared = sensor_matrix.shape[0] == 1
    n = direction.shape[0]
    # per block: every ray's two uniforms of an angular error, their normals in one
    # vectorised pass (:func:`ndtri_block`), the turns; each ray sees the same operations in
    # the same order as one ray at a time
    u1, u2 = np.empty(BLOCK), np.empty(BLOCK)
    a1, a2 = np.empty(BLOCK), np.empty(BLOCK)
    c1, s1, c2, s2 = np.empty(BLOCK), np.empty(BLOCK), np.empty(BLOCK), np.empty(BLOCK)
    for lo in range(0, n, BLOCK):
        m = min(BLOCK, n - lo)
        for j in range(m):
            flown[lo + j, 0] = direction[lo + j, 0]
            flown[lo + j, 1] = direction[lo + j, 1]
            flown[lo + j, 2] = direction[lo + j, 2]
        for a in range(keys.shape[0]):
            for j in range(m):
                counter = np.uint64(ray_index[lo + j]) + np.uint64(1)  # one block: two draws
                w = philox_block(counter, keys[a, 0], keys[a, 1])
                u1[j] = to_unit(w[0])
                u2[j] = to_unit(w[1])
            ndtri_block(u1, a1, m)
            ndtri_block(u2, a2, m)
            sigma = sigmas[a]
            for j in range(m):  # the C library's sines and cosines, independent calls
                c1[j], s1[j] = math.cos(a1[j] * sigma), math.sin(a1[j] * sigma)
                c2[j], s2[j] = math.cos(a2[j] * sigma), math.sin(a2[j] * sigma)
            for j in range(m):
                i = lo + j
                flown[i, 0], flown[i, 1], flown[i, 2] = turn_ray_with(
                    flown[i, 0], flown[i, 1], flown[i, 2], c1[j], s1[j], c2[j], s2[j])
        for j in range(m):
            i = lo + j
            scene[i, 0], scene[i, 1], scene[i, 2] = matvec(
                sensor_matrix, 0 if shared else i, flown[i, 0], flown[i, 1], flown[i, 2], False)


@njit(nogil=True, cache=True)
def ray_stage_drawn(direction, drawn, sigmas, sensor_matrix, flown, scene):  # noqa: ANN001
    """:func:`ray_stage` with normals drawn beforehand: ``drawn`` (A, N, 2), the two normals
    of every ray for each angular error (another generator's, e.g. the Ziggurat's
    :func:`lidarsim_core.kernels.ziggurat.ray_normals`: a draw with a rare rejection loop
    inside this loop would slow every ray)."""
    shared = sensor_matrix.shape[0] == 1
    for i in range(direction.shape[0]):
        x, y, z = direction[i, 0], direction[i, 1], direction[i, 2]
        for a in range(drawn.shape[0]):
            x, y, z = turn_ray(x, y, z, drawn[a, i, 0] * sigmas[a], drawn[a, i, 1] * sigmas[a])
        flown[i, 0], flown[i, 1], flown[i, 2] = x, y, z
        scene[i, 0], scene[i, 1], scene[i, 2] = matvec(sensor_matrix, 0 if shared else i,
                                                       x, y, z, False)


@njit(nogil=True, cache=True)
def body_rays(scene, sensor_position, position, matrix, origin_out, direction_out):  # noqa: ANN001
    """Write the sensor's origin and the scene-frame directions in one target's body frame
    (:func:`lidarsim_core.geometry.frames.to_body` and ``rotate(..., inverse=True)``).

    ``sensor_position`` (1 or N, 3), ``position`` (1 or N, 3) and ``matrix`` (1 or N, 3, 3)
    are the sensor's and the target's poses; a single row serves every ray.
    """
    for i in range(scene.shape[0]):
        s = 0 if sensor_position.shape[0] == 1 else i
        p = 0 if position.shape[0] == 1 else i
        k = 0 if matrix.shape[0] == 1 else i
        rx = sensor_position[s, 0] - position[p, 0]
        ry = sensor_position[s, 1] - position[p, 1]
        rz = sensor_position[s, 2] - position[p, 2]
        origin_out[i, 0], origin_out[i, 1], origin_out[i, 2] = matvec(matrix, k, rx, ry, rz,
                                                                      True)
        direction_out[i, 0], direction_out[i, 1], direction_out[i, 2] = matvec(
            matrix, k, scene[i, 0], scene[i, 1], scene[i, 2], True)


@njit(nogil=True, cache=True)
def closest_hit(target, distance, face, normal, direction, face_part, part_offset,
                best, best_target, best_face, best_part, cos_incidence):  # noqa: ANN001
    """Keep target ``target``'s hits that are closer than the best so far (targets are
    visited in scenario order; a tie keeps the earlier one), with their face, part and
    incidence cosine ``|n · d|`` in its body frame."""
    for i in range(distance.shape[0]):
        f = face[i]
        d = distance[i]
        if f >= 0 and d < best[i]:
            best[i] = d
            best_target[i] = target
            best_face[i] = f
            best_part[i] = face_part[f] + part_offset
            dot = (normal[i, 0] * direction[i, 0] + normal[i, 1] * direction[i, 1]) + \
                normal[i, 2] * direction[i, 2]
            cos_incidence[i] = abs(dot)


@njit(nogil=True, cache=True)
def measure(best, best_target, flown, ray_index, range_min, range_max, kinds,  # noqa: ANN001
            keys, params, drawn):  # noqa: ANN001, ANN201
    """The range gate, the range errors and the point-record columns of the pulses that
    return.

    ``kinds``, ``keys``, ``params``: the chain's range models in chain order, (R,) kinds,
    (R, 2) Philox keys and (R, 2) parameters: :data:`RANGE_GAUSSIAN` (``range``: σ),
    :data:`RANGE_SYSTEMATIC` (``range_systematic``: 1 + scale, bias) and
    :data:`RANGE_QUANTISED` (``range_quantisation``: step, offset). ``drawn``: (R, M) normals
    drawn beforehand for the M pulses that pass the range gate, in order (another generator's,
    e.g. the Ziggurat's), or (R, 0) to draw the seed paper's here. Returns ``rows`` (the
    pulses kept, in order), the true and measured ranges, and the measured and true points
    (sensor frame, (3, M)), each of the exact length.
    """
    n = best.shape[0]
    count = 0
    for i in range(n):
        if best_target[i] >= 0 and best[i] >= range_min and best[i] <= range_max:
            count += 1
    rows = np.empty(count, dtype=np.int64)
    k = 0
    for i in range(n):
        if best_target[i] >= 0 and best[i] >= range_min and best[i] <= range_max:
            rows[k] = i
            k += 1
    if drawn.shape[1] == 0:  # the seed paper's normals, drawn here for the returns in order
        drawn = np.zeros((kinds.shape[0], count))
        uniform = np.empty(count)
        for a in range(kinds.shape[0]):
            if kinds[a] == RANGE_GAUSSIAN:
                for k in range(count):
                    counter = np.uint64(ray_index[rows[k]]) + np.uint64(1)
                    uniform[k] = to_unit(philox_block(counter, keys[a, 0], keys[a, 1])[0])
                ndtri_block(uniform, drawn[a], count)
    range_true = np.empty(count)
    range_measured = np.empty(count)
    point = np.empty((3, count))
    truth = np.empty((3, count))
    for k in range(count):
        i = rows[k]
        r = best[i]
        measured = r
        for a in range(kinds.shape[0]):
            if kinds[a] == RANGE_GAUSSIAN:  # R + z σ (noise.gaussian.RangeError)
                measured = measured + drawn[a, k] * params[a, 0]
            elif kinds[a] == RANGE_SYSTEMATIC:  # R (1 + scale) + bias
                measured = measured * params[a, 0] + params[a, 1]
            else:  # offset + q round((R - offset) / q), halves to even as NumPy's round
                measured = params[a, 1] + params[a, 0] * np.round(
                    (measured - params[a, 1]) / params[a, 0])
        range_true[k] = r
        range_measured[k] = measured
        for c in range(3):
            point[c, k] = flown[i, c] * measured
            truth[c, k] = flown[i, c] * r
    return rows, range_true, range_measured, point, truth
