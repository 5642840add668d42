"""Per-ray rotations of the built-in trajectories in numba (:mod:`lidarsim_core.posing`).

A chain ``R(τ) = F0 · Rot(a1, w1 τ) · F1 · … · Rot(aK, wK τ) · FK`` of fixed rotations and
rotations at constant rates about fixed axes covers the closed-form tumbling motion (with the
LVLH frame's turn) and constant angular velocity. Quaternions are scalar-last (SciPy's
order); the arithmetic is :func:`lidarsim_core.posing.chain_quaternions_numpy`'s, operation
for operation, with the C library's sine and cosine (which NumPy also calls for float64).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(inline="always", cache=True)
def _mul(ax, ay, az, aw, bx, by, bz, bw):  # noqa: ANN001, ANN202
    """Hamilton product a ⊗ b, scalar-last."""
    return (aw * bx + ax * bw + (ay * bz - az * by),
            aw * by + ay * bw + (az * bx - ax * bz),
            aw * bz + az * bw + (ax * by - ay * bx),
            aw * bw - (ax * bx + ay * by + az * bz))


@njit(nogil=True, cache=True)
def chain_matrices(tau, fixed, axes, rates):  # noqa: ANN001, ANN201
    """(N, 3, 3) matrices of the chain at times ``tau`` (N,).

    ``fixed`` is (K+1, 4) quaternions, ``axes`` (K, 3) unit vectors, ``rates`` (K,) rad/s.
    """
    n = tau.shape[0]
    k = rates.shape[0]
    out = np.empty((n, 3, 3))
    for i in range(n):
        x, y, z, w = fixed[0, 0], fixed[0, 1], fixed[0, 2], fixed[0, 3]
        for j in range(k):
            half = 0.5 * (rates[j] * tau[i])
            s = math.sin(half)
            c = math.cos(half)
            x, y, z, w = _mul(x, y, z, w, s * axes[j, 0], s * axes[j, 1], s * axes[j, 2], c)
            x, y, z, w = _mul(x, y, z, w, fixed[j + 1, 0], fixed[j + 1, 1], fixed[j + 1, 2],
                              fixed[j + 1, 3])
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
