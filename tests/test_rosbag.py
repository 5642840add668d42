"""ROS 2 bags: a 20-frame tumbling-Envisat run written by ``lidarsim simulate --out run.mcap``
and read back with rosbags' AnyReader and a ROS 2 type store, against the in-memory clouds
and ``lidarsim poses``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("rosbags")

import lidarsim_core as ls  # noqa: E402
from lidarsim_core.io.rosbag import POINT_FIELDS_ROS, typestore, write_bag  # noqa: E402

EXAMPLE = Path(__file__).parents[1] / "examples" / "scenarios" / "envisat_tumbling_hold.yaml"
#: PointField datatype constants of sensor_msgs/msg/PointField.
DATATYPES = {"i1": 1, "u1": 2, "i2": 3, "u2": 4, "i4": 5, "u4": 6, "f4": 7, "f8": 8}


def _run_cli(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", "COLUMNS": "200"}
    return subprocess.run([sys.executable, "-m", "lidarsim_core", *args], env=env,
                          capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The tumbling example (coarse mesh for speed) as a bag and as a pose file."""
    root = tmp_path_factory.mktemp("bag")
    data = yaml.safe_load(EXAMPLE.read_text())
    data["targets"][0]["mesh"]["options"]["detail"] = "coarse"
    scenario = root / "tumbling.yaml"
    scenario.write_text(yaml.safe_dump(data))
    res = _run_cli("simulate", str(scenario), "--out", str(root / "run.mcap"))
    assert res.returncode == 0, res.stderr
    res = _run_cli("poses", str(scenario), "--out", str(root / "poses.json"))
    assert res.returncode == 0, res.stderr
    return scenario, root / "run.mcap", json.loads((root / "poses.json").read_text())


def _messages(path: Path) -> dict[str, list]:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    out: dict[str, list] = {}
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        for connection, stamp, raw in reader.messages():
            message = reader.deserialize(raw, connection.msgtype)
            out.setdefault(connection.topic, []).append((connection.msgtype, stamp, message))
    return out


def _ns(seconds: float) -> int:
    return int(round(seconds * 1e9))


def _stamp_ns(header) -> int:
    return header.stamp.sec * 10 ** 9 + header.stamp.nanosec


def _cloud_array(message) -> np.ndarray:
    dtype = np.dtype({"names": [f.name for f in message.fields],
                      "formats": [{v: k for k, v in DATATYPES.items()}[f.datatype]
                                  for f in message.fields],
                      "offsets": [f.offset for f in message.fields],
                      "itemsize": message.point_step})
    return np.frombuffer(np.asarray(message.data, dtype=np.uint8).tobytes(), dtype=dtype)


def test_bag_has_one_pointcloud2_per_frame_with_the_record(run):
    scenario, bag, poses = run
    messages = _messages(bag)
    assert set(messages) == {"/lidarsim/points", "/tf", "/lidarsim/ground_truth/envisat"}
    points = messages["/lidarsim/points"]
    assert len(points) == 20 == len(poses["frames"])
    sim = ls.Simulation(ls.load_scenario(scenario))
    for (msgtype, stamp, message), frame in zip(points, poses["frames"]):
        assert msgtype == "sensor_msgs/msg/PointCloud2"
        assert stamp == _stamp_ns(message.header) == _ns(frame["t_start_s"])
        assert message.header.frame_id == "sensor" and message.height == 1
        names = [f.name for f in message.fields]
        assert names[:9] == ["x", "y", "z", "intensity", "t", "ring", "return_number",
                             "number_of_returns", "label"]
        assert names == [name for name, _, _ in POINT_FIELDS_ROS]
        assert {f.name: f.datatype for f in message.fields}["t"] == DATATYPES["u4"]
        assert message.row_step == message.point_step * message.width
    for index in (0, 11, 19):  # every field against the in-memory cloud of the same frame
        cloud = sim.run_frame(index)
        message = points[index][2]
        assert message.width == len(cloud) > 100
        data = _cloud_array(message)
        for name, column, dtype in POINT_FIELDS_ROS:
            expected = cloud[column]
            if name == "t":
                expected = np.round((cloud["timestamp"] - cloud.frame.t_start) * 1e9)
                # t + header stamp gives each point's time to the nanosecond
                np.testing.assert_allclose(data["t"] * 1e-9 + _stamp_ns(message.header) * 1e-9,
                                           cloud["timestamp"], atol=1e-9)
            np.testing.assert_array_equal(data[name], expected.astype(dtype), err_msg=name)


def test_tf_and_ground_truth_equal_lidarsim_poses(run):
    _, bag, poses = run
    messages = _messages(bag)
    tf, truth = messages["/tf"], messages["/lidarsim/ground_truth/envisat"]
    assert len(tf) == len(truth) == 20
    for (_, stamp, message), (_, gt_stamp, gt), frame in zip(tf, truth, poses["frames"]):
        assert stamp == gt_stamp == _ns(frame["t_start_s"])
        by_child = {t.child_frame_id: t for t in message.transforms}
        assert set(by_child) == {"sensor", "envisat"}
        target = frame["targets"][0]
        for child, q, r in (("sensor", frame["q_sensor_in_scene"], frame["r_sensor_in_scene_m"]),
                            ("envisat", target["q_target_in_scene"],
                             target["r_target_in_scene_m"])):
            transform = by_child[child]
            assert transform.header.frame_id == "scene"
            assert _stamp_ns(transform.header) == _ns(frame["t_start_s"])
            t, rot = transform.transform.translation, transform.transform.rotation
            np.testing.assert_allclose([t.x, t.y, t.z], r, atol=1e-9, rtol=0)
            np.testing.assert_allclose([rot.x, rot.y, rot.z, rot.w], q, atol=1e-9, rtol=0)
        assert gt.header.frame_id == "sensor" and _stamp_ns(gt.header) == stamp
        p, o = gt.pose.position, gt.pose.orientation
        np.testing.assert_allclose([p.x, p.y, p.z], target["r_target_in_sensor_m"], atol=1e-9,
                                   rtol=0)
        np.testing.assert_allclose([o.x, o.y, o.z, o.w], target["q_target_in_sensor"],
                                   atol=1e-9, rtol=0)
    # the target really tumbles: the ground truth changes from frame to frame
    first, last = truth[0][2].pose.orientation, truth[-1][2].pose.orientation
    assert abs(first.w - last.w) + abs(first.x - last.x) > 1e-3


def test_livox_custom_msg(tmp_path):
    scenario = ls.demo_scenario(duration_s=0.05, backend="numpy", detail="coarse", seed=3)
    sim = ls.Simulation(scenario)
    path = write_bag([sim.run_frame(0)], tmp_path / "livox.mcap",
                     target_names=[t.name for t in sim.targets], livox=True)
    cloud = sim.run_frame(0)
    from rosbags.highlevel import AnyReader

    with AnyReader([path], default_typestore=typestore(livox=True)) as reader:
        found = [(c, reader.deserialize(raw, c.msgtype)) for c, _, raw in reader.messages()
                 if c.topic == "/livox/lidar"]
    assert len(found) == 1
    connection, message = found[0]
    assert connection.msgtype == "livox_ros_driver2/msg/CustomMsg"
    assert message.point_num == len(message.points) == len(cloud)
    assert message.timebase == _ns(cloud.frame.t_start)
    xyz = np.array([[p.x, p.y, p.z] for p in message.points])
    np.testing.assert_array_equal(xyz, cloud.xyz.astype(np.float32))
    offsets = np.array([p.offset_time for p in message.points])
    np.testing.assert_allclose(message.timebase * 1e-9 + offsets * 1e-9, cloud["timestamp"],
                               atol=1e-9)
    np.testing.assert_array_equal([p.line for p in message.points], cloud["channel"])
    diffuse = cloud["intensity"] <= 1
    np.testing.assert_array_equal(np.array([p.reflectivity for p in message.points])[diffuse],
                                  np.round(150 * cloud["intensity"][diffuse]))


def test_existing_bag_is_refused_and_nothing_is_left_on_error(run, tmp_path):
    scenario, bag, _ = run
    res = _run_cli("simulate", str(scenario), "--out", str(bag))
    assert res.returncode == 2 and "exists" in res.stderr
    (tmp_path / "blocker").write_text("a file, not a folder")
    res = _run_cli("simulate", str(scenario), "--out", str(tmp_path / "blocker" / "a.mcap"))
    assert res.returncode == 2 and "blocker is a file" in res.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["blocker"]
    res = _run_cli("simulate", str(scenario), "--out", str(tmp_path / "new" / "a.mcap"))
    assert res.returncode == 0, res.stderr  # a missing folder is created (the one policy)
    assert (tmp_path / "new" / "a.mcap").is_file()
