"""Sequences of frames: timing fields, per-frame poses, ground-truth pose files that agree with
the clouds, the example scenarios, and ``lidarsim poses``."""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from helpers import datasheet
from scipy.spatial.transform import Rotation, Slerp

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.io.groundtruth import read_ground_truth, write_ground_truth
from lidarsim_core.pipeline import Simulation
from lidarsim_core.pipeline.simulation import sequence_frame_infos
from lidarsim_core.records.groundtruth import pose_from_record
from lidarsim_core.scenario import ScanConfig
from lidarsim_core.scenario import load_scenario, scenario_from_dict
from lidarsim_core.trajectories.orbit import mean_motion_from_altitude

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "scenarios"
BOX = np.array([1.0, 2.0, 1.5])


def _box_residual(points: np.ndarray) -> np.ndarray:
    return np.abs(np.max(np.abs(points) / (BOX / 2), axis=1) - 1.0) * BOX.min() / 2


def _box_scene(motion: str = "per_ray", frames: int = 3) -> dict:
    """A static sensor and a box moving and turning at constant rates: its pose in the sensor
    frame is a constant-rate screw, so frame-start and frame-end poses interpolate exactly."""
    return {
        "seed": 9,
        "sensor": {"datasheet": datasheet(point_rate_hz=40_000.0),
                   "pose": {"position_m": [0.5, -0.2, 0.1], "euler_deg": [3, -2, 5]}},
        "targets": [{"name": "box",
                     "mesh": {"model": "box", "options": {"extents_m": BOX.tolist()}},
                     "trajectory": {"kind": "constant_velocity", "position_m": [9.0, 0.0, 0.0],
                                    "velocity_m_s": [-1.0, 0.8, 0.3], "euler_deg": [5, 10, 15],
                                    "angular_velocity_deg_s": [40.0, -20.0, 60.0]}}],
        "scan": {"duration_s": 0.1, "frame_rate_hz": 4, "frames": frames, "motion": motion},
        "backend": "numpy",
        "noise": [],
    }


# ---- timing ------------------------------------------------------------------------------
def test_frame_rate_and_sequence_duration_define_the_frames():
    scan = ScanConfig(duration_s=0.1, frame_rate_hz=10, sequence_duration_s=2.0, start_s=1.0)
    assert scan.frames == 20 and scan.period_s == pytest.approx(0.1)
    assert scan.frame_interval(19) == pytest.approx((2.9, 3.0))
    assert ScanConfig(duration_s=1, frame_period_s=20, sequence_duration_s=820).frames == 41
    assert ScanConfig(duration_s=1, frame_period_s=20, sequence_duration_s=801).frames == 41
    # a validated scenario survives a round trip through its dump (frames is then explicit)
    again = ScanConfig.model_validate(scan.model_dump())
    assert again.frames == 20


@pytest.mark.parametrize("scan, field, words", [
    ({"duration_s": 0.1, "frame_rate_hz": -10}, "scan.frame_rate_hz", "greater than 0"),
    ({"duration_s": 0.1, "frame_rate_hz": 0}, "scan.frame_rate_hz", "greater than 0"),
    ({"duration_s": 0.1, "frame_period_s": -1}, "scan.frame_period_s", "greater than 0"),
    ({"duration_s": 0.1, "frame_rate_hz": 10, "frame_period_s": 0.1}, "scan",
     "either frame_period_s or frame_rate_hz"),
    ({"duration_s": 0.5, "frame_rate_hz": 10, "frames": 3}, "scan", "frames would overlap"),
    ({"duration_s": 0.1, "frame_rate_hz": 10, "frames": 3, "sequence_duration_s": 1},
     "scan", "disagrees with sequence_duration_s"),
    ({"duration_s": 0.1, "sequence_duration_s": -2}, "scan.sequence_duration_s",
     "greater than 0"),
])
def test_bad_sequence_timing_is_a_one_line_error(tmp_path, scan, field, words):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({"sensor": {"datasheet": "livox-mid70-rose"},
                                    "targets": [{"name": "t", "mesh": {"model": "sphere"}}],
                                    "scan": scan}))
    with pytest.raises(ConfigError) as err:
        load_scenario(path)
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: field '{field}'")
    assert words in message


# ---- per-frame poses and the pose file ------------------------------------------------------
def test_frame_info_carries_start_and_end_poses_of_every_body():
    sim = Simulation(scenario_from_dict(_box_scene()))
    for frame in range(3):
        info = sim.frame_info(frame)
        assert (info.t_start, info.t_end) == pytest.approx((0.25 * frame, 0.25 * frame + 0.1))
        for key, t in (("start", info.t_start), ("end", info.t_end)):
            box = sim.targets[0].trajectory.poses_at(np.array([t]))
            sensor = sim.sensor_trajectory.poses_at(np.array([t]))
            rec = getattr(info, f"target_poses_{key}")[0]
            np.testing.assert_allclose(rec["translation_m"], box.position[0], atol=1e-12)
            rel = info.targets_in_sensor[0] if key == "start" else info.targets_in_sensor_end[0]
            # independent composition: x_sensor = Rs⁻¹ (Rb x + pb - ps)
            x = np.array([[0.3, -0.4, 0.5]])
            want = sensor.apply_inverse(box.apply(x))
            got = Rotation.from_quat(rel["quaternion_xyzw"]).apply(x) + rel["translation_m"]
            np.testing.assert_allclose(got, want, atol=1e-12)


@pytest.mark.parametrize("suffix", [".json", ".csv"])
def test_pose_file_reproduces_the_noiseless_points_in_frozen_mode(tmp_path, suffix):
    sim = Simulation(scenario_from_dict(_box_scene("frozen")))
    clouds = [sim.run_frame(f) for f in range(3)]
    path = write_ground_truth(tmp_path / f"poses{suffix}", [c.frame for c in clouds],
                              clouds=[f"cloud_{f:04d}.ply" for f in range(3)])
    if suffix == ".json":
        records = read_ground_truth(path)["frames"]
        poses = [pose_from_record(r["targets"][0]) for r in records]
        assert [r["cloud"] for r in records] == ["cloud_0000.ply", "cloud_0001.ply",
                                                 "cloud_0002.ply"]
    else:
        with path.open(newline="") as stream:
            rows = list(csv.DictReader(stream))
        assert [r["target"] for r in rows] == ["box"] * 3
        poses = [pose_from_record({
            "q_target_in_sensor": [float(r[f"q_target_in_sensor_{a}"]) for a in "xyzw"],
            "r_target_in_sensor_m": [float(r[f"r_target_in_sensor_{a}_m"]) for a in "xyz"]})
            for r in rows]
    for cloud, pose in zip(clouds, poses):
        assert len(cloud) > 500
        # the recorded pose maps the mesh onto the noiseless points: inversely, the points
        # lie on the box surface in body coordinates
        assert _box_residual(pose.apply_inverse(cloud.xyz_true)).max() < 1e-9


def test_pose_file_start_and_end_bracket_the_per_ray_motion(tmp_path):
    sim = Simulation(scenario_from_dict(_box_scene("per_ray")))
    clouds = [sim.run_frame(f) for f in range(3)]
    data = read_ground_truth(write_ground_truth(tmp_path / "poses.json",
                                                [c.frame for c in clouds]))
    assert data["motion"] == "per_ray" and data["target_names"] == ["box"]
    for cloud, record in zip(clouds, data["frames"]):
        target = record["targets"][0]
        start, end = pose_from_record(target), pose_from_record(target, end=True)
        t0, t1 = record["t_start_s"], record["t_end_s"]
        # constant-rate screw: linear translation, SLERP rotation between the recorded poses
        s = (cloud["timestamp"] - t0) / (t1 - t0)
        rotation = Slerp([0.0, 1.0], Rotation.concatenate([start.rotation, end.rotation]))(s)
        position = start.position + s[:, None] * (end.position - start.position)
        body = rotation.apply(cloud.xyz_true - position, inverse=True)
        assert _box_residual(body).max() < 1e-9
        # and the start pose alone does not fit (the box moved during the frame)
        assert _box_residual(start.apply_inverse(cloud.xyz_true)).max() > 0.01


def test_pose_file_errors(tmp_path):
    infos = sequence_frame_infos(scenario_from_dict(_box_scene()), [0])
    with pytest.raises(ConfigError, match="not a lidarsim-poses"):
        (tmp_path / "x.json").write_text("{}")
        read_ground_truth(tmp_path / "x.json")
    from lidarsim_core.base.errors import OutputError

    with pytest.raises(OutputError, match="use .json or .csv"):
        write_ground_truth(tmp_path / "poses.txt", infos)
    write_ground_truth(tmp_path / "poses.json", infos)
    with pytest.raises(OutputError, match="exists"):
        write_ground_truth(tmp_path / "poses.json", infos, overwrite=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["poses.json", "x.json"]


# ---- the example scenarios ------------------------------------------------------------------
def _run(name: str) -> tuple[Simulation, list]:
    sc = load_scenario(EXAMPLES / name)
    sim = Simulation(sc)
    return sim, [sim.run_frame(f) for f in range(sc.scan.frames)]


def _sensor_positions(clouds) -> np.ndarray:
    return np.array([c.frame.sensor_pose_start["translation_m"] for c in clouds])


def test_example_vbar_approach_closes_from_250_to_20_m():
    sim, clouds = _run("vbar_approach.yaml")
    assert len(clouds) == 41
    pos = _sensor_positions(clouds)
    np.testing.assert_allclose(pos[:, [0, 2]], 0.0, atol=1e-9)  # stays on V-bar
    assert pos[0, 1] == pytest.approx(250.0) and pos[-1, 1] == pytest.approx(20.0)
    assert np.all(np.diff(pos[:, 1]) <= 1e-9)
    counts = np.array([len(c) for c in clouds])
    assert counts[0] > 0 and counts[-1] > 50 * counts[0]  # closer: far more points
    # the bus's -X end face is 5 m from the target centre, toward the chaser
    assert clouds[-1]["range_true"].min() == pytest.approx(15.0, abs=0.05)


def test_example_tumbling_hold_sees_envisat_turn_at_its_2013_rate():
    sim, clouds = _run("envisat_tumbling_hold.yaml")
    assert len(clouds) == 20 and all(len(c) > 300 for c in clouds)
    np.testing.assert_allclose(_sensor_positions(clouds), [[0, 30, 0]] * 20, atol=1e-9)
    q = Rotation.from_quat([c.frame.targets_in_sensor[0]["quaternion_xyzw"] for c in clouds])
    step = (q[:-1].inv() * q[1:]).magnitude()
    n_deg = math.degrees(mean_motion_from_altitude(780.0))
    np.testing.assert_allclose(np.degrees(step), (2.67 + n_deg) * 0.1, rtol=1e-9)


def test_example_fly_around_keeps_50_m_and_sees_the_target_all_round():
    sim, clouds = _run("flyaround_50m.yaml")
    assert len(clouds) == 50 and all(len(c) > 100 for c in clouds)
    pos = _sensor_positions(clouds)
    np.testing.assert_allclose(np.linalg.norm(pos, axis=1), 50.0, atol=1e-9)
    azimuth = np.degrees(np.unwrap(np.arctan2(pos[:, 0], pos[:, 1])))
    assert np.ptp(azimuth) > 340  # nearly a full circle in 50 frames
    r = [c.frame.targets_in_sensor[0]["translation_m"] for c in clouds]
    np.testing.assert_allclose(r, [[50, 0, 0]] * 50, atol=1e-9)  # target on the boresight


def test_example_two_targets_labels_and_occludes():
    sim, clouds = _run("two_targets.yaml")
    assert len(clouds) == 30
    assert clouds[0].frame.target_names == ["envisat", "debris"]
    both = [c for c in clouds if {0, 1} <= set(np.unique(c["target"]))]
    assert len(both) >= 20
    for cloud in both:
        debris = cloud["range_true"][cloud["target"] == 1]
        assert debris.max() < 26.0 < cloud["range_true"][cloud["target"] == 0].min()


# ---- command line ---------------------------------------------------------------------------
def test_lidarsim_poses_command(tmp_path):
    scenario = tmp_path / "box.yaml"
    scenario.write_text(yaml.safe_dump(_box_scene()))
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", "COLUMNS": "200"}

    def run(*args: str) -> subprocess.CompletedProcess:
        # through the package's main() (under `python -m lidarsim_core.cli` the module runs
        # as __main__, a second copy that does not see commands added by other modules)
        code = "import sys; from lidarsim_core.cli import main; main(sys.argv[1:])"
        return subprocess.run([sys.executable, "-c", code, *args], env=env,
                              capture_output=True, text=True, timeout=300)

    out = tmp_path / "poses.json"
    done = run("poses", str(scenario), "--out", str(out), "--clouds", "cloud_{frame:04d}.ply")
    assert done.returncode == 0, done.stderr
    data = json.loads(out.read_text())
    assert [f["cloud"] for f in data["frames"]] == [f"cloud_{i:04d}.ply" for i in range(3)]
    infos = sequence_frame_infos(load_scenario(scenario))
    for rec, info in zip(data["frames"], infos):
        np.testing.assert_allclose(rec["targets"][0]["r_target_in_sensor_m"],
                                   info.targets_in_sensor[0]["translation_m"], atol=1e-12)
    again = run("poses", str(scenario), "--out", str(out))
    assert again.returncode == 2 and "exists" in again.stderr
    assert len(again.stderr.strip().splitlines()) == 1
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({**_box_scene(), "scan": {"duration_s": 0.1,
                                                             "frame_rate_hz": -4}}))
    failed = run("poses", str(bad), "--out", str(tmp_path / "p.csv"))
    assert failed.returncode == 2
    assert "scan.frame_rate_hz" in failed.stderr and "greater than 0" in failed.stderr
    assert not (tmp_path / "p.csv").exists()
