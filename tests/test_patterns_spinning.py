"""The spinning multi-channel pattern against the Velodyne and Ouster datasheets."""

from __future__ import annotations

import math

import numpy as np
import pytest
from patterns_support import build, make_sheet

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.patterns.geometry import az_el_from_directions
from lidarsim_core.plugins.resolve import get_sensor, pattern_for

# VLP-16 User Manual: laser IDs 0..15 in firing order, their vertical angles, and the timing
VLP16_ELEVATIONS = [-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15]
VLP16_FIRING_S = 2.304e-6
VLP16_CYCLE_S = 55.296e-6


@pytest.fixture(scope="module")
def vlp16():
    return pattern_for(get_sensor("velodyne-vlp16"))


@pytest.fixture(scope="module")
def vlp16_rev(vlp16):
    return vlp16.rays(0.0, 0.1)  # one revolution at 10 Hz


def test_vlp16_has_16_rings_at_the_datasheet_elevations(vlp16_rev):
    _, el = az_el_from_directions(vlp16_rev.direction)
    for laser, expected in enumerate(VLP16_ELEVATIONS):
        ring = np.degrees(el[vlp16_rev.channel == laser])
        np.testing.assert_allclose(ring, expected, atol=1e-9)
    rings = np.unique(np.round(np.degrees(el), 6))
    np.testing.assert_allclose(rings, np.arange(-15, 16, 2))


def test_vlp16_firing_timing(vlp16, vlp16_rev):
    t, ch = vlp16_rev.t, vlp16_rev.channel
    # within a cycle lasers 0..15 fire in order, 2.304 µs apart; cycles every 55.296 µs
    np.testing.assert_array_equal(ch[:32], np.tile(np.arange(16), 2))
    np.testing.assert_allclose(t[:16], np.arange(16) * VLP16_FIRING_S, rtol=0, atol=1e-15)
    np.testing.assert_allclose(t[16:32] - t[:16], VLP16_CYCLE_S, rtol=1e-12)
    for laser in range(16):
        np.testing.assert_allclose(np.diff(t[ch == laser]), VLP16_CYCLE_S, rtol=1e-9)
    # 18.432 µs recharge after the 16th firing
    assert t[16] - t[15] == pytest.approx(VLP16_CYCLE_S - 15 * VLP16_FIRING_S, rel=1e-12)
    assert vlp16.mean_rate_hz == pytest.approx(16 / VLP16_CYCLE_S, rel=1e-12)
    full = math.floor(0.1 / VLP16_CYCLE_S)
    partial = math.ceil((0.1 - full * VLP16_CYCLE_S) / VLP16_FIRING_S)
    assert len(vlp16_rev) == full * 16 + partial  # 1808 cycles and 11 lasers of the next


def test_vlp16_turns_clockwise_at_10_hz(vlp16_rev):
    az, _ = az_el_from_directions(vlp16_rev.direction)
    laser0 = vlp16_rev.channel == 0
    step = np.angle(np.exp(1j * np.diff(az[laser0])))
    # 360° × 10 Hz × 55.296 µs = 0.199° per cycle, azimuth decreasing (clockwise from above)
    np.testing.assert_allclose(np.degrees(step), -360 * 10 * VLP16_CYCLE_S, rtol=1e-9)
    # the head advances between two lasers of one cycle too
    first = az_el_from_directions(vlp16_rev.direction[:2])[0]
    assert math.degrees(first[1] - first[0]) == pytest.approx(-360 * 10 * VLP16_FIRING_S,
                                                              rel=1e-9)


def test_hdl32e_interleaved_firing_order():
    pattern = pattern_for(get_sensor("velodyne-hdl32e"))
    batch = pattern.rays(0.0, 46.08e-6)
    _, el = az_el_from_directions(batch.direction)
    expected = [-30.67, -9.33, -29.33, -8.00, -28.00, -6.66, -26.66, -5.33]
    np.testing.assert_allclose(np.degrees(el[:8]), expected, atol=1e-9)
    np.testing.assert_allclose(np.diff(batch.t), 1.152e-6, rtol=1e-9)
    assert len(batch) == 32


def test_ouster_columns_fire_all_beams_together_with_staggered_azimuths():
    pattern = pattern_for(get_sensor("ouster-os1-64"))
    batch = pattern.rays(0.0, 0.1)
    assert len(batch) == 64 * 2048  # 2048 columns per turn at 10 Hz
    t = batch.t.reshape(2048, 64)
    np.testing.assert_array_equal(t, np.repeat(t[:, :1], 64, axis=1))
    np.testing.assert_allclose(np.diff(t[:, 0]), 1 / 20480, rtol=1e-9)
    az, el = az_el_from_directions(batch.direction[:64])
    np.testing.assert_allclose(np.degrees(az[:4]), [3.164, 1.055, -1.055, -3.164], atol=1e-9)
    assert np.degrees(el).max() == pytest.approx(16.6) and np.degrees(el).min() == \
        pytest.approx(-16.6)


def test_default_cycle_follows_the_point_rate():
    sheet = make_sheet("spinning", {"elevations_deg": [-1, 0, 1], "firing_interval_s": 1e-6},
                       fov_type="panoramic", fov_h_deg=360, fov_v_deg=4, rate=30_000)
    pattern = build(sheet)
    assert pattern.cycle.period_s == pytest.approx(1e-4)
    assert len(pattern.rays(0, 1.0)) == 30_000


@pytest.mark.parametrize("options, match", [
    ({"elevations_deg": [0, 1], "firing_order": [0, 0]}, "firing_order"),
    ({"elevations_deg": [0, 1], "azimuth_offsets_deg": [1.0]}, "azimuth_offsets_deg"),
    ({"elevations_deg": [0, 1], "firing_interval_s": 1e-6, "cycle_period_s": 1e-6},
     "not before the end"),
    ({"elevations_deg": [0, 1], "cycle_period_s": 1e-9}, "more than the datasheet"),
])
def test_bad_spinning_options_are_config_errors(options, match):
    sheet = make_sheet("spinning", options, fov_type="panoramic", fov_h_deg=360, fov_v_deg=4)
    with pytest.raises(ConfigError, match=match):
        build(sheet)
