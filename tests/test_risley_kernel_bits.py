"""The blocked Risley kernel (lidarsim_core.kernels.risley) gives the same bits as the
one-prism-at-a-time kernel it replaced, kept here as the reference, on over a million rays of
several datasheets and prism geometries (entrance and exit faces, two to four prisms, several
channels, phases beyond the branch-free sine's range, totally reflected beams)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lidarsim_core.plugins import get_registry
from lidarsim_core.plugins.resolve import get_sensor

numba = pytest.importorskip("numba", reason="the compiled patterns need the 'fast' extra")

from lidarsim_core.kernels.risley import BLOCK, _refract, risley_directions  # noqa: E402
from lidarsim_core.kernels.trig import sincos, sincos_reduced  # noqa: E402


@numba.njit(error_model="numpy")
def _one_prism_at_a_time(t, channel, incident, sin_wedge, cos_wedge, rotor_hz, phase_rad,
                         entrance, index):  # noqa: ANN001, ANN202
    """The kernel before the blocks (lidarsim 2026-11-27, commit 0345f0a), verbatim."""
    n = t.shape[0]
    d = np.empty((3, n))
    for i in range(n):
        c = channel[i]
        d[0, i], d[1, i], d[2, i] = incident[c, 0], incident[c, 1], incident[c, 2]
    for p in range(rotor_hz.shape[0]):
        rate, phase, eta = rotor_hz[p], phase_rad[p], index[p]
        inv_eta = 1.0 / eta
        sw, cw, first = sin_wedge[p], cos_wedge[p], entrance[p]
        small = abs(phase) < 1e5
        for i in range(n):
            x = rate * t[i]
            turns = x - math.floor(x)
            roll = 2.0 * np.pi * turns + phase
            if small:
                sin_r, cos_r = sincos_reduced(roll)
            else:
                sin_r, cos_r = sincos(roll)
            tx, ty, tz = cw, sw * cos_r, sw * sin_r
            dx, dy, dz = d[0, i], d[1, i], d[2, i]
            if first:
                dx, dy, dz = _refract(dx, dy, dz, tx, ty, tz, inv_eta)
                dx, dy, dz = _refract(dx, dy, dz, 1.0, 0.0, 0.0, eta)
            else:
                dx, dy, dz = _refract(dx, dy, dz, 1.0, 0.0, 0.0, inv_eta)
                dx, dy, dz = _refract(dx, dy, dz, tx, ty, tz, eta)
            d[0, i], d[1, i], d[2, i] = dx, dy, dz
    out = np.empty((n, 3))
    for i in range(n):
        dx, dy, dz = d[0, i], d[1, i], d[2, i]
        norm = math.sqrt(dx * dx + dy * dy + dz * dz)
        out[i, 0] = dx / norm
        out[i, 1] = dy / norm
        out[i, 2] = dz / norm
    return out


def _datasheet_args(name: str, index: np.ndarray) -> tuple:
    sheet = get_sensor(name)
    pattern = get_registry().get("scan_pattern", sheet.scan_pattern.name).for_sensor(sheet)
    t, _, channel = pattern.cycle.rays(index)
    prisms = pattern.options.prisms
    wedge = np.radians([p.wedge_deg for p in prisms])
    return (t, channel, pattern._incident, np.sin(wedge), np.cos(wedge),
            np.array([p.rotor_hz for p in prisms]),
            np.array([math.radians(p.phase_deg) for p in prisms]),
            np.array([p.wedge_face == "entrance" for p in prisms]),
            np.array(pattern._index, dtype=np.float64))


def _random_geometry(seed: int, n: int) -> tuple:
    """Two to four prisms of random wedges, faces, rates, phases (some beyond 1e5 rad) and
    indices, several tilted channels, times from 0 to a day."""
    rng = np.random.default_rng(seed)
    p = int(rng.integers(2, 5))
    wedge = np.radians(rng.uniform(-35, 35, p))
    phase = rng.uniform(-np.pi, np.pi, p)
    phase[rng.random(p) < 0.3] *= 1e6
    n_ch = int(rng.integers(1, 7))
    az, el = np.radians(rng.uniform(-10, 10, n_ch)), np.radians(rng.uniform(-10, 10, n_ch))
    incident = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)
    t = np.sort(rng.uniform(0, 86_400.0, n))
    channel = rng.integers(0, n_ch, n).astype(np.int16)
    return (t, channel, incident, np.sin(wedge), np.cos(wedge), rng.uniform(-200, 200, p),
            phase, rng.random(p) < 0.5, rng.uniform(1.3, 2.2, p))


def _same_bits(args: tuple) -> None:
    new, bad = risley_directions(*args)
    old = _one_prism_at_a_time(*args)
    assert new.shape == old.shape
    assert new.tobytes() == old.tobytes()  # the same bits, NaN rows included
    assert bad == (~np.isfinite(old).all(axis=1)).sum()


@pytest.mark.parametrize("sensor", ["livox-mid70", "livox-avia", "livox-mid40"])
def test_datasheets_same_bits_as_the_one_prism_at_a_time_kernel(sensor):
    # 400 000 rays from the scan start and 100 000 a day into the scan, per datasheet
    index = np.concatenate([np.arange(400_000), 86_400 * 240_000 + np.arange(100_000)])
    _same_bits(_datasheet_args(sensor, index))


@pytest.mark.parametrize("seed", range(6))
def test_random_prism_geometries_same_bits(seed):
    args = _random_geometry(seed, 100_000 + 37 * seed)  # blocks cut at different places
    _same_bits(args)
    new, _ = risley_directions(*args)
    assert np.isnan(new).any(axis=1).sum() == np.isnan(new).all(axis=1).sum()


def test_total_reflection_gives_nan_rows_as_before():
    # a steep wedge of high index: some roll angles reflect the beam inside the second prism
    t = np.linspace(0.0, 1.0, 3 * BLOCK + 5)
    args = (t, np.zeros(len(t), dtype=np.int16), np.array([[1.0, 0.0, 0.0]]),
            np.sin(np.radians([35.0, 35.0])), np.cos(np.radians([35.0, 35.0])),
            np.array([3.0, -5.0]), np.zeros(2), np.array([False, True]), np.array([1.7, 1.7]))
    out, _ = risley_directions(*args)
    assert 0 < np.isnan(out[:, 0]).sum() < len(t)
    _same_bits(args)


def test_short_and_empty_batches():
    for n in (0, 1, BLOCK - 1, BLOCK, BLOCK + 1):
        _same_bits(_datasheet_args("livox-mid70", np.arange(n, dtype=np.int64)))
