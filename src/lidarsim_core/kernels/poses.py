"""Per-ray rotations of the built-in trajectories in numba (:mod:`lidarsim_core.posing`).

A chain ``R(τ) = F0 · Rot(a1, w1 τ) · F1 · … · Rot(aK, wK τ) · FK`` of fixed rotations and
rotations at constant rates about fixed axes covers the closed-form tumbling motion (with the
LVLH frame's turn) and constant angular velocity. Quaternions are scalar-last (SciPy's
order); the arithmetic is :meth:`lidarsim_core.posing.RotationChain.matrices_numpy`'s,
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
