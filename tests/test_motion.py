"""Motion during a scan: per-ray poses against the static mesh, the frozen mode, occlusion
between several moving targets."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import datasheet
from scipy.spatial.transform import Rotation

from lidarsim_core.pipeline import Simulation
from lidarsim_core.scenario import scenario_from_dict

BOX = np.array([2.0, 3.0, 1.5])  # box extents (m): its surface is max_i |x_i| / (BOX_i/2) = 1
SPIN_DEG_S = 90.0                # a known, fast spin so the distortion is large


R0 = Rotation.from_euler("xyz", [10.0, 20.0, 30.0], degrees=True)
SPIN_AXIS = np.array([0.3, -0.2, 1.0])  # body frame


def _scenario(motion: str, **scan) -> dict:
    """A box spinning at SPIN_DEG_S about a tilted axis, 12 m from a sensor that itself
    translates and turns during the frame (both poses matter for every ray)."""
    return {
        "seed": 3,
        "sensor": {"datasheet": datasheet(point_rate_hz=50_000.0),
                   "trajectory": {"kind": "constant_velocity", "position_m": [0.0, 0.3, -0.2],
                                  "velocity_m_s": [1.5, -0.8, 0.4],
                                  "euler_deg": [2.0, -3.0, 4.0],
                                  "angular_velocity_deg_s": [0.0, 4.0, -6.0]}},
        "targets": [{"name": "box",
                     "mesh": {"model": "box", "options": {"extents_m": BOX.tolist()}},
                     "trajectory": {"kind": "tumbling", "position_m": [12.0, 0.0, 0.0],
                                    "quaternion_xyzw": R0.as_quat().tolist(),
                                    "symmetry_axis": SPIN_AXIS.tolist(),
                                    "angular_momentum_axis": R0.apply(SPIN_AXIS).tolist(),
                                    "spin_rate_deg_s": SPIN_DEG_S}}],
        "scan": {"duration_s": 0.2, "motion": motion, **scan},
        "backend": "numpy",
        "noise": [],
    }


def _body_points(sim: Simulation, cloud, times: np.ndarray) -> np.ndarray:
    """Noiseless sensor-frame points moved into the target body frame with the ground-truth
    sensor and target poses at ``times``."""
    scene = sim.sensor_trajectory.poses_at(times).apply(cloud.xyz_true)
    return sim.targets[0].trajectory.poses_at(times).apply_inverse(scene)


def _box_residual(points: np.ndarray) -> np.ndarray:
    """Distance of each point from the box surface, exact for points near a face."""
    return np.abs(np.max(np.abs(points) / (BOX / 2), axis=1) - 1.0) * BOX.min() / 2


def test_per_ray_points_lie_on_the_static_mesh_at_their_own_time():
    sim = Simulation(scenario_from_dict(_scenario("per_ray")))
    cloud = sim.run_frame(0)
    assert len(cloud) > 2000
    t = cloud["timestamp"]
    assert t.min() >= 0.0 and t.max() < 0.2 and np.ptp(t) > 0.19
    on_mesh = _box_residual(_body_points(sim, cloud, t))
    assert on_mesh.max() < 1e-9  # numerical precision of a float64 ray caster at 12 m
    # the motion is real: with the frame-start pose the same points miss the mesh by up to
    # the distance the box corners travel in 0.2 s (90 °/s · 0.2 s · ~2 m ≈ 0.6 m)
    start = _box_residual(_body_points(sim, cloud, np.zeros_like(t)))
    assert start.max() > 0.2
    # ...and the residual grows with the time since frame start, as the motion does
    late = t > 0.15
    assert np.median(start[late]) > 10 * np.median(start[t < 0.02]) + 1e-3


def test_frozen_points_lie_on_the_mesh_at_the_frame_start_pose():
    sc = scenario_from_dict(_scenario("frozen", frames=2, frame_period_s=0.5))
    sim = Simulation(sc)
    for frame in (0, 1):
        cloud = sim.run_frame(frame)
        t_start = cloud.frame.t_start
        assert t_start == pytest.approx(0.5 * frame)
        at_start = _box_residual(_body_points(sim, cloud, np.full(len(cloud), t_start)))
        assert at_start.max() < 1e-9
        own_time = _box_residual(_body_points(sim, cloud, cloud["timestamp"]))
        assert own_time.max() > 0.2  # frozen ignores the motion during the frame


def test_per_ray_and_frozen_differ_only_by_the_motion():
    still = _scenario("per_ray")
    still["targets"][0]["trajectory"]["spin_rate_deg_s"] = 0.0
    still["sensor"]["trajectory"].update(velocity_m_s=[0, 0, 0], angular_velocity_deg_s=[0, 0, 0])
    frozen = {**still, "scan": {**still["scan"], "motion": "frozen"}}
    a = Simulation(scenario_from_dict(still)).run_frame(0)
    b = Simulation(scenario_from_dict(frozen)).run_frame(0)
    np.testing.assert_array_equal(a["ray_index"], b["ray_index"])
    np.testing.assert_allclose(a.xyz_true, b.xyz_true, atol=1e-12)


def test_nearer_moving_target_occludes_the_farther_one():
    """A plate sweeping across the view 8 m ahead hides part of a box 15 m ahead; every point
    is on the surface of the body it is labelled with, and no box point was behind the plate
    at its own time."""
    plate = np.array([2.0, 2.0])
    data = {
        "seed": 1,
        "sensor": {"datasheet": datasheet(point_rate_hz=50_000.0), "pose": {}},
        "targets": [
            {"name": "box", "mesh": {"model": "box", "options": {"extents_m": BOX.tolist()}},
             "trajectory": {"kind": "tumbling", "position_m": [15.0, 0.0, 0.0],
                            "spin_rate_deg_s": 40.0}},
            {"name": "plate", "mesh": {"model": "plate", "options": {"size_m": plate.tolist()}},
             "trajectory": {"kind": "constant_velocity", "position_m": [8.0, -1.5, 0.0],
                            "velocity_m_s": [0.0, 10.0, 0.0]}},
        ],
        "scan": {"duration_s": 0.3},
        "backend": "numpy",
        "noise": [],
    }
    sim = Simulation(scenario_from_dict(data))
    cloud = sim.run_frame(0)
    t = cloud["timestamp"]
    label = cloud["target"]
    assert set(np.unique(label)) == {0, 1}
    assert cloud.frame.target_names == ["box", "plate"]
    box_poses = sim.targets[0].trajectory.poses_at(t)
    plate_poses = sim.targets[1].trajectory.poses_at(t)
    on_box = box_poses.apply_inverse(cloud.xyz_true)  # the sensor is at the scene origin
    on_plate = plate_poses.apply_inverse(cloud.xyz_true)
    assert _box_residual(on_box[label == 0]).max() < 1e-9
    assert np.abs(on_plate[label == 1, 0]).max() < 1e-9
    assert np.all(np.abs(on_plate[label == 1, 1:]) <= plate / 2 + 1e-9)
    # box points: the ray to them crosses the plate's plane outside the plate at that time
    rays = cloud.xyz_true[label == 0]
    crossing = rays * (plate_poses.position[label == 0, 0] / rays[:, 0])[:, None]
    local = crossing - plate_poses.position[label == 0]
    assert np.all(np.any(np.abs(local[:, 1:]) > plate / 2 - 1e-9, axis=1))
    # and the plate did hide some box: without it, more rays reach the box
    alone = {**data, "targets": data["targets"][:1]}
    assert len(Simulation(scenario_from_dict(alone)).run_frame(0)) > (label == 0).sum() + 100


def test_numerically_integrated_tumbling_gives_the_same_cloud_on_any_thread_count(monkeypatch):
    data = _scenario("per_ray", frames=2, frame_period_s=2.0)
    data["targets"][0]["trajectory"] = {
        "kind": "torque_free", "position_m": [12.0, 0.0, 0.0],
        "inertia_kg_m2": [1.0, 2.0, 2.5], "angular_velocity_deg_s": [5.0, 40.0, -10.0]}
    data["chunk_rays"] = 3000
    clouds = {}
    for threads in ("1", "4"):
        monkeypatch.setenv("LIDARSIM_THREADS", threads)
        sim = Simulation(scenario_from_dict(data))  # a fresh, empty integration cache each
        clouds[threads] = [sim.run_frame(1), sim.run_frame(0)]
        for cloud in clouds[threads]:
            t = cloud["timestamp"]
            assert _box_residual(_body_points(sim, cloud, t)).max() < 1e-9
    for a, b in zip(clouds["1"], clouds["4"]):
        np.testing.assert_array_equal(a.xyz_true, b.xyz_true)
