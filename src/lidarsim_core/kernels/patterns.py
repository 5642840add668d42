"""Firing schedules and the spinning and Lissajous patterns' directions in numba.

:func:`cycle_rays` gives the time, slot and channel of every ray of a
:class:`~lidarsim_core.patterns.timing.FiringCycle` with at most one integer division per ray
(none along a run of consecutive indices; NumPy needs four, with temporaries), bit for bit
NumPy's values. The direction kernels use the
NumPy code's formulas in its order with :func:`.trig.sincos` (within 2 ulp of the C
library's sine and cosine), so directions agree with NumPy's to a few ulp.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .trig import sincos


@njit(nogil=True, cache=True)
def cycle_rays(index, size, period_s, offsets_s, channels):  # noqa: ANN001, ANN201
    """Emission time (N,), slot (N,) and channel (N,) of every ray ``index``.

    A ray whose index follows the previous one's steps the slot (and the cycle) instead of
    dividing: the same integers, a few times faster on the contiguous ranges patterns are
    mostly asked for."""
    n = index.shape[0]
    t = np.empty(n)
    slot = np.empty(n, dtype=np.int64)
    channel = np.empty(n, dtype=np.int16)
    cycle = s = previous = 0
    for i in range(n):
        k = index[i]
        if i > 0 and k == previous + 1:
            s += 1
            if s == size:
                s = 0
                cycle += 1
        else:
            cycle = k // size
            s = k - cycle * size
        previous = k
        slot[i] = s
        t[i] = np.float64(cycle) * period_s + offsets_s[s]
        channel[i] = channels[s]
    return t, slot, channel


@njit(inline="always", cache=True)
def _unit(azimuth, elevation):  # noqa: ANN001, ANN202
    sin_el, cos_el = sincos(elevation)
    sin_az, cos_az = sincos(azimuth)
    return cos_el * cos_az, cos_el * sin_az, sin_el


@njit(nogil=True, cache=True)
def spinning_directions(t, channel, rotation_hz, azimuth_start, spin, az_offset,
                        elevation):  # noqa: ANN001, ANN201
    """(N, 3) directions of a spinning head: azimuth ``azimuth_start + spin·mod(f t, 1) +
    az_offset[channel]``, elevation ``elevation[channel]``."""
    n = t.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        x = rotation_hz * t[i]
        turns = x - np.floor(x)  # NumPy's mod(x, 1) (a float floor: .trig)
        c = channel[i]
        out[i, 0], out[i, 1], out[i, 2] = _unit(azimuth_start + spin * turns + az_offset[c],
                                                elevation[c])
    return out


@njit(nogil=True, cache=True)
def lissajous_directions(t, azimuth_hz, azimuth_phase, amp_az, elevation_hz, elevation_phase,
                         amp_el, elevation_centre):  # noqa: ANN001, ANN201
    """(N, 3) directions of a Lissajous scanner (see
    :meth:`lidarsim_core.patterns.lissajous.LissajousPattern.angles`)."""
    n = t.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        x = azimuth_hz * t[i]
        y = elevation_hz * t[i]
        sin_az, _ = sincos(2 * np.pi * (x - np.floor(x)) + azimuth_phase)
        sin_el, _ = sincos(2 * np.pi * (y - np.floor(y)) + elevation_phase)
        out[i, 0], out[i, 1], out[i, 2] = _unit(amp_az * sin_az,
                                                elevation_centre + amp_el * sin_el)
    return out
