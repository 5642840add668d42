"""Organised range images: shapes from the datasheets, every pixel equal to its point, the
layout checked against the points' own timestamps and directions, and the NPZ + 16-bit PNG."""

from __future__ import annotations

import math

import numpy as np
import pytest

import lidarsim_core as ls
from lidarsim_core.scenario import demo_target_pose
from lidarsim_core.scenario import scenario_from_dict


def _simulate(sensor: str, duration_s: float) -> tuple[ls.Simulation, ls.PointCloud]:
    scenario = scenario_from_dict({
        "seed": 1, "sensor": {"datasheet": sensor},
        "targets": [{"name": "envisat", "mesh": {"model": "envisat",
                                                  "options": {"detail": "coarse"}},
                     "pose": demo_target_pose(20.0)}],
        "scan": {"duration_s": duration_s}, "backend": {"name": "numpy"}})
    sim = ls.Simulation(scenario)
    return sim, sim.run_frame(0)


def _every_point_in_its_pixel(cloud: ls.PointCloud, image) -> np.ndarray:
    """Rows of the cloud in the image; each pixel's range/intensity/part equal its point's."""
    hit = image.point_index >= 0
    rows = image.point_index[hit]
    np.testing.assert_array_equal(image.range[hit], cloud["range"][rows])
    np.testing.assert_array_equal(image.intensity[hit], cloud["intensity"][rows])
    np.testing.assert_array_equal(image.part[hit], cloud["part"][rows])
    assert np.all(np.isnan(image.range[~hit])) and np.all(image.part[~hit] == -1)
    first = np.flatnonzero((cloud["detected"] == 1) & (cloud["return_number"] <= 1))
    assert sorted(rows.tolist()) == first.tolist()  # every first return once, nothing else
    return rows


def test_vlp16_is_16_channels_by_the_columns_of_one_revolution():
    sheet = ls.get_sensor("velodyne-vlp16")
    options = sheet.scan_pattern.options
    revolution = 1.0 / options["rotation_hz"]
    sim, cloud = _simulate("velodyne-vlp16", revolution)
    image = cloud.range_image(sim.pattern)
    columns = math.ceil(revolution / options["cycle_period_s"])  # firing cycles per turn
    assert image.shape == (16, columns) and image.layout == "spinning"
    assert len(cloud) > 300
    rows = _every_point_in_its_pixel(cloud, image)
    # rows: channels by elevation, highest first; columns: the firing cycle of each point
    elevations = np.asarray(options["elevations_deg"])[image.row_channel]
    assert np.all(np.diff(elevations) < 0)
    r, c = np.nonzero(image.point_index >= 0)
    np.testing.assert_array_equal(image.row_channel[r], cloud["channel"][rows])
    cycle = np.floor((cloud["timestamp"][rows] - cloud.frame.t_start) / options["cycle_period_s"]
                     + 1e-6)
    np.testing.assert_array_equal(c, cycle)
    # the default pattern (catalogue datasheet) gives the same image
    np.testing.assert_array_equal(cloud.range_image().point_index, image.point_index)


def test_flash_is_the_256_by_256_detector_array():
    sim, cloud = _simulate("ball-vns-flash", 1.0 / 30.0)
    image = cloud.range_image(sim.pattern)
    assert image.shape == (256, 256) and image.layout == "flash"
    rows = _every_point_in_its_pixel(cloud, image)
    assert len(rows) > 1000
    r, c = np.nonzero(image.point_index >= 0)
    # row-major from the top left: elevation falls down the rows, azimuth (+Y = left) falls
    # along the columns
    elevation, azimuth = cloud["elevation"][rows], cloud["azimuth"][rows]
    assert np.corrcoef(r, elevation)[0, 1] < -0.99 and np.corrcoef(c, azimuth)[0, 1] < -0.99


def test_raster_is_lines_by_samples():
    sim, cloud = _simulate("opromolla2015-space-lidar", 1.0)
    image = cloud.range_image(sim.pattern)
    assert image.shape == sim.pattern.shape == (100, 100) and image.layout == "raster"
    rows = _every_point_in_its_pixel(cloud, image)
    _, c = np.nonzero(image.point_index >= 0)
    # bidirectional lines turned round: column order follows azimuth on every line
    assert np.corrcoef(c, cloud["azimuth"][rows])[0, 1] < -0.99


def test_saved_npz_and_16_bit_png(tmp_path):
    from PIL import Image

    sim, cloud = _simulate("ball-vns-flash", 1.0 / 30.0)
    image = cloud.range_image(sim.pattern)
    npz, png = image.save(tmp_path / "flash")
    assert (npz.name, png.name) == ("flash.npz", "flash.png")
    with np.load(npz) as data:
        np.testing.assert_array_equal(data["range"], image.range)
        np.testing.assert_array_equal(data["point_index"], image.point_index)
        scale = float(data["range_scale_m"])
    read = Image.open(png)
    assert read.mode.startswith("I;16") or read.mode == "I"
    assert float(read.text["range_scale_m"]) == scale == 1e-3
    pixels = np.asarray(read, dtype=np.int64)
    hit = np.isfinite(image.range)
    np.testing.assert_array_equal(pixels[hit], np.round(image.range[hit] / scale))
    assert np.all(pixels[~hit] == 0)


def test_layouts_are_refused_when_they_do_not_apply():
    sim, cloud = _simulate("velodyne-vlp16", 0.25)
    with pytest.raises(ls.ConfigError, match="revolutions"):
        cloud.range_image(sim.pattern)
    sim, cloud = _simulate("velodyne-vlp16", 0.1)
    other = ls.Simulation(sim.scenario.with_updates(sensor={"datasheet": "ouster-os1-16"}))
    with pytest.raises(ls.ConfigError, match="not this scan pattern's"):
        cloud.range_image(other.pattern)  # another 16-channel head: directions differ
    rose = ls.Simulation(ls.demo_scenario(duration_s=0.01, backend="numpy", detail="coarse"))
    with pytest.raises(ls.ConfigError, match="no regular layout"):
        rose.run_frame(0).range_image(rose.pattern)


def test_simulate_range_image_option_writes_npz_and_png(tmp_path):
    import os
    import subprocess
    import sys

    import yaml

    scenario = tmp_path / "vlp.yaml"
    scenario.write_text(yaml.safe_dump({
        "seed": 1, "sensor": {"datasheet": "velodyne-vlp16"},
        "targets": [{"name": "envisat", "mesh": {"model": "envisat",
                                                  "options": {"detail": "coarse"}},
                     "pose": {"position_m": [15.0, 0.0, 0.0]}}],
        "scan": {"duration_s": 0.1}, "backend": {"name": "numpy"}}))
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1"}
    res = subprocess.run([sys.executable, "-m", "lidarsim_core", "simulate", str(scenario),
                          "--out", str(tmp_path / "cloud.npz"), "--range-image"],
                         capture_output=True, text=True, env=env, timeout=300)
    assert res.returncode == 0, res.stderr
    cloud = ls.read(tmp_path / "cloud.npz")
    with np.load(tmp_path / "cloud.range.npz") as data:
        hit = data["point_index"] >= 0
        assert data["range"].shape[0] == 16
        np.testing.assert_array_equal(data["range"][hit], cloud["range"][data["point_index"][hit]])
    assert (tmp_path / "cloud.range.png").stat().st_size > 0
