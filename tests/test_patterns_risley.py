"""The Risley-prism pattern: Snell's law, single-prism optics, the MID-70/MID-40/Avia datasheet
figures (FOV, petal rate) and the paraxial limit (the seed paper's rose)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from patterns_support import build, make_sheet

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.patterns.geometry import az_el_from_directions, off_axis_angle
from lidarsim_core.patterns.optics import refract, tilted_normal
from lidarsim_core.plugins.resolve import get_sensor, pattern_for


# ---- vector Snell's law -------------------------------------------------------------------
def test_refraction_obeys_snell_and_stays_in_the_plane_of_incidence():
    rng = np.random.default_rng(3)
    d = rng.normal(size=(2000, 3))
    d[:, 0] = np.abs(d[:, 0]) + 0.5
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    n = tilted_normal(0.3, rng.uniform(0, 2 * np.pi, 2000))
    for n1, n2 in ((1.0, 1.5), (1.5, 1.0), (1.0, 2.4)):
        out = refract(d, n, n1 / n2)
        ok = np.all(np.isfinite(out), axis=1)
        sin_i = np.linalg.norm(np.cross(d, n), axis=1)
        sin_t = np.linalg.norm(np.cross(out[ok], n[ok]), axis=1)
        np.testing.assert_allclose(n1 * sin_i[ok], n2 * sin_t, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(out[ok], axis=1), 1.0, atol=1e-12)
        # coplanar with the incident ray and the normal
        np.testing.assert_allclose(np.einsum("ij,ij->i", np.cross(d[ok], n[ok]), out[ok]), 0.0,
                                   atol=1e-12)
        # total internal reflection exactly where n1 sin θi > n2
        np.testing.assert_array_equal(~ok, n1 * sin_i > n2)


def test_normal_incidence_passes_straight():
    d = np.array([[1.0, 0.0, 0.0]])
    np.testing.assert_allclose(refract(d, np.array([1.0, 0, 0]), 1 / 1.5), d)


@pytest.mark.parametrize("face", ["exit", "entrance"])
def test_single_prism_deviation_matches_the_prism_formula(face):
    alpha, n = 20.0, 1.5
    pattern = build(make_sheet("risley", {"prisms": [{"wedge_deg": alpha, "rotor_hz": 10,
                                                      "wedge_face": face}],
                                          "refractive_index": n}, fov_h_deg=60))
    a = math.radians(alpha)
    if face == "exit":  # normal incidence on the flat face, refraction at the tilted one
        expected = math.asin(n * math.sin(a)) - a
    else:  # refraction into the tilted face, then out through the flat one
        inside = a - math.asin(math.sin(a) / n)
        expected = math.asin(n * math.sin(inside))
    batch = pattern.rays(0.0, 0.1)
    np.testing.assert_allclose(off_axis_angle(batch.direction), expected, atol=1e-12)


def test_paraxial_limit_is_the_sum_of_thin_prism_deviations():
    """Thin wedges deviate by (n-1)α each, added as 2-D vectors: the rose of the seed paper."""
    alpha, n, f1, f2 = 0.5, 1.5, -77.7333, 121.5667
    pattern = build(make_sheet("risley", {
        "prisms": [{"wedge_deg": alpha, "rotor_hz": f1}, {"wedge_deg": alpha, "rotor_hz": f2}],
        "refractive_index": n}, fov_h_deg=10, rate=100_000))
    batch = pattern.rays(0.0, 0.02)
    rolls = pattern.prism_rolls(batch.t)
    # a tilted face normal leaning toward ψ bends the beam toward ψ + π
    delta = math.radians((n - 1) * alpha)
    expected = -delta * (np.exp(1j * rolls[:, 0]) + np.exp(1j * rolls[:, 1]))
    got = batch.direction[:, 1] + 1j * batch.direction[:, 2]
    assert np.max(np.abs(got - expected)) < 2e-3 * 2 * delta


def test_total_internal_reflection_is_a_config_error():
    sheet = make_sheet("risley", {"prisms": [{"wedge_deg": 45, "rotor_hz": 10},
                                             {"wedge_deg": 45, "rotor_hz": -7}],
                                  "refractive_index": 1.8}, fov_h_deg=170)
    with pytest.raises(ConfigError, match="totally reflect"):
        build(sheet)


# ---- the catalogue's Livox sensors ---------------------------------------------------------
@pytest.fixture(scope="module")
def mid70():
    return pattern_for(get_sensor("livox-mid70"))


@pytest.fixture(scope="module")
def mid70_second(mid70):
    return mid70.rays(0.0, 1.0)


def test_mid70_maximum_off_axis_angle(mid70, mid70_second):
    # datasheet: 70.4° circular FOV, i.e. 35.2° from the boresight
    assert math.degrees(mid70.max_off_axis_rad()) == pytest.approx(35.2, abs=0.1)
    assert math.degrees(off_axis_angle(mid70_second.direction).max()) == pytest.approx(35.2,
                                                                                       abs=0.1)
    assert mid70.max_off_axis_rad() <= mid70.sensor.half_fov_h_rad


def test_mid70_passes_through_the_centre(mid70_second):
    # equal wedges cancel when opposed: the rosette's petals meet on the boresight
    assert math.degrees(off_axis_angle(mid70_second.direction).min()) < 0.1


def test_mid70_petal_tip_rate(mid70, mid70_second):
    """Petal tips (local maxima of the off-axis angle) come at |f1| + |f2| = 199.3 Hz."""
    theta = off_axis_angle(mid70_second.direction)
    interior = theta[1:-1]
    tips = (interior > theta[:-2]) & (interior >= theta[2:]) & (interior > 0.9 * theta.max())
    t_tips = mid70_second.t[1:-1][tips]
    rate = (len(t_tips) - 1) / (t_tips[-1] - t_tips[0])
    assert rate == pytest.approx(199.3, rel=0.01)
    assert np.diff(t_tips).std() < 2e-5  # evenly spaced, one every 5.02 ms
    assert abs(mid70.options.prisms[0].rotor_hz) + abs(mid70.options.prisms[1].rotor_hz) == \
        pytest.approx(199.3, rel=1e-4)


def test_mid70_pattern_does_not_repeat_within_a_second(mid70_second):
    # non-repetitive: the rosette half a second later is not the same rosette
    first = mid70_second.direction[:1000]
    later = mid70_second.direction[50_000:51_000]
    assert np.max(np.linalg.norm(first - later, axis=1)) > 0.1


def test_mid40_fov():
    pattern = pattern_for(get_sensor("livox-mid40"))
    assert math.degrees(pattern.max_off_axis_rad()) == pytest.approx(19.2, abs=0.1)


def test_avia_six_channels_fill_its_rectangular_fov():
    pattern = pattern_for(get_sensor("livox-avia"))
    batch = pattern.rays(0.0, 0.5)
    az, el = az_el_from_directions(batch.direction)
    # datasheet: 70.4° × 77.2°, reached to within 0.1° and never exceeded
    assert math.degrees(np.abs(az).max()) == pytest.approx(35.2, abs=0.1)
    assert math.degrees(np.abs(el).max()) == pytest.approx(38.6, abs=0.1)
    assert pattern.inside_fov(batch.direction).all()
    np.testing.assert_array_equal(np.bincount(batch.channel), np.full(6, len(batch) // 6))
    # interleaved firing: the channels fire in turn, one ray every 1/240,000 s
    np.testing.assert_array_equal(batch.channel[:12], np.tile(np.arange(6), 2))
    np.testing.assert_allclose(np.diff(batch.t[:12]), 1 / 240_000)


def test_simultaneous_channels_share_their_firing_time():
    sheet = make_sheet("risley", {"prisms": [{"wedge_deg": 5, "rotor_hz": 20},
                                             {"wedge_deg": 5, "rotor_hz": -13}],
                                  "channels": [{}, {"elevation_deg": 2}, {"elevation_deg": -2}],
                                  "channel_firing": "simultaneous"}, fov_h_deg=40, rate=3000)
    batch = build(sheet).rays(0.0, 0.01)
    assert len(batch) == 30
    np.testing.assert_allclose(batch.t.reshape(10, 3), np.repeat(np.arange(10) / 1000, 3)
                               .reshape(10, 3))
    # the channel offsets survive the prisms: three distinct beams at every instant
    d = batch.direction.reshape(10, 3, 3)
    assert np.min(np.linalg.norm(d[:, 0] - d[:, 1], axis=1)) > 0.01
