"""HCW relative motion: closed form against the equations of motion and classic manoeuvres."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.trajectories.hcw import HCWTrajectory
from lidarsim_core.trajectories.orbit import (
    MU_EARTH_M3_S2,
    OrbitConfig,
    hcw_positions,
    hcw_propagate,
    hcw_state,
    mean_motion_from_altitude,
)

N = 2 * math.pi / 6000.0  # a 100-minute orbit


def _hcw(**options) -> HCWTrajectory:
    options.setdefault("orbit", {"mean_motion_rad_s": N})
    return HCWTrajectory.from_config(options, source="s.yaml", field="sensor.trajectory")


def test_mean_motion_from_altitude_gives_known_periods():
    # geostationary altitude 35 786 km: one sidereal day (86 164.1 s)
    assert 2 * math.pi / mean_motion_from_altitude(35_786.0) == pytest.approx(86_164.1, rel=2e-4)
    # Kepler's third law at 780 km (Envisat's altitude class): ~100.3 min
    a = 6_378_137.0 + 780e3
    assert OrbitConfig(altitude_km=780).period == pytest.approx(2 * math.pi * math.sqrt(
        a ** 3 / MU_EARTH_M3_S2))
    assert OrbitConfig(period_s=6000).mean_motion == pytest.approx(N)


def test_closed_form_satisfies_the_hcw_equations():
    rng = np.random.default_rng(4)
    p0, v0 = rng.normal(0, 50, 3), rng.normal(0, 0.1, 3)
    t = np.linspace(-3000, 9000, 301)
    h = 0.5
    pos, vel = hcw_propagate(p0, v0, N, t)
    p_plus, _ = hcw_propagate(p0, v0, N, t + h)
    p_minus, _ = hcw_propagate(p0, v0, N, t - h)
    acc = (p_plus - 2 * pos + p_minus) / h ** 2
    np.testing.assert_allclose((p_plus - p_minus) / (2 * h), vel, atol=1e-7)
    x, z = pos[:, 0], pos[:, 2]
    vx, vy = vel[:, 0], vel[:, 1]
    expected = np.column_stack([3 * N ** 2 * x + 2 * N * vy, -2 * N * vx, -N ** 2 * z])
    np.testing.assert_allclose(acc, expected, atol=1e-8)
    # and it starts from the given state
    start = hcw_propagate(p0, v0, N, np.array([0.0]))
    np.testing.assert_allclose(start[0][0], p0, atol=1e-12)
    np.testing.assert_allclose(start[1][0], v0, atol=1e-15)


def test_two_to_one_ellipse_closes_after_one_orbit():
    traj = _hcw(position_m=[0, 100, 0], segments=[{"type": "fly_around", "orbits": 2}])
    period = 2 * math.pi / N
    t = np.linspace(0, period, 2001)
    pos, vel = traj.states_at(t)
    np.testing.assert_allclose(pos[-1], pos[0], atol=1e-9)
    np.testing.assert_allclose(vel[-1], vel[0], atol=1e-12)
    # semi-axes 50 m radial, 100 m along-track (2:1), centred on the target, in plane
    assert np.ptp(pos[:, 0]) / 2 == pytest.approx(50.0, rel=1e-5)
    assert np.ptp(pos[:, 1]) / 2 == pytest.approx(100.0, rel=1e-9)
    np.testing.assert_allclose(pos.mean(axis=0)[:2], 0.0, atol=0.1)
    assert np.abs(pos[:, 2]).max() == 0.0
    # x²/50² + y²/100² = 1 everywhere
    np.testing.assert_allclose((pos[:, 0] / 50) ** 2 + (pos[:, 1] / 100) ** 2, 1.0, atol=1e-12)
    # from +V-bar the natural motion rises toward +R-bar first
    assert pos[100, 0] > 0 and pos[500, 1] == pytest.approx(0.0, abs=1e-9)
    # one impulse inserted it: Δv = n·y/2 radially
    assert len(traj.impulses) == 1
    np.testing.assert_allclose(traj.impulses[0][1], [N * 50, 0, 0])


def test_out_of_plane_fly_around_keeps_a_constant_range():
    traj = _hcw(position_m=[0, 50, 0],
                segments=[{"type": "fly_around", "orbits": 1, "out_of_plane": True}])
    t = np.linspace(0, 2 * math.pi / N, 997)
    pos, _ = traj.states_at(t)
    np.testing.assert_allclose(np.linalg.norm(pos, axis=1), 50.0, atol=1e-9)
    np.testing.assert_allclose(pos[:, 2], math.sqrt(3) * pos[:, 0], atol=1e-9)
    np.testing.assert_allclose(pos[-1], pos[0], atol=1e-9)


def test_vbar_is_a_natural_equilibrium_and_radial_hops_move_along_it():
    still = _hcw(position_m=[0, 30, 0])
    pos, vel = still.states_at(np.array([-500.0, 0.0, 1234.5, 1e5]))
    np.testing.assert_allclose(pos, [[0, 30, 0]] * 4, atol=1e-9)
    np.testing.assert_allclose(vel, 0.0, atol=1e-12)
    # a radial impulse vx returns to V-bar half an orbit later, 4·vx/n closer (toward -y)
    vx = 0.05
    half = math.pi / N
    hop = _hcw(position_m=[0, 250, 0],
               segments=[{"type": "coast", "duration_s": half, "delta_v_m_s": [vx, 0, 0]}])
    pos, vel = hop.states_at(np.array([half]))
    np.testing.assert_allclose(pos[0], [0, 250 - 4 * vx / N, 0], atol=1e-9)
    np.testing.assert_allclose(vel[0], [-vx, 0, 0], atol=1e-12)


def test_forced_vbar_approach_with_holds():
    traj = _hcw(orbit={"altitude_km": 780}, position_m=[0, 250, 0],
                segments=[{"type": "straight", "to_m": [0, 100, 0], "speed_m_s": 0.5},
                          {"type": "hold", "duration_s": 60},
                          {"type": "straight", "to_m": [0, 20, 0], "duration_s": 400}])
    assert traj.end_time_s == pytest.approx(760.0)
    t = np.array([0, 150, 300, 330, 360, 560, 760, 2000.0])
    pos, vel = traj.states_at(t)
    np.testing.assert_allclose(pos, [[0, y, 0] for y in (250, 175, 100, 100, 100, 60, 20, 20)],
                               atol=1e-9)
    np.testing.assert_allclose(vel[1], [0, -0.5, 0])
    np.testing.assert_allclose(vel[5], [0, -0.2, 0])
    np.testing.assert_allclose(vel[-1], 0.0, atol=1e-12)  # at rest on V-bar afterwards
    starts = [round(t0) for t0, _ in traj.impulses]
    assert starts == [0, 300, 360, 760]


def test_one_state_in_floats_is_a_row_of_the_arrays_bit_for_bit():
    """hcw_state (plain floats, NumPy's own sine and cosine) gives the bits of the vectorised
    closed form's row, positions and velocities, for (3,) states with each row's own tau."""
    rng = np.random.default_rng(11)
    p, v = rng.normal(0, 80, (200, 3)), rng.normal(0, 0.3, (200, 3))
    tau = np.concatenate([rng.uniform(-9000, 9000, 100), rng.uniform(-1, 1, 100)])
    for k in range(200):
        ref_p, ref_v = hcw_propagate(p[k], v[k], N, tau[k:k + 1])
        pos, vel = hcw_state(p[k], v[k], N, float(tau[k]))
        assert np.array_equal(np.array(pos), ref_p[0]) and np.array_equal(np.array(vel), ref_v[0])
    # the same rows of one array call (a state broadcast over many times)
    many_p, many_v = hcw_propagate(p[0], v[0], N, tau)
    assert np.array_equal(hcw_positions(p[0], v[0], N, tau), many_p)
    rows = np.array([hcw_state(p[0], v[0], N, float(t)) for t in tau])
    assert np.array_equal(rows[:, 0], many_p) and np.array_equal(rows[:, 1], many_v)


def test_one_time_is_the_row_of_many_on_every_kind_of_segment():
    """states_at and pose_matrices of one time (the culling's middle poses, plain floats) equal
    that time's row of a call with many, on natural, hold and straight segments and on their
    boundaries (a boundary belongs to the later segment)."""
    traj = _hcw(orbit={"altitude_km": 780}, position_m=[5, 250, -3], velocity_m_s=[0.01, 0, 0.02],
                segments=[{"type": "coast", "duration_s": 100},
                          {"type": "straight", "to_m": [0, 100, 0], "speed_m_s": 0.5},
                          {"type": "hold", "duration_s": 60},
                          {"type": "coast", "duration_s": 50, "delta_v_m_s": [0, 0.01, 0]}])
    times = np.concatenate([[-50.0, 0.0, 100.0], [t0 for t0, _ in traj.impulses],
                            np.linspace(-10, traj.end_time_s + 100, 97)])
    pos, vel = traj.states_at(times)
    poses = traj.pose_matrices(times).full(len(times))
    for i, t in enumerate(times):
        one_p, one_v = traj.states_at(np.array([t]))
        assert np.array_equal(one_p[0], pos[i]), t
        assert np.array_equal(one_v[0], vel[i]), t
        one = traj.pose_matrices(np.array([t]))
        assert np.array_equal(one.position[0], poses.position[i]), t
        assert np.array_equal(one.matrix[0], poses.matrix[i]), t


def test_look_at_attitude_points_the_boresight_at_the_target():
    traj = _hcw(position_m=[0, 60, 0], segments=[{"type": "fly_around", "orbits": 1}])
    t = np.linspace(0, 6000, 50)
    poses = traj.poses_at(t)
    boresight = poses.rotation.apply([1.0, 0.0, 0.0])
    np.testing.assert_allclose(boresight, -poses.position / np.linalg.norm(
        poses.position, axis=1, keepdims=True), atol=1e-12)
    up = poses.rotation.apply([0.0, 0.0, 1.0])
    np.testing.assert_allclose(up, [[0, 0, 1]] * len(t), atol=1e-12)  # in-plane: +Z = H-bar
    # R-bar approach: boresight along x, up stays +H-bar
    rbar = _hcw(position_m=[-80, 0, 0],
                segments=[{"type": "straight", "to_m": [-20, 0, 0], "speed_m_s": 0.1}])
    r = rbar.poses_at(np.array([100.0])).rotation
    np.testing.assert_allclose(r.apply([1.0, 0, 0])[0], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(r.apply([0, 0, 1.0])[0], [0, 0, 1], atol=1e-12)
    fixed = _hcw(position_m=[0, 60, 0], attitude={"mode": "fixed", "euler_deg": [0, 0, -90]})
    np.testing.assert_allclose(fixed.poses_at(np.array([5.0])).rotation.apply([1.0, 0, 0]),
                               [[0, -1, 0]], atol=1e-12)


@pytest.mark.parametrize("options, field, words", [
    ({"position_m": [0, 50, 0], "orbit": {}}, "sensor.trajectory.orbit", "exactly one"),
    ({"position_m": [0, 50, 0], "orbit": {"altitude_km": 500, "period_s": 6000}},
     "sensor.trajectory.orbit", "exactly one"),
    ({"position_m": [0, 50, 0], "orbit": {"altitude_km": -5}},
     "sensor.trajectory.orbit.altitude_km", "greater than 0"),
    ({"position_m": [10, 50, 0],
      "segments": [{"type": "fly_around", "orbits": 1, "out_of_plane": True}]},
     "sensor.trajectory.segments.0", "z = √3·x"),
    ({"position_m": [0, 50, 0],
      "segments": [{"type": "straight", "to_m": [0, 20, 0], "speed_m_s": 1, "duration_s": 3}]},
     "sensor.trajectory.segments.0.straight", "exactly one"),
    ({"position_m": [0, 50, 0], "segments": [{"type": "straight", "to_m": [0, 50, 0],
                                              "speed_m_s": 1}]},
     "sensor.trajectory.segments.0.to_m", "end point"),
    ({"position_m": [0, 50, 0], "segments": [{"type": "hold", "duration_s": -1}]},
     "sensor.trajectory.segments.0.hold.duration_s", "greater than 0"),
    ({"position_m": [0, 50, 0], "segments": [{"type": "warp", "duration_s": 1}]},
     "sensor.trajectory.segments.0", "tag"),
])
def test_bad_hcw_options_are_one_line_errors(options, field, words):
    options.setdefault("orbit", {"mean_motion_rad_s": N})
    with pytest.raises(ConfigError) as err:
        HCWTrajectory.from_config(options, source="s.yaml", field="sensor.trajectory")
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(f"s.yaml: field '{field}'")
    assert words in message
