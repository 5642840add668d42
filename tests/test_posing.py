"""Per-ray poses in closed form (lidarsim_core.geometry.posing) agree with the SciPy path of
``poses_at``, are shared by culling and casting, and leave third-party trajectories alone."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lidarsim_core.geometry.posing import PoseMatrices, RotationChain
from lidarsim_core.pipeline import Simulation
from lidarsim_core.plugins import get_registry
from lidarsim_core.scenario import load_scenario
from lidarsim_core.trajectories.base import Trajectory
from lidarsim_core.trajectories.matrices import has_fast_path, pose_matrices
from lidarsim_core.trajectories.tumbling import TumblingTrajectory

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "scenarios"
ORBIT = {"altitude_km": 780}
TRAJECTORIES = {
    "tumbling-envisat-2013": ("tumbling", {
        "euler_deg": [-90, 0, -90], "symmetry_axis": [0, 1, 0],
        "angular_momentum_axis": [0, 0, -1], "spin_rate_deg_s": 2.67, "orbit": ORBIT,
        "position_m": [1.0, -2.0, 0.5], "centre_of_mass_m": [0.3, -1.2, 4.0]}),
    "tumbling-nutation": ("tumbling", {
        "euler_deg": [20, 0, 0], "symmetry_axis": [0, 0, 1], "angular_momentum_axis": [0, 0, 1],
        "spin_rate_deg_s": 3.0, "precession_rate_deg_s": 5.0, "t_ref_s": 0.7,
        "centre_of_mass_m": [0.5, 0.1, -0.2]}),
    "torque-free-triaxial-lvlh": ("torque_free", {
        "inertia_kg_m2": [17000, 124000, 129000], "angular_velocity_deg_s": [0.5, 0.2, 3.0],
        "orbit": ORBIT, "centre_of_mass_m": [0.0, 1.0, 2.0], "euler_deg": [10, 20, 30]}),
    "constant-velocity-body": ("constant_velocity", {
        "position_m": [40, -2, 0], "velocity_m_s": [0, 0.5, 0.1], "euler_deg": [0, 10, 30],
        "angular_velocity_deg_s": [1, -4, 10], "t_ref_s": 0.3}),
    "constant-velocity-scene": ("constant_velocity", {
        "velocity_m_s": [0.2, 0, 0], "quaternion_xyzw": [0.1, 0.2, 0.3, 0.9],
        "angular_velocity_deg_s": [0, 0, -7], "angular_velocity_frame": "scene"}),
    "hcw-fly-around": ("hcw", {
        "orbit": ORBIT, "position_m": [0, 50, 0],
        "segments": [{"type": "fly_around", "orbits": 1, "out_of_plane": True}]}),
    "hcw-fixed-attitude": ("hcw", {
        "orbit": ORBIT, "position_m": [0, 30, 0], "segments": [{"type": "hold",
                                                                "duration_s": 60}],
        "attitude": {"mode": "fixed", "euler_deg": [0, 0, -90]}}),
    "keyframes-slerp": ("keyframes", {"keyframes": [
        {"t_s": 0.0, "position_m": [30, 0, 0], "euler_deg": [0, 0, 0]},
        {"t_s": 0.4, "position_m": [29, 2, 1], "euler_deg": [5, -3, 40]},
        {"t_s": 0.4 + 1e-6, "position_m": [29, 2, 1], "euler_deg": [5, -3, 40.0001]},
        {"t_s": 2.0, "position_m": [25, 8, 2], "euler_deg": [-30, 60, 170]}],
        "extrapolate": "hold"}),
    "keyframes-look-at": ("keyframes", {"keyframes": [
        {"t_s": 0.0, "position_m": [30, 0, 0]}, {"t_s": 2.0, "position_m": [20, 10, 5]}],
        "position_interpolation": "cubic", "attitude": {"mode": "look_at"}}),
    "static": ("static", {"position_m": [1, 2, 3], "euler_deg": [10, 20, 30]}),
}


def _trajectory(kind: str, options: dict) -> Trajectory:
    cls = get_registry().get("trajectory", kind)
    return cls.from_config(options)


@pytest.mark.parametrize("name", sorted(TRAJECTORIES))
def test_closed_forms_agree_with_the_scipy_path_to_1e12_m(name):
    trajectory = _trajectory(*TRAJECTORIES[name])
    assert has_fast_path(trajectory)
    t = np.concatenate([np.linspace(-0.5, 2.5, 4001), [0.0, 0.4, 0.4 + 5e-7, 1e-9]])
    fast = pose_matrices(trajectory, t)
    ref = trajectory.poses_at(t)
    # body points up to 30 m from the origin (Envisat's extent), mapped both ways
    points = np.random.default_rng(5).uniform(-30, 30, (len(t), 3))
    mapped = np.einsum("nij,nj->ni", fast.matrix, points) + fast.position
    np.testing.assert_allclose(mapped, ref.apply(points), rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast.position, ref.position, rtol=0, atol=1e-12)
    # proper rotations
    eye = np.einsum("nij,nkj->nik", fast.matrix, fast.matrix)
    np.testing.assert_allclose(eye, np.broadcast_to(np.eye(3), eye.shape), atol=1e-14)


def test_compiled_chain_is_within_a_few_ulp_of_numpy():
    pytest.importorskip("numba")
    from lidarsim_core.kernels.poses import chain_matrices

    trajectory = _trajectory(*TRAJECTORIES["tumbling-nutation"])
    chain = trajectory._chain
    assert len(chain.rates) == 2
    tau = np.random.default_rng(1).uniform(-100, 100, 10_000)
    compiled = chain_matrices(tau, chain.fixed, chain.axes, chain.rates)
    reference = chain.matrices_numpy(tau)
    assert np.abs(compiled - reference).max() <= 8 * np.finfo(float).eps


def test_chain_composes_in_order_against_scipy():
    from scipy.spatial.transform import Rotation

    r0 = Rotation.from_euler("xyz", [10, 20, 30], degrees=True)
    a, b = np.array([0.0, 0.6, 0.8]), np.array([1.0, 0.0, 0.0])
    chain = RotationChain.build((a, 0.3), r0, (b, -2.0), r0.inv())
    tau = np.linspace(-3, 3, 13)
    ref = Rotation.from_rotvec(np.outer(0.3 * tau, a)) * r0 * \
        Rotation.from_rotvec(np.outer(-2.0 * tau, b)) * r0.inv()
    np.testing.assert_allclose(chain.matrices_numpy(tau), ref.as_matrix(), atol=1e-15)


def test_a_subclass_overriding_poses_at_and_plugins_take_the_general_path():
    class Shifted(TumblingTrajectory):
        def poses_at(self, t):
            poses = super().poses_at(t)
            return type(poses)(poses.position + 1.0, poses.rotation)

    class ThirdParty(Trajectory):
        name = "third_party"

        def poses_at(self, t):
            return _trajectory("static", {"position_m": [0, 0, 1]}).poses_at(t)

    shifted = Shifted.from_config({"spin_rate_deg_s": 3.0})
    assert not has_fast_path(shifted)
    t = np.linspace(0, 1, 5)
    np.testing.assert_allclose(pose_matrices(shifted, t).position, 1.0)
    plugin = ThirdParty.from_config({})
    assert not has_fast_path(plugin)
    got = pose_matrices(plugin, t)
    assert isinstance(got, PoseMatrices)
    np.testing.assert_array_equal(got.position, np.tile([0, 0, 1.0], (5, 1)))


def test_poses_are_computed_once_per_piece_and_the_frame_matches_the_scipy_path(monkeypatch):
    """The tumbling hold: trajectories are evaluated twice per piece (once at the piece's
    middle time for culling, once at the times of the pulses it keeps; once without the
    kernels, which do not cull; pieces of 4,096 pulses are too short for direction groups,
    whose cull would evaluate them at the piece's middle time again), and the points agree
    with the SciPy path of ``poses_at`` to 1e-12 m."""
    import lidarsim_core.trajectories.matrices as posing

    scenario = load_scenario(EXAMPLES / "envisat_tumbling_hold.yaml")
    sim = Simulation(scenario)
    calls = {"n": 0}
    original = posing.pose_matrices

    def counting(trajectory, t):
        calls["n"] += 1
        return original(trajectory, t)

    monkeypatch.setattr("lidarsim_core.pipeline.context.pose_matrices", counting)
    monkeypatch.setenv("LIDARSIM_THREADS", "1")
    fast = sim.run_frame(0, chunk_rays=4096)
    k0, k1 = sim.frame_rays(0)
    pieces = -(-(k1 - k0) // 4096)
    # sensor and target, twice per piece each when culling (without the kernels: once)
    assert calls["n"] == (2 if sim.culler is None else 4) * pieces

    monkeypatch.setattr(posing, "has_fast_path", lambda trajectory: False)
    reference = Simulation(scenario).run_frame(0, chunk_rays=4096)
    assert len(fast) == len(reference) > 500
    np.testing.assert_array_equal(fast["ray_index"], reference["ray_index"])
    for column in ("x_true", "y_true", "z_true", "range_true", "x", "y", "z"):
        np.testing.assert_allclose(fast[column], reference[column], rtol=0, atol=1e-12,
                                   err_msg=column)


@pytest.mark.parametrize("scene", ["tumbling-risley", "flyaround-50m", "vlp16-circling-15m"])
def test_per_ray_poses_give_the_same_bytes_for_any_chunk_size_and_threads(scene, monkeypatch):
    from lidarsim_core.bench.suite import SUITE
    from lidarsim_core.scenario import scenario_from_dict

    scenario = scenario_from_dict(SUITE[scene][1](0.03), source="<test>")
    clouds = []
    for threads, chunk in (("1", 1), ("1", 997), ("2", 65536)):
        monkeypatch.setenv("LIDARSIM_THREADS", threads)
        clouds.append(Simulation(scenario).run_frame(0, chunk_rays=chunk))
    assert len(clouds[0]) > 50
    for other in clouds[1:]:
        for name, column in clouds[0].columns.items():
            assert column.tobytes() == other[name].tobytes(), name
