"""Conservative culling of pulses that cannot reach any target (numba; see
:mod:`lidarsim_core.pipeline.cull`).

A pulse is kept when its nominal ray, in a target's body frame, meets a leaf of that target's
box tree with every box grown by ``grow`` (the largest distance by which the flown ray, or any
of its beam's sub-rays, can stray from the nominal ray before leaving the target's bounding
box). The slab tests run in float64 with an extra tolerance in ``grow``. When one pose holds for
a whole piece, :func:`direction_grid` projects the grown leaf boxes once onto a cube map of
directions and :func:`cull_by_grid` looks each pulse up in it instead.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(inline="always", cache=True)
def _inverse(d):  # noqa: ANN001, ANN202
    """1/d, with a huge finite value for 0 so that no 0·inf (NaN) appears in the slab test."""
    return 1.0 / d if d != 0.0 else 1e300


@njit(inline="always", cache=True)
def _slab(o, inv, lo, hi, grow):  # noqa: ANN001, ANN202
    a = (lo - grow - o) * inv
    b = (hi + grow - o) * inv
    return min(a, b), max(a, b)


@njit(inline="always", cache=True)
def _meets_tree(o, inv, box_lo, box_hi, first_child, root, grow, stack):  # noqa: ANN001, ANN202
    """Whether the ray ``o + s·d`` (``s >= 0``, ``inv = 1/d``) meets a leaf box of the tree
    at ``root`` with every box grown by ``grow``; ``stack`` is scratch deeper than the tree."""
    stack[0] = root
    top = 1
    while top > 0:
        top -= 1
        node = stack[top]
        near_x, far_x = _slab(o[0], inv[0], box_lo[node, 0], box_hi[node, 0], grow)
        near_y, far_y = _slab(o[1], inv[1], box_lo[node, 1], box_hi[node, 1], grow)
        near_z, far_z = _slab(o[2], inv[2], box_lo[node, 2], box_hi[node, 2], grow)
        if max(0.0, near_x, near_y, near_z) > min(far_x, far_y, far_z):
            continue
        child = first_child[node]
        if child < 0:
            return True
        stack[top] = child
        stack[top + 1] = child + 1
        top += 2
    return False


@njit(nogil=True, cache=True)
def direction_grid(corners, cells):  # noqa: ANN001, ANN201
    """A cube map of the directions that may meet any of the boxes, or None.

    ``corners`` are the (B, 8, 3) corners of boxes in the sensor frame, corner ``c`` at the
    high end of the box's first, second and third edge where bit 0, 1, 2 of ``c`` is set.
    Face ``f`` of the map (axis ``f // 2``, sign ``+`` for even ``f``) covers the directions
    whose largest component is that axis with that sign; cell ``(i, j)`` of a face is set
    when a direction in it may meet a box: the bounding rectangle of the projection on the
    face of the box clipped to ``depth >= D / 2`` (``D`` the box's distance from the
    origin). Every point of the box that a direction of the face reaches has ``depth >=
    D / √3`` (it lies in the face's cone, where ``|p| <= √3 depth``), so the clipped box,
    whose projection is bounded, holds them all: a box beside, across or near the sensor
    sets only the cells it can be seen through. Returns None when the origin is in (or
    within 1 µm of) a box.
    """
    grid = np.zeros((6, cells, cells), dtype=np.uint8)
    half = cells / 2.0
    points = np.empty((20, 3))  # the clipped box's vertices: 8 corners, 12 edge crossings
    for b in range(corners.shape[0]):
        box = corners[b]
        # the box's nearest point to the origin (its edges are orthogonal)
        near = box[0].copy()
        scale = 0.0
        for c in range(8):
            scale = max(scale, abs(box[c, 0]), abs(box[c, 1]), abs(box[c, 2]))
        for k in range(3):
            edge = box[1 << k] - box[0]
            length2 = edge[0] ** 2 + edge[1] ** 2 + edge[2] ** 2
            if length2 > 0.0:
                t = -(box[0, 0] * edge[0] + box[0, 1] * edge[1] + box[0, 2] * edge[2]) / length2
                t = min(max(t, 0.0), 1.0)
                near += t * edge
        distance = math.sqrt(near[0] ** 2 + near[1] ** 2 + near[2] ** 2)
        if distance <= 1e-6:
            return None
        clip = 0.5 * distance
        # rounding of the edge crossings and of the rays' u, v, relative to the depth
        slack = 1e-9 + 1e-13 * scale / clip
        for face in range(6):
            axis = face // 2
            sign = 1.0 if face % 2 == 0 else -1.0
            u_axis = (axis + 1) % 3
            v_axis = (axis + 2) % 3
            count = 0
            for c in range(8):
                depth = sign * box[c, axis]
                if depth >= clip:
                    points[count] = box[c]
                    count += 1
                for k in range(3):  # the edges from c to its neighbour across bit k
                    other = c | (1 << k)
                    if other == c:
                        continue
                    other_depth = sign * box[other, axis]
                    if (depth >= clip) != (other_depth >= clip):
                        w = (clip - depth) / (other_depth - depth)
                        points[count] = box[c] + w * (box[other] - box[c])
                        points[count, axis] = sign * clip
                        count += 1
            if count == 0:
                continue  # the box is behind this face's cone
            u_min, u_max, v_min, v_max = np.inf, -np.inf, np.inf, -np.inf
            for p in range(count):
                depth = sign * points[p, axis]
                u, v = points[p, u_axis] / depth, points[p, v_axis] / depth
                u_min, u_max = min(u_min, u), max(u_max, u)
                v_min, v_max = min(v_min, v), max(v_max, v)
            if u_max < -1.0 - slack or u_min > 1.0 + slack or v_max < -1.0 - slack \
                    or v_min > 1.0 + slack:
                continue  # the box is seen only through other faces
            # a hair wider than the rectangle, for the rounding of the rays' u, v
            i0 = min(max(int(math.floor((max(u_min - slack, -2.0) + 1.0) * half)), 0),
                     cells - 1)
            i1 = min(max(int(math.floor((min(u_max + slack, 2.0) + 1.0) * half)), 0),
                     cells - 1)
            j0 = min(max(int(math.floor((max(v_min - slack, -2.0) + 1.0) * half)), 0),
                     cells - 1)
            j1 = min(max(int(math.floor((min(v_max + slack, 2.0) + 1.0) * half)), 0),
                     cells - 1)
            grid[face, i0:i1 + 1, j0:j1 + 1] = 1
    return grid


@njit(cache=True)
def in_grid(x, y, z, grid, half, cells):  # noqa: ANN001, ANN201
    """Whether direction ``(x, y, z)`` falls in a set cell of :func:`direction_grid`'s cube
    map (``half`` = cells / 2); a zero vector is kept (not a direction: the exact path
    decides)."""
    ax, ay, az = abs(x), abs(y), abs(z)
    if ax >= ay and ax >= az:
        face, depth, u, v = (0 if x > 0 else 1), ax, y, z
    elif ay >= az:
        face, depth, u, v = (2 if y > 0 else 3), ay, z, x
    else:
        face, depth, u, v = (4 if z > 0 else 5), az, x, y
    if depth == 0.0:
        return True
    ci = min(max(int(math.floor((u / depth + 1.0) * half)), 0), cells - 1)
    cj = min(max(int(math.floor((v / depth + 1.0) * half)), 0), cells - 1)
    return bool(grid[face, ci, cj])


@njit(nogil=True, cache=True)
def cull_by_grid(directions, grid):  # noqa: ANN001, ANN201
    """Indices of the directions whose cell of :func:`direction_grid`'s cube map is set."""
    n = directions.shape[0]
    cells = grid.shape[1]
    half = cells / 2.0
    keep = np.empty(n, dtype=np.int64)
    kept = 0
    for i in range(n):
        if in_grid(directions[i, 0], directions[i, 1], directions[i, 2], grid, half, cells):
            keep[kept] = i
            kept += 1
    return keep[:kept]



@njit(nogil=True, cache=True)
def cull_posed(directions, sensor_rotation, sensor_position, rotation, position, first, moving,
               box_lo, box_hi, first_child, roots, margin):  # noqa: ANN001, ANN201
    """Indices of the pulses that may reach a target, with poses per pulse: the frame changes
    into each target's body frame are made per pulse here, without arrays of them.

    Parameters
    ----------
    directions
        (N, 3) nominal directions in the sensor frame.
    sensor_rotation, sensor_position
        (1 or N, 3, 3) body→scene rotations and (1 or N, 3) positions of the sensor.
    rotation, position
        Every target's poses one after the other: (P, 3, 3) and (P, 3); target ``t``'s
        start at ``first[t]`` and hold N poses if ``moving[t]``, else one.
    box_lo, box_hi, first_child, roots
        A binary tree of (B, 3) boxes in the targets' body frames; node ``k``'s children are
        ``first_child[k]`` and the next node, -1 for a leaf; ``roots[t]`` is target ``t``'s
        root node.
    margin
        The largest angle (rad) between a flown (sub-)ray and its pulse's nominal direction;
        a target's boxes grow by it times the farthest corner of its root box from the
        sensor, plus 1e-9 m for the rounding of the box test.
    """
    n = directions.shape[0]
    keep = np.empty(n, dtype=np.int64)
    kept = 0
    stack = np.empty(2 * first_child.shape[0] + 2, dtype=np.int64)
    inv = np.empty(3)
    o = np.empty(3)
    sensor_moving = sensor_rotation.shape[0] > 1
    for i in range(n):
        s = i if sensor_moving else 0
        rs = sensor_rotation[s]
        dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
        # the nominal direction in the scene frame
        sx = rs[0, 0] * dx + rs[0, 1] * dy + rs[0, 2] * dz
        sy = rs[1, 0] * dx + rs[1, 1] * dy + rs[1, 2] * dz
        sz = rs[2, 0] * dx + rs[2, 1] * dy + rs[2, 2] * dz
        reach = False
        for t in range(roots.shape[0]):
            if reach:
                break
            p = first[t] + (i if moving[t] else 0)
            rt = rotation[p]
            ox = sensor_position[s, 0] - position[p, 0]
            oy = sensor_position[s, 1] - position[p, 1]
            oz = sensor_position[s, 2] - position[p, 2]
            root = roots[t]
            far2 = 0.0
            for a in range(3):  # origin and direction in the body frame: Rtᵀ v
                o[a] = rt[0, a] * ox + rt[1, a] * oy + rt[2, a] * oz
                inv[a] = _inverse(rt[0, a] * sx + rt[1, a] * sy + rt[2, a] * sz)
                reach_a = max(abs(box_lo[root, a] - o[a]), abs(box_hi[root, a] - o[a]))
                far2 += reach_a * reach_a
            grow = math.sqrt(far2) * (margin + 1e-9) + 1e-9
            reach = _meets_tree(o, inv, box_lo, box_hi, first_child, root, grow, stack)
        if reach:
            keep[kept] = i
            kept += 1
    return keep[:kept]


@njit(nogil=True, cache=True)
def motion_bound(sensor_rotation, sensor_position, rotation, position, reference,
                 reach):  # noqa: ANN001, ANN201
    """A bound on how far any point within ``reach`` of a target's origin strays, in the
    sensor frame, from where the ``reference`` pose puts it: ``max ‖Mᵢ − M₀‖_F · reach +
    max |oᵢ − o₀|`` over the N poses, with ``Mᵢ = Rsᵢᵀ Rtᵢ`` and ``oᵢ = Rsᵢᵀ (ptᵢ − psᵢ)``
    (the Frobenius norm bounds the spectral one). Each array holds N rows or one (shared).
    With one sensor pose, ``‖Mᵢ − M₀‖_F = ‖Rtᵢ − Rt₀‖_F`` and ``|oᵢ − o₀| = |ptᵢ − pt₀|``
    (a rotation keeps norms), so only the target's rows are read."""
    n = max(sensor_rotation.shape[0], sensor_position.shape[0], rotation.shape[0],
            position.shape[0])
    worst_rotation = 0.0
    worst_shift = 0.0
    if sensor_rotation.shape[0] == 1 and sensor_position.shape[0] == 1:
        if rotation.shape[0] > 1:
            r0 = rotation[reference]
            for i in range(rotation.shape[0]):
                frob = 0.0
                for a in range(3):
                    for b in range(3):
                        frob += (rotation[i, a, b] - r0[a, b]) ** 2
                worst_rotation = max(worst_rotation, frob)
        if position.shape[0] > 1:
            p0 = position[reference]
            for i in range(position.shape[0]):
                shift = 0.0
                for a in range(3):
                    shift += (position[i, a] - p0[a]) ** 2
                worst_shift = max(worst_shift, shift)
        return math.sqrt(worst_rotation) * reach + math.sqrt(worst_shift)
    m0 = np.empty((3, 3))
    o0 = np.empty(3)
    m = np.empty((3, 3))
    o = np.empty(3)
    for i in range(-1, n):
        k = reference if i < 0 else i
        s = k if sensor_rotation.shape[0] > 1 else 0
        t = k if rotation.shape[0] > 1 else 0
        sp = k if sensor_position.shape[0] > 1 else 0
        tp = k if position.shape[0] > 1 else 0
        dx = position[tp, 0] - sensor_position[sp, 0]
        dy = position[tp, 1] - sensor_position[sp, 1]
        dz = position[tp, 2] - sensor_position[sp, 2]
        for a in range(3):
            o[a] = sensor_rotation[s, 0, a] * dx + sensor_rotation[s, 1, a] * dy + \
                sensor_rotation[s, 2, a] * dz
            for b in range(3):
                m[a, b] = sensor_rotation[s, 0, a] * rotation[t, 0, b] + \
                    sensor_rotation[s, 1, a] * rotation[t, 1, b] + \
                    sensor_rotation[s, 2, a] * rotation[t, 2, b]
        if i < 0:
            m0[:, :] = m
            o0[:] = o
            continue
        frob = 0.0
        shift = 0.0
        for a in range(3):
            shift += (o[a] - o0[a]) ** 2
            for b in range(3):
                frob += (m[a, b] - m0[a, b]) ** 2
        worst_rotation = max(worst_rotation, frob)
        worst_shift = max(worst_shift, shift)
    return math.sqrt(worst_rotation) * reach + math.sqrt(worst_shift)


@njit(nogil=True, cache=True)
def cull_by_grid_cones(directions, grid, use_grid, block, axes, cosines):  # noqa: ANN001, ANN201
    """Indices of the directions whose cell of :func:`direction_grid`'s cube map is set (when
    ``use_grid``) or that lie within one of their block's cones.

    Pulse ``i`` belongs to block ``i // block``; ``axes`` (blocks, K, 3) are unit cone axes
    and ``cosines`` (blocks, K) the cosines of their half angles (a direction ``d`` is within
    a cone when ``d · axis >= cosine · |d|``).
    """
    n = directions.shape[0]
    cells = grid.shape[1]
    half = cells / 2.0
    keep = np.empty(n, dtype=np.int64)
    kept = 0
    cones = axes.shape[1]
    for i in range(n):
        x, y, z = directions[i, 0], directions[i, 1], directions[i, 2]
        if use_grid and in_grid(x, y, z, grid, half, cells):
            keep[kept] = i
            kept += 1
            continue
        if cones == 0:
            continue
        b = i // block
        norm = math.sqrt(x * x + y * y + z * z)
        for k in range(cones):
            if x * axes[b, k, 0] + y * axes[b, k, 1] + z * axes[b, k, 2] >= \
                    cosines[b, k] * norm:
                keep[kept] = i
                kept += 1
                break
    return keep[:kept]
