"""Constant linear and angular velocity, and the look-at attitude law."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.trajectories.attitude import look_at
from lidarsim_core.trajectories.kinematic import ConstantVelocityTrajectory


def test_constant_velocity_moves_and_turns_uniformly():
    traj = ConstantVelocityTrajectory.from_config({
        "position_m": [10, 0, 0], "velocity_m_s": [0.5, -1, 2], "euler_deg": [0, 0, 90],
        "angular_velocity_deg_s": [0, 0, 10], "t_ref_s": 2.0})
    t = np.array([0.0, 2.0, 5.0, 38.0])
    poses = traj.poses_at(t)
    np.testing.assert_allclose(poses.position, [[10 + 0.5 * (x - 2), -(x - 2), 2 * (x - 2)]
                                                for x in t], atol=1e-12)
    yaw = poses.rotation.as_euler("xyz", degrees=True)[:, 2]
    np.testing.assert_allclose(np.mod(yaw, 360), np.mod(90 + 10 * (t - 2), 360), atol=1e-9)


def test_body_and_scene_angular_velocity_describe_the_same_motion():
    r0 = Rotation.from_euler("xyz", [20, -30, 45], degrees=True)
    w_body = np.array([3.0, -7.0, 5.0])
    body = ConstantVelocityTrajectory.from_config({
        "quaternion_xyzw": r0.as_quat().tolist(), "angular_velocity_deg_s": w_body.tolist()})
    scene = ConstantVelocityTrajectory.from_config({
        "quaternion_xyzw": r0.as_quat().tolist(), "angular_velocity_frame": "scene",
        "angular_velocity_deg_s": r0.apply(w_body).tolist()})
    t = np.linspace(-10, 60, 15)
    a, b = body.poses_at(t).rotation, scene.poses_at(t).rotation
    assert (a.inv() * b).magnitude().max() < 1e-12
    # the angle turned grows as |ω|·t
    turned = (r0.inv() * a).magnitude()
    expected = np.mod(np.abs(np.radians(np.linalg.norm(w_body)) * t), 2 * math.pi)
    expected = np.minimum(expected, 2 * math.pi - expected)
    np.testing.assert_allclose(turned, expected, atol=1e-9)


def test_zero_velocities_are_static():
    assert ConstantVelocityTrajectory.from_config({"position_m": [1, 2, 3]}).is_static
    assert not ConstantVelocityTrajectory.from_config({"velocity_m_s": [0, 0, 1e-3]}).is_static


def test_look_at_frames_are_right_handed_and_aim_at_the_point():
    rng = np.random.default_rng(8)
    positions = rng.normal(0, 30, (200, 3))
    point = np.array([1.0, -2.0, 0.5])
    rot = look_at(positions, point, np.array([0.0, 0.0, 1.0]))
    mats = rot.as_matrix()
    np.testing.assert_allclose(np.linalg.det(mats), 1.0, atol=1e-12)
    aim = point - positions
    np.testing.assert_allclose(mats[:, :, 0], aim / np.linalg.norm(aim, axis=1, keepdims=True),
                               atol=1e-12)
    assert np.all(mats[:, 2, 2] > 0)  # +Z leans toward the requested up
    # degenerate cases: up parallel to the boresight, and sitting on the point
    edge = look_at(np.array([[0.0, 0.0, -5.0], [1.0, -2.0, 0.5]]), point * 0,
                   np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(edge.apply([1.0, 0, 0])[0], [0, 0, 1], atol=1e-12)
    assert np.all(np.isfinite(edge.as_quat()))


@pytest.mark.parametrize("options, field", [
    ({"velocity_m_s": [1, 2]}, "t.velocity_m_s"),  # 'needs 3 values, got 2'
    ({"angular_velocity_frame": "inertial"}, "t.angular_velocity_frame"),
    ({"spin": 3}, "t.spin"),
    ({"angular_velocity_deg_s": [0, float("inf"), 0]}, "t.angular_velocity_deg_s.1"),
])
def test_bad_constant_velocity_options_name_the_field(options, field):
    with pytest.raises(ConfigError) as err:
        ConstantVelocityTrajectory.from_config(options, source="s.yaml", field="t")
    assert str(err.value).startswith(f"s.yaml: field '{field}'")
    assert "\n" not in str(err.value)
