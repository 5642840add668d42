"""The closed loop (lidarsim_core.loop): stepping is the same simulator as a scenario run, the
record replays to the bit, and the commanded motion follows the HCW equations."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.loop import LoopSession, hcw_forced, propagate
from lidarsim_core.loop.dynamics import hcw_step
from lidarsim_core.loop.pointing import Pointing
from lidarsim_core.pipeline.simulation import Simulation
from lidarsim_core.scenario.load import load_scenario, scenario_from_dict
from lidarsim_core.trajectories.attitude import FixedAttitude, LookAtAttitude
from lidarsim_core.trajectories.orbit import hcw_propagate, mean_motion_from_altitude

ROOT = Path(__file__).resolve().parents[1]
N780 = mean_motion_from_altitude(780)
TUMBLING = {"kind": "tumbling", "position_m": [0, 0, 0], "centre_of_mass_m": [0, 0, 0],
            "euler_deg": [-90, 0, -90], "symmetry_axis": [0, 1, 0],
            "angular_momentum_axis": [0, 0, -1], "spin_rate_deg_s": 2.67,
            "orbit": {"altitude_km": 780}}


def scene(sensor_trajectory: dict, *, frames: int = 3, seed: int = 11) -> dict:
    """A MID-70 near Envisat (coarse) tumbling at its 2013 rate, 0.1 s frames."""
    return {"seed": seed,
            "sensor": {"datasheet": "livox-mid70-rose", "trajectory": sensor_trajectory},
            "targets": [{"name": "envisat", "mesh": {"model": "envisat",
                                                     "options": {"detail": "coarse"}},
                         "trajectory": TUMBLING}],
            "scan": {"duration_s": 0.1, "frame_rate_hz": 10, "frames": frames}}


APPROACH = {"kind": "hcw", "orbit": {"altitude_km": 780}, "position_m": [0, 22, 0],
            "segments": [{"type": "straight", "to_m": [1.0, 12.0, 0.5], "speed_m_s": 2.0}]}


def assert_same_cloud(a, b, *, same_hash: bool = True) -> None:
    """Every column to the bit and the frame metadata equal (the configuration hash names the
    scenario file, which differs for a replay)."""
    assert len(a) == len(b) > 50
    assert list(a.columns) == list(b.columns)
    for key in a.columns:
        assert a.columns[key].dtype == b.columns[key].dtype, key
        assert a.columns[key].tobytes() == b.columns[key].tobytes(), key
    da, db = a.frame.to_dict(), b.frame.to_dict()
    if not same_hash:
        da.pop("config_hash"), db.pop("config_hash")
    assert da == db


@pytest.fixture(scope="module")
def approach_sim() -> Simulation:
    return Simulation(scenario_from_dict(scene(APPROACH)))


def test_steps_on_the_scenario_trajectories_give_its_frames(approach_sim):
    """Moving sensor (2 m/s straight HCW leg) and tumbling target: stepping the session
    along the scenario's own trajectories gives the scenario's frames to the bit."""
    session = LoopSession(approach_sim, steer_sensor=False)
    for frame in range(3):
        assert_same_cloud(session.step().cloud, approach_sim.run_frame(frame))
    assert session.frame == 3 and session.time_s == pytest.approx(0.3)
    # the state reported is the trajectory's: 2 m/s along the leg
    velocity = session.state.velocity_m_s
    assert np.linalg.norm(velocity) == pytest.approx(2.0)
    np.testing.assert_allclose(velocity / 2.0, np.array([1.0, -10.0, 0.5]) /
                               np.linalg.norm([1.0, -10.0, 0.5]), atol=1e-12)


def test_steering_with_the_scenario_poses_gives_its_frames():
    """The chaser steered step by step with the poses of the scenario's own keyframe
    trajectory (a keyframe at every frame boundary, linear/SLERP: the loop's interpolation)
    gives the scenario's frames to the bit: the loop is the same simulator."""
    times = [0.0, 0.1, 0.2, 0.30000000000000004]
    turn = Rotation.from_euler("xyz", [[2, -3, -90 + 4 * i] for i in range(4)], degrees=True)
    quats = [[float(v) for v in q] for q in turn.as_quat()]
    positions = [[0.3 * i, 25.0 - 1.5 * i, 0.1 * i * i] for i in range(4)]
    traj = {"kind": "keyframes", "position_interpolation": "linear",
            "rotation_interpolation": "slerp",
            "keyframes": [{"t_s": t, "position_m": p, "quaternion_xyzw": q}
                          for t, p, q in zip(times, positions, quats)]}
    sim = Simulation(scenario_from_dict(scene(traj)))
    session = LoopSession(sim)
    assert session.state.position_m.tolist() == positions[0]
    for frame in range(3):
        result = session.step(0.1, position_m=positions[frame + 1],
                              quaternion_xyzw=quats[frame + 1])
        assert_same_cloud(result.cloud, sim.run_frame(frame))


def commands(session: LoopSession) -> list:
    """Four steps of impulses and accelerations, kept for a second identical session."""
    return [session.step(0.1, delta_v_m_s=[0.05, -0.4, 0.02]),
            session.step(0.1),
            session.step(0.1, acceleration_m_s2=[0.1, 0.2, -0.3]),
            session.step(0.1, delta_v_m_s=[0.0, 0.1, 0.0], acceleration_m_s2=[0, 0, 0.5])]


def test_the_record_replays_the_loop_to_the_bit(approach_sim, tmp_path):
    """The keyframe file and scenario written by record() give every frame of the loop to the
    bit through the Python API, `lidarsim simulate` and `lidarsim dataset` (read back with
    numpy.load)."""
    session = LoopSession(approach_sim, seed=99)
    results = commands(session)
    (tmp_path / "rec").mkdir()
    path = session.record(tmp_path / "rec" / "loop.yaml")
    assert (tmp_path / "rec" / "loop.sensor.csv").read_text().count("\n") == 1 + 5  # header, start, 4 steps
    replay = Simulation(load_scenario(path))
    for frame, result in enumerate(results):
        assert_same_cloud(result.cloud, replay.run_frame(frame), same_hash=False)
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1"}
    run = [sys.executable, "-m", "lidarsim_core"]
    out = subprocess.run(run + ["simulate", str(path), "--frame", "2", "--out",
                                str(tmp_path / "f2.npz")], env=env, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    ds = subprocess.run(run + ["dataset", str(path), "--out", str(tmp_path / "ds"), "--format",
                               "npz"], env=env, capture_output=True, text=True, timeout=300)
    assert ds.returncode == 0, ds.stderr
    files = [(2, tmp_path / "f2.npz")] + \
        [(i, tmp_path / "ds" / "frames" / f"frame_{i:06d}.npz") for i in range(4)]
    for frame, file in files:
        with np.load(file) as data:
            for key, column in results[frame].cloud.columns.items():
                assert data[key].tobytes() == column.tobytes(), (file, key)


def test_same_commands_same_frames_and_the_seed_changes_the_noise(approach_sim):
    a = commands(LoopSession(approach_sim, seed=5))
    b = commands(LoopSession(approach_sim, seed=5))
    c = commands(LoopSession(approach_sim, seed=6))
    for ra, rb in zip(a, b):
        assert_same_cloud(ra.cloud, rb.cloud)
    assert not np.array_equal(a[0].cloud.columns["range"], c[0].cloud.columns["range"])
    # the seed is the noise's only: the chaser flies the same path
    assert a[-1].state.position_m.tolist() == c[-1].state.position_m.tolist()


def test_commanded_motion_follows_the_hcw_equations(approach_sim):
    """The chaser's end state after an impulse and an acceleration is the numerical
    integration of the HCW equations (an independent solution), and its pose in the frame
    metadata is the one the session reports."""
    session = LoopSession(approach_sim)
    p0, v0 = session.state.position_m, session.state.velocity_m_s
    dv, acc = np.array([0.05, -0.4, 0.02]), np.array([0.1, 0.2, -0.3])
    result = session.step(0.1, delta_v_m_s=dv, acceleration_m_s2=acc)

    def rhs(_t, s):
        x, y, z, vx, vy, vz = s
        n = N780
        return [vx, vy, vz, 3 * n * n * x + 2 * n * vy + acc[0], -2 * n * vx + acc[1],
                -n * n * z + acc[2]]

    sol = solve_ivp(rhs, (0, 0.1), np.r_[p0, v0 + dv], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(result.state.position_m, sol.y[:3, -1], atol=1e-10)
    np.testing.assert_allclose(result.state.velocity_m_s, sol.y[3:, -1], atol=1e-10)
    end = result.info.sensor_pose_end
    assert end["translation_m"] == result.state.position_m.tolist()
    # the default attitude law: boresight (+X) at the target's centre
    boresight = Rotation.from_quat(end["quaternion_xyzw"]).apply([1.0, 0, 0])
    np.testing.assert_allclose(boresight, -result.state.position_m
                               / np.linalg.norm(result.state.position_m), atol=1e-12)
    # the true relative pose: the target's origin seen from the sensor
    t_in_s, _ = result.target_in_sensor()
    assert np.linalg.norm(t_in_s) == pytest.approx(np.linalg.norm(result.state.position_m))


def test_forced_hcw_solution_over_long_times():
    """The closed form of constant thrust against numerical integration over a whole orbit
    fraction (where the small-angle terms matter)."""
    acc = np.array([2e-4, -1e-4, 3e-4])
    for tau in (0.1, 60.0, 3000.0):
        p, v = hcw_forced(acc, N780, tau)

        def rhs(_t, s):
            x, y, z, vx, vy, vz = s
            n = N780
            return [vx, vy, vz, 3 * n * n * x + 2 * n * vy + acc[0], -2 * n * vx + acc[1],
                    -n * n * z + acc[2]]

        sol = solve_ivp(rhs, (0, tau), np.zeros(6), rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(p, sol.y[:3, -1], rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(v, sol.y[3:, -1], rtol=1e-8, atol=1e-14)


def test_one_row_hcw_is_the_project_closed_form():
    rng = np.random.default_rng(3)
    for _ in range(20):
        p, v, tau = rng.normal(0, 50, 3), rng.normal(0, 0.5, 3), float(rng.uniform(0, 4000))
        pos, vel = hcw_step(p, v, N780, tau)
        ref_p, ref_v = hcw_propagate(p, v, N780, np.array([tau]))
        assert np.array_equal(pos, ref_p[0]) and np.array_equal(vel, ref_v[0])  # same bits
    pos, vel = propagate(p, v, N780, 10.0, delta_v=np.array([0.1, 0, 0]))
    ref_p, ref_v = hcw_propagate(p, v + [0.1, 0, 0], N780, np.array([10.0]))
    np.testing.assert_allclose(pos, ref_p[0], rtol=1e-13)


@pytest.mark.parametrize("law", [LookAtAttitude(), LookAtAttitude(point_m=(1, 2, 3),
                                                                  up=(0, 1, 1)),
                                 FixedAttitude(euler_deg=(10, 20, 30))])
def test_one_row_attitude_is_the_trajectory_law(law):
    """The loop's one-row attitude equals the law's vectorised SciPy rotations, degenerate
    positions included (boresight along 'up', body on the aim point)."""
    positions = np.array([[0, 30, 0], [5, -7, 2], [0, 0, 40], [1, 2, 3], [0, 0, -9]], float)
    pointing = Pointing(law)
    for p in positions:
        got = Rotation.from_quat(pointing.quaternion(p)).as_matrix()
        np.testing.assert_allclose(got, law.rotations(p[None, :]).as_matrix()[0], atol=1e-12)


def test_bad_steps_name_the_field_and_change_nothing(approach_sim, tmp_path):
    session = LoopSession(approach_sim)
    with pytest.raises(ConfigError, match="positive time") as err:
        session.step(-0.1)
    assert err.value.field == "dt"
    with pytest.raises(ConfigError) as err:
        session.step(0.1, delta_v_m_s=[0, float("nan"), 0])
    assert err.value.field == "delta_v_m_s"
    with pytest.raises(ConfigError, match="not both"):
        session.step(0.1, position_m=[0, 20, 0], delta_v_m_s=[0, 0, 0])
    assert session.frame == 0 and len(session.sensor_path.times) == 1
    with pytest.raises(ConfigError, match="no step"):
        session.record(tmp_path / "none.yaml")
    session.step(0.1)
    session.step(0.05)
    with pytest.raises(ConfigError, match="different lengths"):
        session.record(tmp_path / "uneven.yaml")
    assert list(tmp_path.iterdir()) == []
    keyframes = Simulation(scenario_from_dict(scene({"kind": "static",
                                                     "position_m": [0, 20, 0]})))
    with pytest.raises(ConfigError, match="orbit"):
        LoopSession(keyframes).step(0.1, delta_v_m_s=[0, -0.1, 0])
    with pytest.raises(ConfigError, match="no chaser command"):
        LoopSession(keyframes, steer_sensor=False).step(0.1, delta_v_m_s=[0, 0, 0])


def test_steered_target_is_recorded_and_replayed(tmp_path):
    """A target steered by given poses (the chaser held still) replays to the bit."""
    sim = Simulation(scenario_from_dict(scene({"kind": "static", "position_m": [0, 20, 0],
                                               "euler_deg": [0, 0, -90]})))
    session = LoopSession(sim, steer_sensor=False, steer_targets=["envisat"])
    results = []
    for i in range(2):
        q = Rotation.from_euler("z", 20 * (i + 1), degrees=True).as_quat()
        results.append(session.step(0.1, targets={"envisat": ([0.2 * i, -0.5, 0], q)}))
    replay = Simulation(load_scenario(session.record(tmp_path / "t.yaml")))
    assert (tmp_path / "t.envisat.csv").is_file()
    for frame, result in enumerate(results):
        assert_same_cloud(result.cloud, replay.run_frame(frame), same_hash=False)


def test_the_keyframe_window_flies_the_recorded_path_to_the_bit(tmp_path):
    """Over 200 steps of a random path, each step's three-keyframe window gives, at the rays'
    times and at its start and end, the bits of the keyframe trajectory that reads the whole
    recorded file (the replay's)."""
    from lidarsim_core.loop.steered import INTERPOLATION, SteeredPath
    from lidarsim_core.trajectories.keyframes import KeyframeTrajectory

    rng = np.random.default_rng(12)
    path = SteeredPath()
    t = 0.0
    turn = Rotation.from_rotvec(rng.normal(size=3))
    for j in range(201):
        path.add(t, rng.normal(0, 20, 3), turn.as_quat())
        turn = Rotation.from_rotvec(rng.normal(0, 0.05, 3)) * turn
        t = j * 0.1 + 0.1 if j % 3 else t + 0.07 * (1 + rng.random())
    (tmp_path / "path.csv").write_text(path.csv_text())
    full = KeyframeTrajectory.from_config({"file": str(tmp_path / "path.csv"), **INTERPOLATION})
    times = path.times
    window = SteeredPath()
    for j in range(200):
        window.add(times[j], path.positions[j], path.quaternions[j])
        if j == 0:
            continue
        window.add(times[j + 1], path.positions[j + 1], path.quaternions[j + 1])
        steered = window.trajectory()
        t0, t1 = times[j], times[j + 1]
        rays = np.r_[t0, np.sort(rng.uniform(t0, t1, 300))]
        a, b = steered.pose_matrices(rays), full.pose_matrices(rays)
        assert a.position.tobytes() == b.position.tobytes()
        assert a.matrix.tobytes() == b.matrix.tobytes()
        ends = np.array([t0, t1])
        pa, pb = steered.poses_at(ends), full.poses_at(ends)
        assert pa.position.tobytes() == pb.position.tobytes()
        assert pa.rotation.as_quat().tobytes() == pb.rotation.as_quat().tobytes()
        window.drop_last()
