"""A dataset checks a block of frames at once for a sensor clear of every target
(pipeline.inside.clear_of_targets) and skips the frame-by-frame check only for those: a
frame whose sensor is inside a closed target is refused as before, with the same line."""

from __future__ import annotations

import numpy as np
import pytest

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.dataset.generate import generate_dataset
from lidarsim_core.pipeline import Simulation
from lidarsim_core.pipeline.inside import check_sensor_outside, clear_of_targets
from lidarsim_core.scenario import demo_scenario, scenario_from_dict


def _approach(frames: int = 10):
    """A 4 m box flying at 5 m/s through the sensor at the origin: its centre is at
    x = 20 - 5 t, so the sensor is inside it for 3.6 s < t < 4.4 s (frame 8, t = 4 s)."""
    data = demo_scenario(duration_s=0.01, detail="coarse").model_dump(mode="json")
    data["targets"] = [{"name": "hull", "mesh": {"model": "box",
                                                 "options": {"extents_m": [4, 4, 4]}},
                        "trajectory": {"kind": "constant_velocity", "position_m": [20, 0, 0],
                                       "velocity_m_s": [-5, 0, 0]}}]
    data["scan"] = {"duration_s": 0.01, "frames": frames, "frame_period_s": 0.5}
    return scenario_from_dict(data, source="scene.yaml")


def test_clear_frames_are_exactly_those_far_from_every_box(monkeypatch):
    sim = Simulation(_approach())
    clear = clear_of_targets(sim.context, range(10))
    # frame 7 (box at 0.45..4.5 m) is clear by 0.45 m; frame 8 has the sensor inside;
    # frame 9 (box at -4.55..-0.5 m) is clear again
    assert clear.tolist() == [True] * 8 + [False, True]

    def no_probe(*args, **kwargs):
        raise AssertionError("a clear frame needs no probe ray")

    monkeypatch.setattr(sim.context.backend, "cast", no_probe)
    for frame in np.flatnonzero(clear):
        check_sensor_outside(sim.context, int(frame))  # passes without casting
    with pytest.raises(AssertionError, match="no probe"):
        check_sensor_outside(sim.context, 8)  # the frame that is not clear is probed


def test_a_frame_touching_a_box_is_not_clear():
    data = _approach().model_dump(mode="json")
    # frame 1 starts at t = 3.6 s: the box spans x = 0..4 m, its face through the sensor
    data["scan"] = {"duration_s": 0.01, "frames": 2, "frame_period_s": 3.6}
    sim = Simulation(scenario_from_dict(data, source="scene.yaml"))
    assert clear_of_targets(sim.context, [0, 1]).tolist() == [True, False]


def test_a_dataset_refuses_the_frame_inside_a_target_as_in_memory(tmp_path):
    scenario = _approach()
    with pytest.raises(ConfigError) as memory:
        Simulation(scenario).run_frame(8)
    with pytest.raises(ConfigError) as dataset:
        generate_dataset(scenario, tmp_path / "out")
    assert "inside the closed target 'hull' at t = 4 s" in str(dataset.value)
    # the same line but for the file named: the dataset's copy of the scenario, as before
    assert dataset.value.message == memory.value.message
    assert dataset.value.field == memory.value.field == "targets.0.trajectory"


def test_a_dataset_of_clear_frames_is_the_same_with_or_without_the_block_check(
        tmp_path, monkeypatch):
    from lidarsim_core.pipeline import inside

    scenario = _approach(frames=8)  # every frame clear
    generate_dataset(scenario, tmp_path / "block")
    monkeypatch.setattr(inside, "clear_of_targets",
                        lambda ctx, frames: np.zeros(len(list(frames)), dtype=bool))
    generate_dataset(scenario, tmp_path / "each")
    files = sorted(p.relative_to(tmp_path / "block")
                   for p in (tmp_path / "block").rglob("*") if p.is_file())
    assert files and all((tmp_path / "block" / f).read_bytes() ==
                         (tmp_path / "each" / f).read_bytes() for f in files)
