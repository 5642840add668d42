"""Keyframe trajectories: exact at the keyframes, smooth between them, clear errors."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.pipeline import Simulation
from lidarsim_core.scenario import load_scenario
from lidarsim_core.trajectories.keyframes import KeyframeTrajectory

TIMES = np.array([0.0, 1.0, 2.5, 4.0, 6.0])
POSITIONS = np.array([[60, 0, 0], [55, 1, 0.5], [48, 3, 0.2], [40, 2, -1], [30, 0, 0]], float)
ROTATIONS = Rotation.from_euler("xyz", [[0, 0, 0], [10, 5, 30], [20, -10, 80], [0, 0, 150],
                                        [-30, 20, 200]], degrees=True)


def _keyframes(**options) -> KeyframeTrajectory:
    frames = [{"t_s": float(t), "position_m": p.tolist(), "quaternion_xyzw": q.tolist()}
              for t, p, q in zip(TIMES, POSITIONS, ROTATIONS.as_quat())]
    return KeyframeTrajectory.from_config({"keyframes": frames, **options})


@pytest.mark.parametrize("position", ["cubic", "linear"])
@pytest.mark.parametrize("rotation", ["slerp", "spline"])
def test_keyframes_are_reproduced_exactly(position, rotation):
    traj = _keyframes(position_interpolation=position, rotation_interpolation=rotation)
    poses = traj.poses_at(TIMES)
    np.testing.assert_allclose(poses.position, POSITIONS, rtol=0, atol=1e-12)
    assert (poses.rotation.inv() * ROTATIONS).magnitude().max() < 1e-12


def test_cubic_positions_and_spline_rotations_are_smooth_across_keyframes():
    traj = _keyframes(position_interpolation="cubic", rotation_interpolation="spline")
    h = 1e-5
    for knot in TIMES[1:-1]:
        t = np.array([knot - 2 * h, knot - h, knot, knot + h, knot + 2 * h])
        pos = traj.poses_at(t).position
        v_left, v_right = (pos[2] - pos[1]) / h, (pos[3] - pos[2]) / h
        np.testing.assert_allclose(v_left, v_right, atol=1e-3)  # C¹ (C² in fact)
        a_left = (pos[2] - 2 * pos[1] + pos[0]) / h ** 2
        a_right = (pos[4] - 2 * pos[3] + pos[2]) / h ** 2
        np.testing.assert_allclose(a_left, a_right, atol=0.5)
        rot = traj.poses_at(t).rotation
        w_left = (rot[2] * rot[1].inv()).as_rotvec() / h
        w_right = (rot[3] * rot[2].inv()).as_rotvec() / h
        np.testing.assert_allclose(w_left, w_right, atol=1e-3)


def test_linear_and_slerp_move_uniformly_between_keyframes():
    traj = _keyframes(position_interpolation="linear", rotation_interpolation="slerp")
    # inside each interval: constant velocity and a constant-rate turn about a fixed axis
    for i in range(len(TIMES) - 1):
        t = np.linspace(TIMES[i], TIMES[i + 1], 7)
        poses = traj.poses_at(t)
        dt = TIMES[i + 1] - TIMES[i]
        expected = POSITIONS[i] + (t - TIMES[i])[:, None] / dt * (POSITIONS[i + 1] - POSITIONS[i])
        np.testing.assert_allclose(poses.position, expected, atol=1e-12)
        step = (ROTATIONS[i].inv() * ROTATIONS[i + 1]).as_rotvec()
        for k, tk in enumerate(t):
            want = ROTATIONS[i] * Rotation.from_rotvec(step * (tk - TIMES[i]) / dt)
            assert (poses.rotation[k].inv() * want).magnitude() < 1e-12


def test_outside_the_keyframes_hold_or_error():
    held = _keyframes().poses_at(np.array([-5.0, 100.0]))
    np.testing.assert_allclose(held.position, POSITIONS[[0, -1]])
    strict = _keyframes(extrapolate="error")
    with pytest.raises(ConfigError, match=r"keyframes cover t = 0\.\.6 s"):
        strict.poses_at(np.array([1.0, 6.5]))


def test_single_keyframe_is_a_fixed_pose():
    traj = KeyframeTrajectory.from_config({"keyframes": [{"t_s": 2.0, "position_m": [1, 2, 3],
                                                          "euler_deg": [0, 0, 90]}]})
    poses = traj.poses_at(np.array([0.0, 2.0, 9.0]))
    np.testing.assert_allclose(poses.position, [[1, 2, 3]] * 3)
    np.testing.assert_allclose(poses.rotation.apply([1.0, 0, 0]), [[0, 1, 0]] * 3, atol=1e-12)


def test_position_keyframes_with_a_look_at_attitude():
    traj = KeyframeTrajectory.from_config({
        "keyframes": [{"t_s": 0, "position_m": [0, 80, 0]}, {"t_s": 10, "position_m": [0, 40, 10]}],
        "attitude": {"mode": "look_at", "point_m": [0, 0, 0]}})
    poses = traj.poses_at(np.linspace(0, 10, 5))
    boresight = poses.rotation.apply([1.0, 0, 0])
    np.testing.assert_allclose(boresight, -poses.position / np.linalg.norm(
        poses.position, axis=1, keepdims=True), atol=1e-12)


def test_keyframe_files_relative_to_the_scenario(tmp_path):
    csv_text = "t_s,x_m,y_m,z_m,qx,qy,qz,qw\n" + "".join(
        f"{t},{p[0]},{p[1]},{p[2]},{q[0]},{q[1]},{q[2]},{q[3]}\n"
        for t, p, q in zip(TIMES, POSITIONS, ROTATIONS.as_quat()))
    (tmp_path / "path.csv").write_text(csv_text)
    (tmp_path / "path.yaml").write_text(yaml.safe_dump({"keyframes": [
        {"t_s": float(t), "position_m": p.tolist(), "quaternion_xyzw": q.tolist()}
        for t, p, q in zip(TIMES, POSITIONS, ROTATIONS.as_quat())]}))
    (tmp_path / "euler.csv").write_text(
        "t_s,x_m,y_m,z_m,euler_x_deg,euler_y_deg,euler_z_deg\n0,1,2,3,0,0,90\n1,1,2,4,0,0,90\n")
    for name in ("path.csv", "path.yaml"):
        scenario = {
            "sensor": {"datasheet": "livox-mid70-rose"},
            "targets": [{"name": "t", "mesh": {"model": "sphere"},
                         "trajectory": {"kind": "keyframes", "file": name}}],
            "scan": {"duration_s": 0.01}, "backend": "numpy", "noise": []}
        path = tmp_path / f"scenario_{name.replace('.', '_')}.yaml"
        path.write_text(yaml.safe_dump(scenario))
        sim = Simulation(load_scenario(path))
        poses = sim.targets[0].trajectory.poses_at(TIMES)
        np.testing.assert_allclose(poses.position, POSITIONS, atol=1e-12)
        assert (poses.rotation.inv() * ROTATIONS).magnitude().max() < 1e-12
    euler = KeyframeTrajectory.from_config({"file": str(tmp_path / "euler.csv")})
    np.testing.assert_allclose(euler.poses_at(np.array([0.5])).rotation.apply([1.0, 0, 0]),
                               [[0, 1, 0]], atol=1e-12)


@pytest.mark.parametrize("content, field, words", [
    ("t_s,x_m,y_m,z_m\n0,0,0,0\n2,1,0,0\n1,2,0,0\n", "line 4.t_s", "increase strictly"),
    ("t_s,x_m,y_m,z_m,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n1,0,0,0,0,0,0,0\n", "line 3",
     "zero norm"),
    ("t_s,x_m,y_m,z_m\n0,0,zero,0\n", "line 2.y_m", "not a number"),
    ("t_s,x_m,y_m\n0,0,0\n", "header", "lacks column(s) z_m"),
    ("t_s,x_m,y_m,z_m\n", None, "no rows"),
])
def test_bad_keyframe_files_are_one_line_errors(tmp_path, content, field, words):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(ConfigError) as err:
        KeyframeTrajectory.from_config({"file": str(path)}, source="s.yaml", field="f")
    message = str(err.value)
    assert "\n" not in message
    prefix = f"{path}: field '{field}'" if field else f"{path}: "
    assert message.startswith(prefix)
    assert words in message


@pytest.mark.parametrize("frames, extra, field, words", [
    ([{"t_s": 0}, {"t_s": 2}, {"t_s": 2}], {}, "targets.0.trajectory.keyframes.2.t_s",
     "t_s = 2 does not follow the previous keyframe's t_s = 2"),
    ([{"t_s": 0}, {"t_s": 1, "quaternion_xyzw": [0, 0, 0, 0]}], {},
     "targets.0.trajectory.keyframes.1", "zero norm"),
    ([{"t_s": 0, "euler_deg": [0, 0, 1]}], {"attitude": {"mode": "look_at"}},
     "targets.0.trajectory.attitude", "must be omitted"),
    ([], {}, "targets.0.trajectory.keyframes", "at least 1"),
    (None, {}, "targets.0.trajectory", "exactly one of 'keyframes'"),
    ([{"t_s": 0}], {"rotation_interpolation": "cubic"},
     "targets.0.trajectory.rotation_interpolation", "'slerp' or 'spline'"),
])
def test_bad_inline_keyframes_are_one_line_errors(frames, extra, field, words):
    options = {**({"keyframes": frames} if frames is not None else {}), **extra}
    with pytest.raises(ConfigError) as err:
        KeyframeTrajectory.from_config(options, source="s.yaml", field="targets.0.trajectory")
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(f"s.yaml: field '{field}'")
    assert words in message


def test_keyframe_errors_reach_the_scenario_loader(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({
        "sensor": {"datasheet": "livox-mid70-rose"},
        "targets": [{"name": "t", "mesh": {"model": "sphere"}, "trajectory": {
            "kind": "keyframes", "keyframes": [{"t_s": 1.0}, {"t_s": 0.5}]}}],
        "scan": {"duration_s": 0.01}}))
    with pytest.raises(ConfigError) as err:
        Simulation(load_scenario(path))
    assert str(err.value) == (
        f"{path.resolve()}: field 'targets.0.trajectory.keyframes.1.t_s': keyframe times must "
        "increase strictly: t_s = 0.5 does not follow the previous keyframe's t_s = 1")
