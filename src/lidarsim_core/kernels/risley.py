"""The Risley-prism pattern's directions (:class:`lidarsim_core.patterns.risley.RisleyPattern`)
in numba.

The same vector Snell's law through every face of every prism, in the order of the NumPy code
(:meth:`~lidarsim_core.patterns.risley.RisleyPattern.trace`), with :func:`.trig.sincos` for the
prisms' roll angles: within a few ulp of the NumPy directions, without the (N, 3) temporaries
of the eight vectorised refractions.

The rays go in blocks of :data:`BLOCK` through every prism while the block's directions stay in
the cache; each prism's pass over a block is one of four branch-free loops (entrance or exit
face tilted; roll angles within the branch-free sine's range or not), chosen before the loop,
so that LLVM vectorises it (a branch on the face inside the loop keeps every ray scalar, four
times slower). Every ray sees the same floating-point operations in the same order as in the
one-prism-at-a-time loop this replaced (no fast-math, no contraction into FMA, which numba does
not do by default), so the directions are the same bits.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .trig import sincos, sincos_reduced

#: Rays per block: the block's three direction columns (24 KiB) stay in the L1/L2 cache while
#: it goes through every prism.
BLOCK = 1024


@njit(inline="always", error_model="numpy", cache=True)
def _refract(dx, dy, dz, nx, ny, nz, eta):  # noqa: ANN001, ANN202
    """:func:`lidarsim_core.patterns.optics.refract` for one ray (NaN on total reflection),
    without branches."""
    cos_i = dx * nx + dy * ny + dz * nz
    sign = -1.0 if cos_i < 0 else 1.0
    nx, ny, nz, cos_i = nx * sign, ny * sign, nz * sign, cos_i * sign
    sin2_t = eta * eta * (1.0 - cos_i * cos_i)
    k = np.sqrt(1.0 - sin2_t) - eta * cos_i  # NaN on total internal reflection
    return eta * dx + k * nx, eta * dy + k * ny, eta * dz + k * nz


@njit(inline="always", error_model="numpy", cache=True)
def _roll(rate, t, phase):  # noqa: ANN001, ANN202
    """A prism's roll angle (rad) at time ``t``: ``2π·mod(rate·t, 1) + phase``."""
    x = rate * t
    turns = x - np.floor(x)  # NumPy's mod(x, 1): the phase stays exact (a float floor: .trig)
    return 2.0 * np.pi * turns + phase


@njit(inline="always", error_model="numpy", cache=True)
def _through(dx, dy, dz, sin_r, cos_r, sw, cw, eta, inv_eta, entrance):  # noqa: ANN001, ANN202
    """One ray through one prism whose tilted face leans toward roll ``(sin_r, cos_r)``."""
    tx, ty, tz = cw, sw * cos_r, sw * sin_r
    if entrance:
        dx, dy, dz = _refract(dx, dy, dz, tx, ty, tz, inv_eta)
        return _refract(dx, dy, dz, 1.0, 0.0, 0.0, eta)
    dx, dy, dz = _refract(dx, dy, dz, 1.0, 0.0, 0.0, inv_eta)
    return _refract(dx, dy, dz, tx, ty, tz, eta)


@njit(nogil=True, error_model="numpy", cache=True)
def _prism(t, dx, dy, dz, rate, phase, sw, cw, eta, entrance):  # noqa: ANN001, ANN202
    """The rays emitted at times ``t`` (M,) (directions ``dx[:M]``, ``dy[:M]``, ``dz[:M]``,
    updated in place) through one prism."""
    m = t.shape[0]
    inv_eta = 1.0 / eta
    if abs(phase) < 1e5:  # roll angles within the branch-free sine's range
        if entrance:
            for j in range(m):
                sin_r, cos_r = sincos_reduced(_roll(rate, t[j], phase))
                dx[j], dy[j], dz[j] = _through(dx[j], dy[j], dz[j], sin_r, cos_r, sw, cw, eta,
                                               inv_eta, True)
        else:
            for j in range(m):
                sin_r, cos_r = sincos_reduced(_roll(rate, t[j], phase))
                dx[j], dy[j], dz[j] = _through(dx[j], dy[j], dz[j], sin_r, cos_r, sw, cw, eta,
                                               inv_eta, False)
    elif entrance:
        for j in range(m):
            sin_r, cos_r = sincos(_roll(rate, t[j], phase))
            dx[j], dy[j], dz[j] = _through(dx[j], dy[j], dz[j], sin_r, cos_r, sw, cw, eta,
                                           inv_eta, True)
    else:
        for j in range(m):
            sin_r, cos_r = sincos(_roll(rate, t[j], phase))
            dx[j], dy[j], dz[j] = _through(dx[j], dy[j], dz[j], sin_r, cos_r, sw, cw, eta,
                                           inv_eta, False)


@njit(nogil=True, error_model="numpy", cache=True)
def risley_directions(t, channel, incident, sin_wedge, cos_wedge, rotor_hz, phase_rad,
                      entrance, index):  # noqa: ANN001, ANN201
    """(N, 3) emitted directions at times ``t`` of ``channel``'s beams (``incident`` (C, 3))
    through prisms with wedge sine/cosine, rotor rates (Hz), phases (rad), whether the tilted
    face is the entrance, and refractive indices (all (P,)). Blocks of :data:`BLOCK` rays go
    through every prism in turn; NaN rows where a beam is totally reflected. Also returns the
    number of rows that are not finite."""
    n = t.shape[0]
    bad = 0
    out = np.empty((n, 3))
    size = min(n, BLOCK)
    dx, dy, dz = np.empty(size), np.empty(size), np.empty(size)
    for lo in range(0, n, BLOCK):
        # views of the block: indices from 0 are known to be non-negative, so the loops
        # vectorise (``lo + j`` would need numba's negative-index wrap-around on every access)
        t_block = t[lo:lo + BLOCK]
        channel_block = channel[lo:lo + BLOCK]
        out_block = out[lo:lo + BLOCK]
        m = t_block.shape[0]
        for j in range(m):
            c = channel_block[j]
            dx[j], dy[j], dz[j] = incident[c, 0], incident[c, 1], incident[c, 2]
        for p in range(rotor_hz.shape[0]):
            _prism(t_block, dx, dy, dz, rotor_hz[p], phase_rad[p], sin_wedge[p], cos_wedge[p],
                   index[p], entrance[p])
        for j in range(m):
            x, y, z = dx[j], dy[j], dz[j]
            norm = math.sqrt(x * x + y * y + z * z)
            bad += not 0.0 < norm < math.inf  # else |x|, |y|, |z| <= norm: a finite row
            out_block[j, 0] = x / norm
            out_block[j, 1] = y / norm
            out_block[j, 2] = z / norm
    return out, bad
