"""A flash LiDAR's frame is one flash: a long ``duration_s`` does not merge flashes."""

from __future__ import annotations

import numpy as np

from lidarsim_core.pipeline import Simulation
from lidarsim_core.scenario import scenario_from_dict

#: ball-vns-flash at 30 flashes/s, with a smaller array than its 256 × 256 to keep this fast
OPTIONS = {"rows": 32, "columns": 32, "frame_rate_hz": 30.0}
PIXELS = 32 * 32


def _scenario(**scan):
    return scenario_from_dict({
        "seed": 1, "sensor": {"datasheet": "ball-vns-flash", "pattern_options": OPTIONS},
        "targets": [{"name": "t", "mesh": {"model": "envisat", "options": {"detail": "coarse"}},
                     "pose": {"position_m": [60, 0, 0]}}],
        "scan": scan, "noise": []})


def test_half_a_second_of_a_30_hz_flash_lidar_is_one_flash():
    cloud = Simulation(_scenario(duration_s=0.5)).run_frame(0)
    assert cloud.frame.rays_emitted == PIXELS  # not 15 flashes
    assert len(np.unique(cloud["timestamp"])) == 1 and len(cloud) > 0
    assert np.unique(cloud["ray_index"]).size == len(cloud)  # each pixel at most once


def test_a_sequence_of_flashes_is_a_sequence_of_frames():
    sim = Simulation(_scenario(duration_s=1 / 30, frame_rate_hz=30, frames=3))
    times = [np.unique(sim.run_frame(f)["timestamp"]) for f in range(3)]
    assert [len(t) for t in times] == [1, 1, 1]
    np.testing.assert_allclose(np.diff([t[0] for t in times]), 1 / 30)


def test_flashes_per_frame_merges_on_request():
    scen = _scenario(duration_s=0.5).with_updates(
        sensor={"datasheet": "ball-vns-flash",
                "pattern_options": {**OPTIONS, "flashes_per_frame": 3}})
    assert Simulation(scen).frame_info(0).rays_emitted == 3 * PIXELS


def test_slot_azimuth_and_elevation_are_those_of_the_directions(monkeypatch):
    """Fixed-slot patterns take the record's azimuth and elevation from a per-slot table
    (``CycleTimedPattern.nominal_az_el``): the same bits as computing them from the rays'
    directions, on the fast path and on the general one (noise chain with detection), over
    several flashes, whose rays wrap around the slots."""
    from lidarsim_core.patterns.base import ScanPattern
    from lidarsim_core.patterns.timing import CycleTimedPattern

    near = [{"name": "t", "mesh": {"model": "envisat", "options": {"detail": "coarse"}},
             "pose": {"position_m": [15, 0, 0]}}]
    scenarios = [_scenario(duration_s=0.2).with_updates(noise=None, targets=near),
                 _scenario(duration_s=0.2).with_updates(
                     targets=near, noise=[{"name": "angular"}, {"name": "outliers"}],
                     sensor={"datasheet": "ball-vns-flash", "pattern_options":
                             {**OPTIONS, "flashes_per_frame": 3}})]
    assert [Simulation(s).fused is None for s in scenarios] == [False, True]
    for scenario in scenarios:
        fast = Simulation(scenario).run_frame(0)
        monkeypatch.setattr(CycleTimedPattern, "nominal_az_el", ScanPattern.nominal_az_el)
        direct = Simulation(scenario).run_frame(0)
        monkeypatch.undo()
        assert len(fast) > 100
        for column in ("azimuth", "elevation"):
            assert fast[column].tobytes() == direct[column].tobytes()
