"""Raster, Lissajous and flash patterns: geometry and timing against their definitions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from patterns_support import build, make_sheet

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.patterns.geometry import az_el_from_directions
from lidarsim_core.plugins.resolve import get_sensor, pattern_for

RECT = dict(fov_type="rectangular", fov_h_deg=30.0, fov_v_deg=20.0, rate=1000.0)


# ---- raster -----------------------------------------------------------------------------
def test_raster_cells_and_boustrophedon_order():
    pattern = build(make_sheet("raster", {"rows": 4, "columns": 6}, **RECT))
    batch = pattern.rays(0.0, 24e-3)
    az, el = np.degrees(az_el_from_directions(batch.direction))
    # cell centres: 5° columns from +12.5 to -12.5, 5° rows from +7.5 to -7.5
    np.testing.assert_allclose(az[:6], [12.5, 7.5, 2.5, -2.5, -7.5, -12.5], atol=1e-9)
    np.testing.assert_allclose(az[6:12], az[:6][::-1], atol=1e-9)  # second line runs back
    np.testing.assert_allclose(el.reshape(4, 6), np.repeat([[7.5], [2.5], [-2.5], [-7.5]], 6, 1),
                               atol=1e-9)
    assert pattern.shape == (4, 6)


def test_unidirectional_vertical_lines_with_retrace_timing():
    opts = {"rows": 3, "columns": 2, "line_axis": "vertical", "bidirectional": False,
            "line_retrace_s": 0.5e-3, "frame_retrace_s": 2e-3}
    pattern = build(make_sheet("raster", opts, **RECT))
    batch = pattern.rays(0.0, 2 * pattern.cycle.period_s)
    # line = 3 pulses 1 ms apart + 0.5 ms retrace; frame = 2 lines + 2 ms
    t = batch.t[:6] * 1e3
    np.testing.assert_allclose(t, [0, 1, 2, 3.5, 4.5, 5.5], atol=1e-9)
    assert pattern.cycle.period_s == pytest.approx((6 + 0.5 + 2) * 1e-3)
    assert batch.t[6] == pytest.approx(pattern.cycle.period_s)
    az, el = np.degrees(az_el_from_directions(batch.direction[:6]))
    np.testing.assert_allclose(el, [20 / 3, 0, -20 / 3] * 2, atol=1e-9)  # top to bottom, twice
    np.testing.assert_allclose(az, [7.5] * 3 + [-7.5] * 3, atol=1e-9)


def test_raster_from_angular_steps_and_frame_rate():
    opts = {"row_step_deg": 3.0, "column_step_deg": 4.0, "frame_rate_hz": 10}
    pattern = build(make_sheet("raster", opts, **RECT))
    assert pattern.shape == (6, 7)  # floor(20/3), floor(30/4)
    az, el = np.degrees(az_el_from_directions(pattern.rays(0.0, 0.042).direction))
    np.testing.assert_allclose(np.unique(np.round(az, 9)), (np.arange(7) - 3) * 4.0)
    assert pattern.cycle.period_s == pytest.approx(0.1)
    with pytest.raises(ConfigError, match="longer than 1/frame_rate_hz"):
        build(make_sheet("raster", {**opts, "frame_rate_hz": 30}, **RECT))
    with pytest.raises(ConfigError, match="exactly one of rows or row_step_deg"):
        build(make_sheet("raster", {"rows": 3, "row_step_deg": 1.0, "columns": 2}, **RECT))


# ---- Lissajous --------------------------------------------------------------------------
def test_lissajous_follows_its_equations_and_fills_the_fov():
    opts = {"azimuth_hz": 49, "elevation_hz": 50}
    pattern = build(make_sheet("lissajous", opts, **{**RECT, "rate": 20_000.0}))
    batch = pattern.rays(0.0, 1.0)
    az, el = az_el_from_directions(batch.direction)
    np.testing.assert_allclose(az, math.radians(15) * np.sin(2 * np.pi * 49 * batch.t),
                               atol=1e-12)
    np.testing.assert_allclose(el, math.radians(10) * np.cos(2 * np.pi * 50 * batch.t),
                               atol=1e-12)
    assert math.degrees(np.abs(az).max()) == pytest.approx(15, abs=0.01)
    # gcd(49, 50) = 1: the figure repeats after exactly one second
    again = pattern.rays(1.0, 1.01)
    np.testing.assert_allclose(again.direction, batch.direction[:200], atol=1e-9)


def test_lissajous_amplitude_beyond_the_fov_is_an_error():
    sheet = make_sheet("lissajous", {"azimuth_hz": 5, "elevation_hz": 7,
                                     "azimuth_amplitude_deg": 16}, **RECT)
    with pytest.raises(ConfigError, match="exceeds half the datasheet FOV"):
        build(sheet)


# ---- flash ------------------------------------------------------------------------------
def test_vns_flash_frames_share_one_time_per_frame():
    pattern = pattern_for(get_sensor("ball-vns-flash"))
    batch = pattern.rays(0.0, 0.1)  # three frames at 30 Hz
    assert len(batch) == 3 * 256 * 256
    frames = batch.t.reshape(3, 256 * 256)
    np.testing.assert_array_equal(frames, frames[:, :1] * np.ones((1, 256 * 256)))
    np.testing.assert_allclose(frames[:, 0], [0, 1 / 30, 2 / 30])
    np.testing.assert_array_equal(batch.direction[: 256 * 256], batch.direction[256 * 256:
                                                                                2 * 256 * 256])
    assert np.all(batch.channel == 0)


def test_pinhole_flash_pixels_are_equally_spaced_in_the_focal_plane():
    pattern = build(make_sheet("flash", {"rows": 4, "columns": 5},
                               **{**RECT, "rate": 20 * 30.0}))
    d = pattern.rays(0.0, 1 / 30).direction
    y, z = d[:, 1] / d[:, 0], d[:, 2] / d[:, 0]
    tan_h, tan_v = math.tan(math.radians(15)), math.tan(math.radians(10))
    np.testing.assert_allclose(y[:5], tan_h * np.array([0.8, 0.4, 0.0, -0.4, -0.8]), atol=1e-12)
    np.testing.assert_allclose(z[::5], tan_v * np.array([0.75, 0.25, -0.25, -0.75]), atol=1e-12)
    assert pattern.inside_fov(d).all()


def test_flash_faster_than_the_datasheet_rate_is_an_error():
    with pytest.raises(ConfigError, match="more than the datasheet point_rate_hz"):
        build(make_sheet("flash", {"rows": 10, "columns": 10, "frame_rate_hz": 100}, **RECT))
