"""Culling before the per-pulse poses (``PulseCuller.keep_before_poses``) keeps every pulse
that hits, from the trajectories' rate bounds alone.

Independent truth: every pulse is cast without culling (the posed batch through the whole
measurement), and the pulses with a return must all be among the kept ones; the rate bounds
are checked against finite differences of densely sampled poses.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lidarsim_core.pipeline import Simulation
from lidarsim_core.pipeline.cast import process_piece
from lidarsim_core.pipeline.cull import PulseCuller, culled_with_poses
from lidarsim_core.pipeline.posing import with_piece_poses
from lidarsim_core.plugins.manager import get_registry
from lidarsim_core.scenario import scenario_from_dict
from lidarsim_core.trajectories.matrices import motion_rates, pose_matrices

pytest.importorskip("numba", reason="culling runs with the compiled kernels (extra 'fast')")
EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "scenarios"


def _suite(name: str, duration: float) -> dict:
    from lidarsim_core.bench.suite import SUITE

    return SUITE[name][1](duration)


def _approach_two_targets() -> dict:
    """A chaser on a straight V-bar approach (look-at), a tumbling Envisat and a fast box
    passing close by: a moving, turning sensor and a target that needs cones."""
    data = _suite("two-targets", 0.2)
    data["sensor"] = {"datasheet": "livox-mid70-rose", "trajectory": {
        "kind": "hcw", "orbit": {"altitude_km": 780}, "position_m": [0, 45, 0],
        "segments": [{"type": "straight", "to_m": [0, 20, 0], "speed_m_s": 3.0}]}}
    data["targets"][0]["pose"] = {"position_m": [0, 0, 0]}
    data["targets"][1]["trajectory"].update(position_m=[2, 30, 0], velocity_m_s=[0, 0, 3.0],
                                            angular_velocity_deg_s=[40, 0, 90])
    return data


def _keyframe_chaser() -> dict:
    """A chaser on cubic keyframes looking at a tumbling Envisat."""
    data = _suite("tumbling-rose", 0.3)
    data["sensor"]["trajectory"] = {"kind": "keyframes", "attitude": {"point_m": [0, 0, 0]},
                                    "keyframes": [{"t_s": 0, "position_m": [0, 30, 0]},
                                                  {"t_s": 0.4, "position_m": [1, 29, 1]},
                                                  {"t_s": 2, "position_m": [3, 25, 0]}]}
    return data


SCENES = {
    "keyframe-chaser": _keyframe_chaser,
    "tumbling-hold-risley": lambda: _suite("tumbling-risley", 0.3),
    "tumbling-fixed-rose": lambda: _suite("tumbling-fixed-rose", 0.3),
    "flyaround-risley": lambda: _suite("flyaround-50m", 0.3),
    "vlp16-circling": lambda: _suite("vlp16-circling-15m", 0.6),
    "two-targets": lambda: _suite("two-targets", 0.3),
    "approach-two-targets": _approach_two_targets,
}


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_every_pulse_that_hits_is_kept_without_per_pulse_poses(scene):
    sim = Simulation(scenario_from_dict(SCENES[scene](), source=f"<{scene}>"))
    ctx = sim.context
    k0, k1 = sim.frame_rays(0)
    t_frame = ctx.scenario.scan.frame_interval(0)[0]
    hits, kept_total, total = 0, 0, 0
    for start in range(k0, k1, 20_000):  # pieces of 20k pulses, as the pipeline cuts them
        batch = sim.pattern.rays_for_indices(np.arange(start, min(start + 20_000, k1)))
        rows = sim.culler.keep_before_poses(ctx, batch, t_frame)
        assert rows is not None  # decided without a pose per pulse
        posed = with_piece_poses(ctx, batch, t_frame)
        columns = process_piece(ctx, sim.stages, posed, ctx.noise_contexts(0), t_frame, 0)
        hit = np.unique(columns["ray_index"])
        kept = batch.index[rows]
        assert np.isin(hit, kept).all(), f"{np.setdiff1d(hit, kept)[:5]} hit but were culled"
        assert (np.diff(rows) > 0).all()
        hits += len(hit)
        kept_total += len(rows)
        total += len(batch)
    assert hits > 200
    assert kept_total < 0.5 * total  # and most pulses that miss are culled


def test_kept_pulses_get_the_same_pose_bits_as_posing_every_pulse():
    sim = Simulation(scenario_from_dict(_approach_two_targets()))
    ctx = sim.context
    k0, k1 = sim.frame_rays(0)
    batch = sim.pattern.rays_for_indices(np.arange(k0, k0 + 30_000))
    late = culled_with_poses(ctx, sim.culler, batch, 0.0)
    posed = with_piece_poses(ctx, batch, 0.0)
    early = posed.take(sim.culler.keep_before_poses(ctx, batch, 0.0))
    np.testing.assert_array_equal(late.index, early.index)
    for a, b in zip((late.poses.sensor, *late.poses.targets),
                    (early.poses.sensor, *early.poses.targets)):
        n = len(late)
        np.testing.assert_array_equal(a.full(n).matrix, b.full(n).matrix)
        np.testing.assert_array_equal(a.full(n).position, b.full(n).position)


def test_fast_targets_get_cones_and_slow_ones_the_cube_map(monkeypatch):
    """Two targets: the still Envisat in the cube map, the fast box by a cone per block."""
    sim = Simulation(scenario_from_dict(_suite("two-targets", 0.5)))
    monkeypatch.setenv("LIDARSIM_THREADS", "1")  # pieces of 65536 pulses: 0.65 s
    seen = []
    original = PulseCuller._cones

    def spy(self, ctx, cone_targets, *args):
        seen.append(list(cone_targets))
        return original(self, ctx, cone_targets, *args)

    monkeypatch.setattr(PulseCuller, "_cones", spy)
    culled = sim.run_frame(0)
    assert seen and all(cones == [1] for cones in seen)
    sim.culler = None
    every_pulse = sim.run_frame(0)
    for name, column in every_pulse.columns.items():
        np.testing.assert_array_equal(culled[name], column, err_msg=name)


def test_trajectories_without_rate_bounds_are_posed_first(monkeypatch):
    """A torque-free body gives no rate bounds: the posed path decides, the same points."""
    data = _suite("tumbling-fixed-rose", 0.1)
    data["targets"][0]["trajectory"] = {
        "kind": "torque_free", "position_m": [31, 0, 0],
        "inertia_kg_m2": [17000, 124000, 129000], "angular_velocity_deg_s": [2, 1, 3]}
    sim = Simulation(scenario_from_dict(data))
    k0, _ = sim.frame_rays(0)
    batch = sim.pattern.rays_for_indices(np.arange(k0, k0 + 1000))
    assert sim.culler.keep_before_poses(sim.context, batch, 0.0) is None


def _trajectory(kind: str, options: dict):
    return get_registry().get("trajectory", kind).from_config(options)


RATED = {
    "tumbling-2013": ("tumbling", {"position_m": [3, 0, 1], "euler_deg": [-90, 0, -90],
                                   "symmetry_axis": [0, 1, 0], "angular_momentum_axis": [0, 0, -1],
                                   "spin_rate_deg_s": 2.67, "precession_rate_deg_s": 1.5,
                                   "centre_of_mass_m": [0.5, 2, -1],
                                   "orbit": {"altitude_km": 780}}),
    "constant-velocity": ("constant_velocity", {"velocity_m_s": [1, -2, 0.5],
                                                "angular_velocity_deg_s": [30, -10, 5]}),
    "hcw-fly-around": ("hcw", {"orbit": {"altitude_km": 400}, "position_m": [0, 15, 0],
                               "segments": [{"type": "fly_around", "orbits": 1,
                                             "out_of_plane": True}]}),
    "hcw-approach": ("hcw", {"orbit": {"altitude_km": 780}, "position_m": [5, 60, 3],
                             "velocity_m_s": [0.01, -0.05, 0],
                             "segments": [{"type": "coast", "duration_s": 100},
                                          {"type": "straight", "to_m": [0, 8, 1],
                                           "speed_m_s": 0.4},
                                          {"type": "hold", "duration_s": 50}],
                             "attitude": {"point_m": [0, 0, 0], "up": [0, 0, 1]}}),
    "keyframes-cubic-slerp": ("keyframes", {"keyframes": [
        {"t_s": 0, "position_m": [0, 0, 0], "euler_deg": [0, 0, 0]},
        {"t_s": 40, "position_m": [5, 2, -1], "euler_deg": [30, 10, 0]},
        {"t_s": 90, "position_m": [6, -3, 2], "euler_deg": [30, 80, -40]},
        {"t_s": 200, "position_m": [0, 1, 0], "euler_deg": [0, 0, 10]}]}),
    "keyframes-linear-look-at": ("keyframes", {
        "position_interpolation": "linear", "attitude": {"point_m": [0, 0, 0]},
        "keyframes": [{"t_s": 0, "position_m": [30, 0, 5]}, {"t_s": 100, "position_m": [0, 25, 3]},
                      {"t_s": 250, "position_m": [-20, 5, 0]}]}),
}


@pytest.mark.parametrize("name", sorted(RATED))
def test_rate_bounds_hold_between_dense_samples(name):
    kind, options = RATED[name]
    trajectory = _trajectory(kind, options)
    rng = np.random.default_rng(3)
    for t0 in rng.uniform(0, 300, 12):
        t1 = t0 + rng.uniform(0.01, 5.0)
        rates = motion_rates(trajectory, t0, t1)
        assert rates is not None
        turn, speed = rates
        t = np.linspace(t0, t1, 2001)
        poses = pose_matrices(trajectory, t).full(len(t))
        dt = np.diff(t)
        # the angle between consecutive rotations: ‖R1 − R0‖_F = 2√2 sin(θ/2)
        chord = np.linalg.norm(np.diff(poses.matrix, axis=0), axis=(1, 2))
        angle = 2.0 * np.arcsin(np.minimum(chord / (2.0 * np.sqrt(2.0)), 1.0))
        moved = np.linalg.norm(np.diff(poses.position, axis=0), axis=1)
        assert (angle / dt <= turn * (1 + 1e-6) + 1e-9).all()
        assert (moved / dt <= speed * (1 + 1e-6) + 1e-9).all()
        if name == "hcw-fly-around":  # a circle at constant range: the bounds are near
            assert moved.max() / dt[0] > 0.6 * speed and angle.max() / dt[0] > 0.4 * turn


def test_rate_bounds_are_refused_where_the_look_at_law_switches_axes():
    # boresight along 'up' (straight above the point): the law changes its up axis there
    trajectory = _trajectory("hcw", {"orbit": {"altitude_km": 780}, "position_m": [0, 0, 20],
                                     "velocity_m_s": [0.1, 0, 0]})
    assert motion_rates(trajectory, 0.0, 1.0) is None


def test_subclasses_that_redefine_poses_give_no_rate_bounds():
    base = type(_trajectory("constant_velocity", {"velocity_m_s": [1, 0, 0]}))

    class Wobbly(base):
        def pose_matrices(self, t):
            return super().pose_matrices(np.sin(t))

        def poses_at(self, t):
            return super().poses_at(np.sin(t))

    wobbly = Wobbly.from_config({"velocity_m_s": [1, 0, 0]})
    assert motion_rates(wobbly, 0.0, 1.0) is None


def test_spinning_groups_cover_the_range_and_stay_within_their_angle():
    """Every ray of a spinning pattern's direction group is within the group's angle of its
    representative (directions computed exactly), and the groups partition the indices."""
    sim = Simulation(scenario_from_dict(_suite("vlp16-circling-15m", 0.3)))
    pattern = sim.pattern
    for first, count in ((0, 65536), (12345, 7777), (3, 1)):
        index = np.arange(first, first + count)
        grouped = pattern.direction_groups(index)
        everything = grouped.members(np.arange(len(grouped.representative)))
        np.testing.assert_array_equal(everything, index)
        directions = pattern.rays_for_indices(index).direction
        reps = pattern.rays_for_indices(grouped.representative).direction
        worst = 0.0
        for g in range(len(grouped.representative)):
            rows = grouped.members(np.array([g])) - first
            cosine = np.clip(directions[rows] @ reps[g], -1, 1)
            worst = max(worst, float(np.arccos(cosine).max()))
        assert worst <= grouped.angle
        if count > 10_000:
            assert worst > 0.8 * grouped.angle  # the bound is near what the head turns


@pytest.mark.parametrize("datasheet", ["livox-mid70-rose", "livox-mid70", "livox-mid40",
                                       "livox-avia"])
def test_rose_and_risley_groups_stay_within_their_angle(datasheet):
    """Every ray of a rose or Risley direction group is within the group's angle of its
    representative (directions computed exactly, at the start of a scan and 10⁴ s into
    it), the groups partition the indices, and the bound is near the largest deviation
    (the rose's is exact where a petal crosses the boresight; the Risley's is sampled)."""
    data = _suite("static-risley", 0.3)
    data["sensor"]["datasheet"] = datasheet
    pattern = Simulation(scenario_from_dict(data)).pattern
    rate = pattern.sensor.point_rate_hz
    for first, count in ((0, 100_000), (12345, 7777), (int(1e4 * rate), 20_000), (3, 1)):
        index = np.arange(first, first + count)
        grouped = pattern.direction_groups(index)
        members = [grouped.members(np.array([g])) for g in range(len(grouped.representative))]
        np.testing.assert_array_equal(np.sort(np.concatenate(members)), index)
        np.testing.assert_array_equal(grouped.members(np.arange(len(members))), index)
        group = np.empty(count, dtype=np.int64)
        for g, rows in enumerate(members):
            group[rows - first] = g
        directions = pattern.rays_for_indices(index).direction
        reps = pattern.rays_for_indices(grouped.representative).direction
        cosine = np.clip(np.einsum("ij,ij->i", directions, reps[group]), -1.0, 1.0)
        worst = float(np.arccos(cosine).max())
        assert worst <= grouped.angle
        if count > 10_000:
            assert worst > 0.6 * grouped.angle, (worst, grouped.angle)


def test_a_risley_bound_is_refused_where_its_grid_is_too_coarse(monkeypatch):
    """With four roll angles per prism the sampled speed changes too much between grid
    points to be trusted: no bound, no groups (every ray is computed)."""
    from lidarsim_core.patterns import risley

    monkeypatch.setitem(risley.SPEED_STEPS, 2, 4)
    monkeypatch.setattr(risley, "_TURN_RATES", {})  # bounds made earlier in this process
    data = _suite("static-risley", 0.3)
    pattern = Simulation(scenario_from_dict(data)).pattern
    assert pattern.max_turn_rate() is None
    assert pattern.direction_groups(np.arange(1000)) is None


def test_a_risley_bound_is_made_once_per_prism_stack(monkeypatch):
    """Two patterns of one sensor (a dataset's sequences) share the sampled bound; another
    prism stack gets its own."""
    from lidarsim_core.patterns import risley

    monkeypatch.setattr(risley, "_TURN_RATES", {})
    sampled = []
    original = risley.RisleyPattern._sampled_turn_rate

    def counting(self):
        sampled.append(self.options.prisms[0].wedge_deg)
        return original(self)

    monkeypatch.setattr(risley.RisleyPattern, "_sampled_turn_rate", counting)
    rates = []
    for datasheet in ("livox-mid70", "livox-mid70", "livox-mid40"):
        data = _suite("static-risley", 0.1)
        data["sensor"]["datasheet"] = datasheet
        rates.append(Simulation(scenario_from_dict(data)).pattern.max_turn_rate())
    assert len(sampled) == 2 and rates[0] == rates[1] != rates[2]


@pytest.mark.parametrize("scene, seconds, computed_share, hits", [
    ("vlp16-circling-15m", 0.4, 0.25, 200), ("static-demo", 0.5, 0.7, 1000),
    ("tumbling-fixed-risley", 0.5, 0.7, 1000), ("flyaround-50m", 0.5, 0.7, 1000)])
def test_frames_are_culled_by_direction_groups_before_their_directions(
        scene, seconds, computed_share, hits, monkeypatch):
    """The VLP-16 circling Envisat, the rose from a still sensor, the Risley MID-70 on a
    tumbling target and on a fly-around: only the representatives and the groups whose
    representative passes the widened cull are computed, every pulse that hits is among the
    kept ones, and the frame equals the one cast on every pulse, column by column."""
    from lidarsim_core.pipeline import cull

    sim = Simulation(scenario_from_dict(_suite(scene, seconds)))
    ctx = sim.context
    k0, k1 = sim.frame_rays(0)
    index = np.arange(k0, k1)
    computed = []
    original = type(sim.pattern).rays_for_indices

    def spy(self, rows):
        computed.append(len(rows))
        return original(self, rows)

    monkeypatch.setattr(type(sim.pattern), "rays_for_indices", spy)
    kept = cull.culled_piece(ctx, sim.culler, index, 0.0)
    assert len(computed) == 2 and sum(computed) < computed_share * len(index)
    posed = with_piece_poses(ctx, original(sim.pattern, index), 0.0)
    columns = process_piece(ctx, sim.stages, posed, ctx.noise_contexts(0), 0.0, 0)
    hit = np.unique(columns["ray_index"])
    assert len(hit) > hits and np.isin(hit, kept.index).all()
    monkeypatch.setattr(type(sim.pattern), "rays_for_indices", original)
    culled = sim.run_frame(0)
    sim.culler = None
    every_pulse = sim.run_frame(0)
    for name, column in every_pulse.columns.items():
        np.testing.assert_array_equal(culled[name], column, err_msg=name)
