"""Per-ray rotations of the built-in trajectories in numba (:mod:`lidarsim_core.geometry.posing`).

A chain ``R(τ) = F0 · Rot(a1, w1 τ) · F1 · … · Rot(aK, wK τ) · FK`` of fixed rotations and
rotations at constant rates about fixed axes covers the closed-form tumbling motion (with the
LVLH frame's turn) and constant angular velocity. Quaternions are scalar-last (SciPy's
order); the arithmetic is :meth:`lidarsim_core.geometry.posing.RotationChain.matrices_numpy`'s,
operation for operation, with :func:`.trig.sincos` (within 2 ulp of the C library's sine and
cosine, inlined: a C library call costs 10–15 ns) so the matrices agree with the NumPy ones
to a few ulp.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .trig import _LIMIT, sincos, sincos_reduced


@njit(inline="always", cache=True)
def _mul(ax, ay, az, aw, bx, by, bz, bw):  # noqa: ANN001, ANN202
    """Hamilton product a ⊗ b, scalar-last."""
    return (aw * bx + ax * bw + (ay * bz - az * by),
            aw * by + ay * bw + (az * bx - ax * bz),
            aw * bz + az * bw + (ax * by - ay * bx),
            aw * bw - (ax * bx + ay * by + az * bz))


@njit(inline="always", cache=True)
def _link(q, i, s, c, ax, ay, az, fx, fy, fz, fw):  # noqa: ANN001, ANN202
    """q[:, i] ⊗ (s·a, c) ⊗ f, in place."""
    x, y, z, w = _mul(q[0, i], q[1, i], q[2, i], q[3, i], s * ax, s * ay, s * az, c)
    x, y, z, w = _mul(x, y, z, w, fx, fy, fz, fw)
    q[0, i] = x
    q[1, i] = y
    q[2, i] = z
    q[3, i] = w


@njit(nogil=True, cache=True)
def chain_matrices(tau, fixed, axes, rates):  # noqa: ANN001, ANN201
    """(N, 3, 3) matrices of the chain at times ``tau`` (N,).

    ``fixed`` is (K+1, 4) quaternions, ``axes`` (K, 3) unit vectors, ``rates`` (K,) rad/s.
    One link at a time over every ray, so that the loops vectorise.
    """
    n = tau.shape[0]
    q = np.empty((4, n))
    for r in range(4):
        q[r, :] = fixed[0, r]
    for j in range(rates.shape[0]):
        ax, ay, az, rate = axes[j, 0], axes[j, 1], axes[j, 2], rates[j]
        fx, fy, fz, fw = fixed[j + 1, 0], fixed[j + 1, 1], fixed[j + 1, 2], fixed[j + 1, 3]
        reduced = True  # every half-angle within the branch-free sine's range?
        for i in range(n):
            reduced &= abs(0.5 * (rate * tau[i])) < _LIMIT
        if reduced:
            for i in range(n):
                s, c = sincos_reduced(0.5 * (rate * tau[i]))
                _link(q, i, s, c, ax, ay, az, fx, fy, fz, fw)
        else:  # a sequence of days at a fast spin: the C library where needed
            for i in range(n):
                s, c = sincos(0.5 * (rate * tau[i]))
                _link(q, i, s, c, ax, ay, az, fx, fy, fz, fw)
    out = np.empty((n, 3, 3))
    for i in range(n):
        x, y, z, w = q[0, i], q[1, i], q[2, i], q[3, i]
        x2, y2, z2, w2 = x * x, y * y, z * z, w * w
        xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
        out[i, 0, 0] = x2 - y2 - z2 + w2
        out[i, 1, 0] = 2.0 * (xy + zw)
        out[i, 2, 0] = 2.0 * (xz - yw)
        out[i, 0, 1] = 2.0 * (xy - zw)
        out[i, 1, 1] = -x2 + y2 - z2 + w2
        out[i, 2, 1] = 2.0 * (yz + xw)
        out[i, 0, 2] = 2.0 * (xz + yw)
        out[i, 1, 2] = 2.0 * (yz - xw)
        out[i, 2, 2] = -x2 - y2 + z2 + w2
    return out


@njit(nogil=True, cache=True)
def look_at_matrices(positions, point, up):  # noqa: ANN001, ANN201
    """(N, 3, 3) matrices of :func:`lidarsim_core.trajectories.attitude.look_at_matrices`
    (the same construction per row; ``up`` is a unit vector)."""
    n = positions.shape[0]
    out = np.empty((n, 3, 3))
    for i in range(n):
        x0 = point[0] - positions[i, 0]
        x1 = point[1] - positions[i, 1]
        x2 = point[2] - positions[i, 2]
        norm = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        if norm < 1e-12:
            x0, x1, x2, norm = 1.0, 0.0, 0.0, 1.0
        x0, x1, x2 = x0 / norm, x1 / norm, x2 / norm
        dot = up[0] * x0 + up[1] * x1 + up[2] * x2
        z0, z1, z2 = up[0] - dot * x0, up[1] - dot * x1, up[2] - dot * x2
        znorm = np.sqrt(z0 * z0 + z1 * z1 + z2 * z2)
        if znorm < 1e-9:  # the scene axis least aligned with the boresight
            a0, a1, a2 = abs(x0), abs(x1), abs(x2)
            k = 0 if (a0 <= a1 and a0 <= a2) else (1 if a1 <= a2 else 2)
            e0 = 1.0 if k == 0 else 0.0
            e1 = 1.0 if k == 1 else 0.0
            e2 = 1.0 if k == 2 else 0.0
            dot = e0 * x0 + e1 * x1 + e2 * x2
            z0, z1, z2 = e0 - dot * x0, e1 - dot * x1, e2 - dot * x2
            znorm = np.sqrt(z0 * z0 + z1 * z1 + z2 * z2)
        z0, z1, z2 = z0 / znorm, z1 / znorm, z2 / znorm
        out[i, 0, 0], out[i, 1, 0], out[i, 2, 0] = x0, x1, x2
        out[i, 0, 1], out[i, 1, 1], out[i, 2, 1] = z1 * x2 - z2 * x1, z2 * x0 - z0 * x2, \
            z0 * x1 - z1 * x0
        out[i, 0, 2], out[i, 1, 2], out[i, 2, 2] = z0, z1, z2
    return out
