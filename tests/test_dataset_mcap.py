"""``lidarsim dataset --format mcap``: one ROS 2 bag per sequence, read back with rosbags'
AnyReader and the ROS 2 type store against the dataset's own poses files and manifest;
resume at the sequence level; byte-identical bags."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("rosbags")

from lidarsim_core.base.errors import ConfigError  # noqa: E402
from lidarsim_core.dataset import generate_dataset, read_manifest  # noqa: E402

SCENARIO = {
    "seed": 4,
    "sensor": {"datasheet": "livox-mid70-rose", "pose": {"position_m": [0, 0, 0]}},
    "targets": [
        {"name": "envisat", "mesh": {"model": "envisat", "options": {"detail": "coarse"}},
         "trajectory": {"kind": "constant_velocity", "position_m": [30, -8, 0],
                        "velocity_m_s": [0, 1, 0], "angular_velocity_deg_s": [3, 5, 2]}},
        {"name": "debris", "mesh": {"model": "box", "options": {"extents_m": [1.2, 0.8, 0.4]}},
         "trajectory": {"kind": "constant_velocity", "position_m": [20, -2, 0],
                        "velocity_m_s": [0, 2, 0], "angular_velocity_deg_s": [10, 20, 5]}}],
    "scan": {"duration_s": 0.02, "frame_period_s": 0.1, "frames": 3},
    "backend": "numpy",
}
FRAMES = {"near": 3, "far": 2}


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _ns(seconds: float) -> int:
    return int(round(seconds * 1e9))


def _stamp_ns(header) -> int:
    return header.stamp.sec * 10 ** 9 + header.stamp.nanosec


def _messages(path: Path) -> dict[str, list]:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    out: dict[str, list] = {}
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        for connection, stamp, raw in reader.messages():
            out.setdefault(connection.topic, []).append(
                (stamp, reader.deserialize(raw, connection.msgtype)))
    return out


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """Two sequences (3 and 2 frames) written as bags."""
    root = tmp_path_factory.mktemp("mcap")
    (root / "scene.yaml").write_text(yaml.safe_dump(SCENARIO, sort_keys=False))
    plan = {"sequences": [
        {"scenario": "scene.yaml", "name": "near", "frames": FRAMES["near"]},
        {"scenario": "scene.yaml", "name": "far", "frames": FRAMES["far"],
         "set": {"targets.0.trajectory.position_m": [45, -8, 0]}}],
        "format": "mcap"}
    (root / "dataset.yaml").write_text(yaml.safe_dump(plan, sort_keys=False))
    out = root / "ds"
    result = generate_dataset(root / "dataset.yaml", out)
    assert (result.frames_total, result.frames_written, result.frames_skipped) == (5, 5, 0)
    return root, out


def test_one_bag_per_sequence_with_stamps_and_poses_of_the_dataset(dataset):
    _, out = dataset
    manifest = read_manifest(out / "manifest.json")
    assert manifest["complete"] and manifest["identity"]["exporter"]["name"] == "mcap"
    files = {p.relative_to(out).as_posix() for p in out.rglob("*.mcap")}
    assert files == {"sequences/near/bag.mcap", "sequences/far/bag.mcap"}
    assert not list(out.rglob("frames"))  # no per-frame files
    for seq in manifest["sequences"]:
        frames = FRAMES[seq["name"]]
        seq_root = out / seq["root"]
        poses = json.loads((seq_root / seq["poses"]).read_text())["frames"]
        assert len(poses) == frames
        messages = _messages(out / seq["bag"]["file"])
        assert set(messages) == {"/lidarsim/points", "/tf", "/lidarsim/ground_truth/envisat",
                                 "/lidarsim/ground_truth/debris"}
        assert all(len(m) == frames for m in messages.values())
        counts = [m.width for _, m in messages["/lidarsim/points"]]
        assert counts == seq["bag"]["points_per_frame"] and sum(counts) > 20
        assert [f["points"] for f in seq["frames"]] == counts
        for (stamp, cloud), (_, tf), frame in zip(messages["/lidarsim/points"],
                                                  messages["/tf"], poses):
            assert stamp == _stamp_ns(cloud.header) == _ns(frame["t_start_s"])
            by_child = {t.child_frame_id: t.transform for t in tf.transforms}
            sensor = by_child["sensor"]
            np.testing.assert_allclose(
                [sensor.translation.x, sensor.translation.y, sensor.translation.z],
                frame["r_sensor_in_scene_m"], atol=1e-9, rtol=0)
            for target in frame["targets"]:
                t = by_child[target["name"]]
                np.testing.assert_allclose([t.translation.x, t.translation.y, t.translation.z],
                                           target["r_target_in_scene_m"], atol=1e-9, rtol=0)
                np.testing.assert_allclose([t.rotation.x, t.rotation.y, t.rotation.z,
                                            t.rotation.w], target["q_target_in_scene"],
                                           atol=1e-9, rtol=0)
        for name in ("envisat", "debris"):
            truth = messages[f"/lidarsim/ground_truth/{name}"]
            for (stamp, gt), frame in zip(truth, poses):
                target = next(t for t in frame["targets"] if t["name"] == name)
                assert stamp == _ns(frame["t_start_s"])
                p, o = gt.pose.position, gt.pose.orientation
                np.testing.assert_allclose([p.x, p.y, p.z], target["r_target_in_sensor_m"],
                                           atol=1e-9, rtol=0)
                np.testing.assert_allclose([o.x, o.y, o.z, o.w], target["q_target_in_sensor"],
                                           atol=1e-9, rtol=0)
    # the two sequences really differ (the 'set' moved the target away)
    near, far = (manifest["sequences"][i]["bag"]["points_per_frame"][:2] for i in (0, 1))
    assert near != far


def test_manifest_checksums_and_splits_name_the_bags(dataset):
    _, out = dataset
    manifest = read_manifest(out / "manifest.json")
    total = 0
    for seq in manifest["sequences"]:
        bag = out / seq["bag"]["file"]
        assert seq["bag"]["sha256"] == _sha(bag) and seq["bag"]["bytes"] == bag.stat().st_size
        assert seq["bag"]["frames"] == FRAMES[seq["name"]] == seq["frame_count"]
        total += seq["bag"]["bytes"]
    assert manifest["totals"]["bytes"] == total and manifest["totals"]["frames"] == 5
    listed = [line for split in (out / "splits").glob("*.txt")
              for line in split.read_text().split()]
    assert sorted(listed) == ["sequences/far/bag.mcap", "sequences/near/bag.mcap"]


def test_resume_rewrites_only_the_missing_bag_byte_identical(dataset):
    _, out = dataset
    before = {p: _sha(p) for p in sorted(out.rglob("*")) if p.is_file()}
    near, far = out / "sequences/near/bag.mcap", out / "sequences/far/bag.mcap"
    far_mtime = far.stat().st_mtime_ns
    near.unlink()
    result = generate_dataset(out / "dataset.yaml", out)
    assert (result.frames_written, result.frames_skipped) == (FRAMES["near"], FRAMES["far"])
    assert far.stat().st_mtime_ns == far_mtime  # untouched
    after = {p: _sha(p) for p in sorted(out.rglob("*")) if p.is_file()}
    assert after == before  # the rewritten bag and the manifest: the same bytes
    # an incomplete bag (size no longer matches its sidecar) is redone, too
    with open(far, "ab") as stream:
        stream.write(b"junk")
    result = generate_dataset(out / "dataset.yaml", out)
    assert (result.frames_written, result.frames_skipped) == (FRAMES["far"], FRAMES["near"])
    assert {p: _sha(p) for p in sorted(out.rglob("*")) if p.is_file()} == before


def test_refusals_come_before_anything_is_created(dataset, tmp_path):
    root, _ = dataset
    scene = root / "scene.yaml"
    with pytest.raises(ConfigError, match="--workers"):
        generate_dataset(scene, tmp_path / "a", format="mcap", workers=2)
    with pytest.raises(ConfigError, match="--livox needs --format mcap"):
        generate_dataset(scene, tmp_path / "b", format="ply", livox=True)
    with pytest.raises(ConfigError, match="unknown option 'colour'"):
        generate_dataset(scene, tmp_path / "c", format="mcap",
                         exporter_options={"colour": True})
    bad = json.loads(json.dumps(SCENARIO))
    bad["targets"][1]["name"] = "sensor"
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(bad))
    with pytest.raises(ConfigError, match="'sensor' is also a TF frame") as info:
        generate_dataset(tmp_path / "bad.yaml", tmp_path / "d", format="mcap")
    assert info.value.source == str(tmp_path / "bad.yaml")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.yaml"]


def test_cli_single_scenario_with_livox(dataset, tmp_path):
    root, _ = dataset
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", "COLUMNS": "200"}
    out = tmp_path / "one"
    res = subprocess.run([sys.executable, "-m", "lidarsim_core", "dataset",
                          str(root / "scene.yaml"), "--out", str(out), "--format", "mcap",
                          "--frames", "2", "--livox", "-q"],
                         env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    messages = _messages(out / "bag.mcap")
    assert len(messages["/livox/lidar"]) == len(messages["/lidarsim/points"]) == 2
    for (_, custom), (_, cloud) in zip(messages["/livox/lidar"], messages["/lidarsim/points"]):
        assert custom.point_num == cloud.width and custom.timebase == _stamp_ns(cloud.header)
    manifest = read_manifest(out / "manifest.json")
    assert manifest["identity"]["exporter"]["options"] == {"livox": True}
    assert manifest["sequences"][0]["bag"]["file"] == "bag.mcap"
    res = subprocess.run([sys.executable, "-m", "lidarsim_core", "dataset",
                          str(root / "scene.yaml"), "--out", str(tmp_path / "two"),
                          "--format", "mcap", "--workers", "2"],
                         env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 2 and "--workers" in res.stderr + res.stdout
    assert not (tmp_path / "two").exists()


def test_evaluate_refuses_a_bag_dataset_in_one_line(dataset):
    from lidarsim_core.evaluate.data import open_dataset

    _, out = dataset
    with pytest.raises(ConfigError, match="ROS 2 bags"):
        open_dataset(out)


def test_ctrl_c_keeps_finished_bags_only_and_a_rerun_completes_them(dataset, tmp_path,
                                                                      monkeypatch):
    import lidarsim_core.dataset.generate as generate

    root, full = dataset
    reference = {p.relative_to(full): _sha(p) for p in full.rglob("*") if p.is_file()}
    real = generate.write_sequence_bag
    calls = []

    def interrupted(sim, frames, path, *, livox, on_frame=None):
        calls.append(path)
        if len(calls) == 2:  # the second sequence: interrupted after its first frame
            def stop(points):
                raise KeyboardInterrupt
            return real(sim, frames, path, livox=livox, on_frame=stop)
        return real(sim, frames, path, livox=livox, on_frame=on_frame)

    monkeypatch.setattr(generate, "write_sequence_bag", interrupted)
    out = tmp_path / "ds"
    with pytest.raises(KeyboardInterrupt, match="1 of 2 sequence bags are complete"):
        generate_dataset(root / "dataset.yaml", out)
    assert (out / "sequences/near/bag.mcap").is_file()
    far = out / "sequences/far"
    assert sorted(p.name for p in far.iterdir()) == ["poses.json", "scenario.yaml"]
    monkeypatch.setattr(generate, "write_sequence_bag", real)
    result = generate_dataset(root / "dataset.yaml", out)
    assert (result.frames_written, result.frames_skipped) == (FRAMES["far"], FRAMES["near"])
    assert {p.relative_to(out): _sha(p) for p in out.rglob("*") if p.is_file()} == reference
