"""Torque-free tumbling: the closed-form axisymmetric motion and Euler's equations agree with
each other and with the conservation laws."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.trajectories.orbit import mean_motion_from_altitude
from lidarsim_core.trajectories.tumbling import TorqueFreeTrajectory, TumblingTrajectory

R0 = Rotation.from_euler("xyz", [10.0, 20.0, 30.0], degrees=True)


def _angular_velocity(traj, t: np.ndarray, h: float = 1e-4) -> np.ndarray:
    """Scene-frame angular velocity by central differences of the rotations."""
    plus = traj.poses_at(t + h).rotation
    minus = traj.poses_at(t - h).rotation
    return (plus * minus.inv()).as_rotvec() / (2 * h)


def test_flat_spin_has_the_given_rate_and_period():
    # Envisat in 2013: 2.67 °/s about the orbit anti-normal; spin axis body +Y (estimate)
    traj = TumblingTrajectory.from_config({
        "euler_deg": [-90, 0, -90], "symmetry_axis": [0, 1, 0],
        "angular_momentum_axis": [0, 0, -1], "spin_rate_deg_s": 2.67})
    t = np.linspace(0, 300, 31)
    omega = _angular_velocity(traj, t)
    np.testing.assert_allclose(omega, [[0, 0, -math.radians(2.67)]] * len(t), atol=1e-9)
    period = 360 / 2.67  # 134.83 s (ESA: 134.74 s)
    start, end = traj.poses_at(np.array([0.0, period])).rotation
    assert (start.inv() * end).magnitude() < 1e-9
    # the solar-array tip (21 m along body +X from the bus centre) moves at ω·r ≈ 0.98 m/s
    tip = np.array([[21.0, 5.8, 0.0]])
    p = [traj.poses_at(np.array([t0])).apply(tip)[0] for t0 in (10.0, 10.001)]
    speed = np.linalg.norm(p[1] - p[0]) / 0.001
    assert speed == pytest.approx(math.radians(2.67) * 21.0, rel=1e-5)


def test_spin_plus_precession_angular_velocity_and_nutation_cone():
    h = np.array([0.0, 0.0, 1.0])
    s_body = np.array([0.0, 0.0, 1.0])
    tilt = Rotation.from_euler("x", 30, degrees=True)  # 30° nutation
    traj = TumblingTrajectory.from_config({
        "quaternion_xyzw": tilt.as_quat().tolist(), "symmetry_axis": s_body.tolist(),
        "angular_momentum_axis": h.tolist(), "spin_rate_deg_s": 4.0,
        "precession_rate_deg_s": 6.0, "position_m": [5, 6, 7]})
    assert math.degrees(traj.options.nutation_rad) == pytest.approx(30.0)
    t = np.linspace(0, 200, 41)
    rot = traj.poses_at(t).rotation
    axis = rot.apply(s_body)
    # the symmetry axis stays on the 30° cone about h and turns about it at 6 °/s
    np.testing.assert_allclose(axis @ h, math.cos(math.radians(30)), atol=1e-12)
    azimuth = np.unwrap(np.arctan2(axis[:, 1], axis[:, 0]))
    np.testing.assert_allclose(np.diff(azimuth) / np.diff(t), math.radians(6.0), rtol=1e-9)
    # ω = φ̇ h + ψ̇ s(t)
    expected = math.radians(6.0) * h + math.radians(4.0) * axis
    np.testing.assert_allclose(_angular_velocity(traj, t), expected, atol=1e-9)
    np.testing.assert_allclose(traj.poses_at(t).position, [[5, 6, 7]] * len(t))


def test_rotation_is_about_the_centre_of_mass():
    com = np.array([1.0, -2.0, 0.5])
    traj = TumblingTrajectory.from_config({
        "position_m": [40, 0, 0], "centre_of_mass_m": com.tolist(), "spin_rate_deg_s": 30.0})
    poses = traj.poses_at(np.linspace(0, 20, 9))
    np.testing.assert_allclose(poses.apply(np.tile(com, (9, 1))), [[40, 0, 0]] * 9, atol=1e-12)


def test_euler_equations_match_the_closed_form_for_an_axisymmetric_body():
    it, ia = 100.0, 40.0
    w0 = np.radians([1.0, -2.0, 3.0])  # body frame
    numeric = TorqueFreeTrajectory.from_config({
        "inertia_kg_m2": [it, it, ia], "angular_velocity_deg_s": np.degrees(w0).tolist(),
        "quaternion_xyzw": R0.as_quat().tolist()})
    # textbook solution: φ̇ = |H|/I_t about H, ψ̇ = (I_t - I_a)/I_t · ω_z about the body axis
    h_body = np.array([it, it, ia]) * w0
    h = R0.apply(h_body)
    closed = TumblingTrajectory.from_config({
        "quaternion_xyzw": R0.as_quat().tolist(), "symmetry_axis": [0, 0, 1],
        "angular_momentum_axis": h.tolist(),
        "precession_rate_deg_s": math.degrees(np.linalg.norm(h) / it),
        "spin_rate_deg_s": math.degrees((it - ia) / it * w0[2])})
    assert closed.options.inertia_ratio == pytest.approx(ia / it)
    t = np.linspace(-100, 600, 2001)  # before and after t_ref
    a, b = numeric.poses_at(t).rotation, closed.poses_at(t).rotation
    assert (a.inv() * b).magnitude().max() < 1e-8


def test_triaxial_body_conserves_momentum_and_energy_and_flips_about_the_middle_axis():
    inertia = np.array([100.0, 200.0, 250.0])
    # spin about the intermediate axis with a tiny perturbation: the Dzhanibekov flip
    traj = TorqueFreeTrajectory.from_config({
        "inertia_kg_m2": inertia.tolist(), "angular_velocity_deg_s": [0.01, 20.0, 0.01]})
    t = np.linspace(0, 200, 2001)  # the flip comes after ~50 s here
    states = traj.states(t)
    omega = states[:, 4:]
    momentum = traj.angular_momentum_inertial(t)
    np.testing.assert_allclose(momentum, np.tile(momentum[0], (len(t), 1)),
                               atol=1e-8 * np.linalg.norm(momentum[0]))
    energy = 0.5 * np.einsum("ij,j,ij->i", omega, inertia, omega)
    np.testing.assert_allclose(energy, energy[0], rtol=1e-9)
    assert omega[:, 1].min() < -0.9 * omega[0, 1]  # the spin reversed in the body frame
    # about the major axis the same perturbation stays small
    stable = TorqueFreeTrajectory.from_config({
        "inertia_kg_m2": inertia.tolist(), "angular_velocity_deg_s": [0.01, 0.01, 20.0]})
    w = stable.states(t)[:, 4:]
    assert np.abs(w[:, :2]).max() < math.radians(0.05)


def test_full_inertia_tensor_equals_principal_axes_in_a_rotated_frame():
    q = Rotation.from_euler("zyx", [30, -10, 50], degrees=True)  # principal → body axes
    moments = np.array([120.0, 150.0, 220.0])
    tensor = q.as_matrix() @ np.diag(moments) @ q.as_matrix().T
    w_principal = np.array([2.0, -1.0, 5.0])
    full = TorqueFreeTrajectory.from_config({
        "inertia_kg_m2": tensor.tolist(), "angular_velocity_deg_s": q.apply(w_principal).tolist()})
    principal = TorqueFreeTrajectory.from_config({
        "inertia_kg_m2": moments.tolist(), "angular_velocity_deg_s": w_principal.tolist(),
        "quaternion_xyzw": q.as_quat().tolist()})
    t = np.linspace(0, 300, 301)
    # body→scene of the principal frame equals body→scene of the full body times q
    a = full.poses_at(t).rotation * q
    b = principal.poses_at(t).rotation
    assert (a.inv() * b).magnitude().max() < 1e-8


def test_numerical_solution_does_not_depend_on_the_order_times_are_asked_in():
    options = {"inertia_kg_m2": [100.0, 200.0, 250.0], "angular_velocity_deg_s": [3, 20, -4]}
    t = np.linspace(-130, 250, 1001)  # six cached pieces
    whole = TorqueFreeTrajectory.from_config(options).states(t)
    pieces = TorqueFreeTrajectory.from_config(options)
    parts = [pieces.states(t[i::7]) for i in reversed(range(7))]  # late times first
    again = np.empty_like(whole)
    for i, part in zip(reversed(range(7)), parts):
        again[i::7] = part
    np.testing.assert_array_equal(again, whole)


def test_orbit_option_turns_inertial_motion_into_the_rotating_lvlh_frame():
    n = mean_motion_from_altitude(780.0)
    # inertially fixed body: in LVLH it turns at -n about H-bar (+z)
    still = TumblingTrajectory.from_config({"orbit": {"altitude_km": 780}})
    t = np.array([0.0, 100.0, 3000.0])
    expected = Rotation.from_rotvec(np.outer(-n * t, [0, 0, 1]))
    assert (still.poses_at(t).rotation.inv() * expected).magnitude().max() < 1e-12
    # a 2.67 °/s spin about -z appears as (2.67 °/s + n) about -z in LVLH
    spin = TumblingTrajectory.from_config({
        "euler_deg": [-90, 0, -90], "symmetry_axis": [0, 1, 0],
        "angular_momentum_axis": [0, 0, -1], "spin_rate_deg_s": 2.67,
        "orbit": {"mean_motion_rad_s": n}})
    omega = _angular_velocity(spin, np.array([50.0]))[0]
    np.testing.assert_allclose(omega, [0, 0, -(math.radians(2.67) + n)], atol=1e-9)
    numeric = TorqueFreeTrajectory.from_config({
        "inertia_kg_m2": [1, 2, 2.5], "angular_velocity_deg_s": [0, 0, 0],
        "orbit": {"mean_motion_rad_s": n}})
    assert (numeric.poses_at(t).rotation.inv() * expected).magnitude().max() < 1e-10


@pytest.mark.parametrize("cls, options, field, words", [
    (TumblingTrajectory, {"euler_deg": [30, 0, 0], "spin_rate_deg_s": 3.0},
     "targets.0.trajectory", "not the torque-free motion"),
    (TumblingTrajectory, {"symmetry_axis": [0, 0, 0]}, "targets.0.trajectory.symmetry_axis",
     "non-zero"),
    (TumblingTrajectory, {"spin_rate_deg_s": float("nan")},
     "targets.0.trajectory.spin_rate_deg_s", "finite"),
    (TumblingTrajectory, {"quaternion_xyzw": [0, 0, 0, 0]}, "targets.0.trajectory",
     "zero norm"),
    (TorqueFreeTrajectory, {"inertia_kg_m2": [1, 1, 3], "angular_velocity_deg_s": [0, 0, 1]},
     "targets.0.trajectory.inertia_kg_m2", "triangle inequality"),
    (TorqueFreeTrajectory, {"inertia_kg_m2": [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]],
                            "angular_velocity_deg_s": [0, 0, 1]},
     "targets.0.trajectory.inertia_kg_m2", "symmetric"),
    (TorqueFreeTrajectory, {"inertia_kg_m2": [1, -1, 1], "angular_velocity_deg_s": [0, 0, 1]},
     "targets.0.trajectory.inertia_kg_m2", "positive definite"),
    (TorqueFreeTrajectory, {"inertia_kg_m2": [1, 1, 1]},
     "targets.0.trajectory.angular_velocity_deg_s", "required"),
])
def test_unphysical_tumbling_is_a_one_line_error(cls, options, field, words):
    with pytest.raises(ConfigError) as err:
        cls.from_config(options, source="s.yaml", field="targets.0.trajectory")
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(f"s.yaml: field '{field}'")
    assert words in message
