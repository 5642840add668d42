"""The seed paper's rose pattern r = A·sin(B·φ) with a rotation after every turn."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import datasheet
from scipy.signal import find_peaks

from lidarsim_core.patterns.geometry import off_axis_angle
from lidarsim_core.patterns.rose import RosePattern
from lidarsim_core.scenario.datasheet import SensorDatasheet


def _pattern(**options) -> RosePattern:
    sheet = SensorDatasheet.model_validate(datasheet(point_rate_hz=100000.0, fov_h_deg=70.4,
                                                     fov_v_deg=70.4))
    return RosePattern.for_sensor(sheet, {"turn_period_s": 0.04, **options})


@pytest.mark.parametrize("b, petals", [(4, 8), (5, 5), (6, 12), (3, 3)])
def test_petal_count_per_turn(b, petals):
    pattern = _pattern(b=b)
    rays = pattern.rays(0.0, 0.04)
    r = off_axis_angle(rays.direction)
    assert pattern.petals_per_turn == petals
    # each petal tip reaches r = A once per traversal; odd B traces every petal twice per turn
    tips, _ = find_peaks(np.concatenate([[0], r, [0]]), height=0.99 * pattern.amplitude_rad)
    assert len(tips) == (petals if b % 2 == 0 else 2 * petals)
    # distinct tip directions (roll angle of the tips) = petal count
    tip_dirs = rays.direction[tips - 1]
    roll = np.degrees(np.arctan2(tip_dirs[:, 2], tip_dirs[:, 1])) % 360
    assert len(np.unique(np.round(roll, 0) % 360)) == petals


def test_rays_stay_inside_the_fov_and_reach_its_edge():
    pattern = _pattern()
    rays = pattern.rays(0.0, 0.5)
    theta = off_axis_angle(rays.direction)
    assert theta.max() <= np.radians(35.2) + 1e-12
    assert theta.max() > np.radians(35.2) - 1e-3
    np.testing.assert_allclose(np.linalg.norm(rays.direction, axis=1), 1.0, atol=1e-12)
    assert pattern.inside_fov(rays.direction).all()


def test_consecutive_rosettes_differ_by_the_configured_rotation():
    pattern = _pattern(rotation_per_turn_deg=5.0)
    per_turn = int(round(0.04 * 100000))
    first = pattern.rays_for_indices(np.arange(0, per_turn))
    second = pattern.rays_for_indices(np.arange(per_turn, 2 * per_turn))
    # rotating the first rosette by +5 deg about the boresight gives the second
    from scipy.spatial.transform import Rotation

    rotated = Rotation.from_euler("x", 5.0, degrees=True).apply(first.direction)
    np.testing.assert_allclose(rotated, second.direction, atol=1e-9)


def test_timestamps_follow_the_point_rate_and_chunks_are_identical():
    pattern = _pattern()
    whole = pattern.rays(0.0, 0.1)
    assert len(whole) == 10000
    np.testing.assert_allclose(np.diff(whole.t), 1e-5, rtol=1e-9)
    parts = [pattern.rays(a, b) for a, b in ((0.0, 0.0333), (0.0333, 0.07), (0.07, 0.1))]
    np.testing.assert_array_equal(np.concatenate([p.index for p in parts]), whole.index)
    np.testing.assert_array_equal(np.concatenate([p.direction for p in parts]), whole.direction)
