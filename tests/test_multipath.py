"""Multipath ghosts: a flat mirror at 45° in front of a diffuse wall puts every ghost at the
mirror image of its wall point with range d1 + d2; a rough mirror's ghost intensity follows
the closed-form coupling as it tilts; off by default; reproducible across chunks and threads."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import datasheet

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.pipeline import Simulation
from lidarsim_core.scenario import scenario_from_dict

MIRROR_AT = np.array([10.0, 0.0, 0.0])
WALL_Y = -6.0
WALL_RHO = 0.8


def _scene(*, yaw_deg=45.0, slope_deg=0.001, multipath=True, detection=None, returns="multi",
           sub_rays=None, noise=(), acceptance_deg=0.05, **extra):
    sheet = datasheet(fov_h_deg=2.0, fov_v_deg=2.0, range_max_m=130.0, range_min_m=0.05,
                      range_at_reflectivity=[{"reflectivity": 0.1, "range_m": 90.0}],
                      range_resolution_m=0.3, beam_divergence_deg=[0.1, 0.1])
    sensor = {"datasheet": sheet, "detection": detection or {"range_max_m": 500.0},
              "returns": {"mode": returns, "max_returns": 3}}
    if multipath:
        sensor["multipath"] = {"max_bounces": 2, "acceptance_deg": acceptance_deg}
    if sub_rays:
        sensor["beam"] = {"sub_rays": sub_rays}
    data = {
        "seed": 3, "sensor": sensor, "scan": {"duration_s": 0.1}, "backend": "numpy",
        "noise": list(noise),
        "targets": [
            {"name": "mirror", "mesh": {"model": "plate", "options": {"size_m": [1.5, 1.5]}},
             "pose": {"position_m": MIRROR_AT.tolist(), "euler_deg": [0, 0, yaw_deg]},
             "materials": {"plate": {"diffuse_reflectivity": 0.0, "specular_reflectance": 0.9,
                                     "specular_slope_deg": slope_deg}}},
            {"name": "wall", "mesh": {"model": "plate", "options": {"size_m": [40, 40]}},
             "pose": {"position_m": [10.0, WALL_Y, 0.0], "euler_deg": [0, 0, 90]},
             "materials": {"plate": {"diffuse_reflectivity": WALL_RHO}}}],
        **extra,
    }
    return scenario_from_dict(data)


def _mirror_normal(yaw_deg):
    a = math.radians(yaw_deg)
    return np.array([math.cos(a), math.sin(a), 0.0])


def test_flat_mirror_ghosts_lie_at_the_mirror_image_of_the_wall():
    cloud = Simulation(_scene()).run_frame(0)
    ghost = cloud["bounces"] == 1
    assert ghost.sum() > 500
    assert set(cloud["target"][ghost].tolist()) == {1}  # the wall, seen through the mirror
    x = np.stack([cloud["x"], cloud["y"], cloud["z"]], axis=1)[ghost]
    q = np.stack([cloud["x_true"], cloud["y_true"], cloud["z_true"]], axis=1)[ghost]
    # the true point is on the wall ...
    np.testing.assert_allclose(q[:, 1], WALL_Y, atol=1e-9)
    # ... and the reported point is its mirror image through the mirror's plane
    n = _mirror_normal(45.0)
    image = q - 2.0 * ((q - MIRROR_AT) @ n)[:, None] * n
    np.testing.assert_allclose(x, image, atol=1e-9)
    # range = d1 + d2: the mirror hit along the ray, then on to the wall point
    u = x / np.linalg.norm(x, axis=1)[:, None]
    d1 = (MIRROR_AT @ n) / (u @ n)
    p = u * d1[:, None]
    d2 = np.linalg.norm(q - p, axis=1)
    np.testing.assert_allclose(cloud["range"][ghost], d1 + d2, rtol=0, atol=1e-9)
    np.testing.assert_allclose(cloud["range_true"][ghost], d1 + d2, rtol=0, atol=1e-9)
    # intensity: κ² ρ cos θ2 with κ = F for a flat mirror (θ2 = 0 here)
    kappa = 0.9 * -math.expm1(-math.tan(math.radians(0.025)) ** 2
                               / (math.tan(math.radians(0.001)) ** 2 * math.cos(math.pi / 4)))
    cos2 = np.abs((q - p)[:, 1]) / d2
    np.testing.assert_allclose(cloud["intensity"][ghost], kappa ** 2 * WALL_RHO * cos2,
                               rtol=1e-6)


def test_no_ghosts_without_multipath():
    cloud = Simulation(_scene(multipath=False)).run_frame(0)
    assert "bounces" not in cloud.columns
    assert not (cloud["target"] == 1).any()  # the wall is behind the sensor's view


@pytest.mark.parametrize("yaw_deg", [30.0, 40.0, 45.0, 52.0, 60.0])
def test_rough_mirror_ghost_energy_follows_the_lobe_as_it_tilts(yaw_deg):
    slope, gamma = 0.04, 0.05  # lobe comparable to the receiver acceptance
    cloud = Simulation(_scene(yaw_deg=yaw_deg, slope_deg=slope, acceptance_deg=gamma,
                              detection={"range_max_m": 500.0, "keep_undetected": True})
                       ).run_frame(0)
    ghost = cloud["bounces"] == 1
    assert ghost.sum() > 500
    n = _mirror_normal(yaw_deg)
    x = np.stack([cloud["x"], cloud["y"], cloud["z"]], axis=1)[ghost]
    u = x / np.linalg.norm(x, axis=1)[:, None]
    cos1 = np.abs(u @ n)  # incidence on the mirror
    d = u - 2.0 * (u @ n)[:, None] * n  # mirror direction
    cos2 = np.abs(d[:, 1])  # incidence on the wall (normal ±y)
    t2 = math.tan(math.radians(gamma / 2)) ** 2
    m2 = math.tan(math.radians(slope)) ** 2
    kappa = 0.9 * (1.0 - np.exp(-t2 / (m2 * cos1)))
    np.testing.assert_allclose(cloud["intensity"][ghost], kappa ** 2 * WALL_RHO * cos2,
                               rtol=2e-6)


def test_ghost_energy_varies_with_tilt_as_predicted():
    """The coupling rises as the mirror turns to grazing (the lobe, foreshortened by
    cos θ, fits the acceptance better): compare the mean ghost intensity ratio."""
    means = {}
    for yaw in (30.0, 60.0):
        cloud = Simulation(_scene(yaw_deg=yaw, slope_deg=0.04,
                                  detection={"range_max_m": 500.0, "keep_undetected": True})
                           ).run_frame(0)
        ghost = cloud["bounces"] == 1
        means[yaw] = float(np.median(cloud["intensity"][ghost]))
    t = math.tan(math.radians(0.025)) ** 2 / math.tan(math.radians(0.04)) ** 2
    k30 = 1 - math.exp(-t / math.cos(math.radians(30)))
    k60 = 1 - math.exp(-t / math.cos(math.radians(60)))
    # θ1 = yaw for the central ray; θ2 = 90° − 2·yaw' (the wall normal is ±y)
    expected = (k60 ** 2 * math.cos(math.radians(30))) / (k30 ** 2 * math.cos(math.radians(30)))
    assert means[60.0] / means[30.0] == pytest.approx(expected, rel=0.02)


def test_multipath_needs_detection():
    with pytest.raises(ConfigError, match="sensor.multipath"):
        data = _scene().model_dump()
        data["sensor"]["detection"] = None
        Simulation(scenario_from_dict(data))


@pytest.mark.parametrize("sub_rays", [None, 8])
def test_ghosts_are_byte_identical_across_chunks_and_threads(sub_rays, monkeypatch):
    sc = _scene(sub_rays=sub_rays, noise=[{"name": "angular"}, {"name": "range"}])
    ref = Simulation(sc).run_frame(0)
    assert (ref["bounces"] > 0).sum() > 100
    for chunk, threads in ((97, "1"), (1000, "2")):
        monkeypatch.setenv("LIDARSIM_THREADS", threads)
        other = Simulation(sc).run_frame(0, chunk_rays=chunk)
        assert set(other.columns) == set(ref.columns)
        for key in ref.columns:
            assert np.array_equal(ref[key], other[key], equal_nan=True), key


def test_light_in_orbit_example_shows_every_effect():
    from pathlib import Path

    from lidarsim_core.scenario import load_scenario

    path = Path(__file__).resolve().parents[1] / "examples" / "scenarios" / "light_in_orbit.yaml"
    sim = Simulation(load_scenario(path))
    cloud = sim.run_frame(0)
    ghost = cloud["bounces"] > 0
    assert ghost.sum() > 100 and (cloud["target"][ghost] == 0).all()  # the bus, via the panel
    assert (cloud["part"] == sim.false_alarm_part).any()  # the Sun's false alarms
    link = sim.link
    # the signal the intensity stands for (within range noise) is clipped at 200
    signal = cloud["intensity"] * link.constant / cloud["range"] ** link.exponent
    assert 190 < signal.max() < 210 and (signal > 190).sum() > 10


def test_every_light_effect_with_sub_rays_is_byte_identical_across_chunks_and_threads(
        monkeypatch):
    data = _scene(sub_rays=8, noise=[{"name": "angular"}, {"name": "range"}],
                  sun={"direction": [-0.8, 0.5, 0.33], "spectral_irradiance_w_m2_nm": 0.9,
                       "noise_equivalent_irradiance_w_m2": 2.0}).model_dump()
    data["targets"][0]["materials"]["plate"]["diffuse_reflectivity"] = 0.3  # sunlit background
    data["sensor"]["receiver"] = {"saturation_signal": 50.0, "range_walk": True}
    sc = scenario_from_dict(data)
    ref = Simulation(sc).run_frame(0)
    assert (ref["bounces"] > 0).sum() > 100 and (ref["target"] == -1).sum() > 5
    for chunk, threads in ((89, "1"), (1500, "2")):
        monkeypatch.setenv("LIDARSIM_THREADS", threads)
        other = Simulation(sc).run_frame(0, chunk_rays=chunk)
        for key in ref.columns:
            assert np.array_equal(ref[key], other[key], equal_nan=True), key
