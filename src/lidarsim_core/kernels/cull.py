"""Conservative culling of pulses that cannot reach any target (numba; see
:mod:`lidarsim_core.cull`).

A pulse is kept when its nominal ray, in a target's body frame, meets a leaf of that target's
box tree with every box grown by ``grow`` (the largest distance by which the flown ray, or any
of its beam's sub-rays, can stray from the nominal ray before leaving the target's bounding
box). The slab tests run in float64 with an extra tolerance in ``grow``.
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
def cull_pulses(directions, rotation, origin, grow, box_lo, box_hi, first_child,
                roots):  # noqa: ANN001, ANN201
    """Indices of the pulses that may reach a target.

    Parameters
    ----------
    directions
        (N, 3) nominal directions in the sensor frame.
    rotation, origin, grow
        (T, M, 3, 3) sensor-to-body rotations, (T, M, 3) sensor origins in each target's
        body frame and (T, M) distances by which its boxes grow; M is 1 (one pose for all
        pulses) or N.
    box_lo, box_hi, first_child
        A binary tree of (B, 3) boxes in the targets' body frames; node ``k``'s children are
        ``first_child[k]`` and the next node, -1 for a leaf.
    roots
        (T,) the root node of each target.
    """
    n = directions.shape[0]
    keep = np.empty(n, dtype=np.int64)
    kept = 0
    stack = np.empty(2 * first_child.shape[0] + 2, dtype=np.int64)
    inv = np.empty(3)
    for i in range(n):
        reach = False
        dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
        m = i if rotation.shape[1] > 1 else 0
        for t in range(roots.shape[0]):
            if reach:
                break
            r = rotation[t, m]
            inv[0] = _inverse(r[0, 0] * dx + r[0, 1] * dy + r[0, 2] * dz)
            inv[1] = _inverse(r[1, 0] * dx + r[1, 1] * dy + r[1, 2] * dz)
            inv[2] = _inverse(r[2, 0] * dx + r[2, 1] * dy + r[2, 2] * dz)
            reach = _meets_tree(origin[t, m], inv, box_lo, box_hi, first_child, roots[t],
                                grow[t, m], stack)
        if reach:
            keep[kept] = i
            kept += 1
    return keep[:kept]
