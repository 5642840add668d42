"""Frame metadata of many frames at once (lidarsim_core.pipeline.frameinfo) against the one-frame
composition: every pose of every frame is the same to the bit, and so is the poses file."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_posing import TRAJECTORIES, _trajectory

from lidarsim_core.bench.suite import SUITE
from lidarsim_core.pipeline import Simulation
from lidarsim_core.records.groundtruth import frame_record, frame_records
from lidarsim_core.scenario import scenario_from_dict


def _one_frame(sim: Simulation, frame: int) -> dict:
    """The reference: each frame's poses looked up on their own, row by row in SciPy."""
    t0, t1 = sim.scenario.scan.frame_interval(frame)
    times = np.array([t0, t1])
    sensor = sim.sensor_trajectory.poses_at(times)
    targets = [t.trajectory.poses_at(times) for t in sim.targets]
    return {"sensor_pose_start": sensor[0].to_records()[0],
            "sensor_pose_end": sensor[1].to_records()[0],
            "target_poses_start": [p[0].to_records()[0] for p in targets],
            "target_poses_end": [p[1].to_records()[0] for p in targets],
            "targets_in_sensor": [p[0].relative_to(sensor[0]).to_records()[0]
                                  for p in targets],
            "targets_in_sensor_end": [p[1].relative_to(sensor[1]).to_records()[0]
                                      for p in targets],
            "rays_emitted": sim.frame_rays(frame)[1] - sim.frame_rays(frame)[0]}


def _sequence(name: str, frames: int) -> Simulation:
    data = SUITE[name][1](0.1)
    data["scan"] = {**data.get("scan", {}), "duration_s": 0.1, "frame_rate_hz": 10,
                    "frames": frames}
    return Simulation(scenario_from_dict(data, source=f"<{name}>"))


@pytest.mark.parametrize("name", ["tumbling-risley", "flyaround-50m", "two-targets",
                                  "static-demo"])
def test_frame_infos_match_one_frame_lookups(name: str) -> None:
    sim = _sequence(name, 40)
    frames = [0, 1, 17, 39, 5]
    infos = sim.frame_infos(frames)
    assert [i.frame for i in infos] == frames
    for info in infos:
        ref = _one_frame(sim, info.frame)
        got = {key: getattr(info, key) for key in ref}
        # JSON text: the numbers are the same to the last bit (repr round-trips float64)
        assert json.dumps(got) == json.dumps(ref)
        assert info.to_dict() == sim.frame_info(info.frame).to_dict()
    if name != "static-demo":  # the poses move over the sequence (not a comparison of constants)
        a, b = infos[0], infos[3]
        assert (a.sensor_pose_start, a.target_poses_start) != \
            (b.sensor_pose_start, b.target_poses_start)


@pytest.mark.parametrize("name", ["two-targets", "flyaround-50m", "tumbling-rose"])
def test_frame_records_match_one_frame_records(name: str) -> None:
    sim = _sequence(name, 12)
    infos = sim.frame_infos(range(12))
    clouds = [f"frames/{f:06d}.ply" for f in range(12)]
    batch = frame_records(infos, clouds)
    assert json.dumps(batch) == json.dumps([frame_record(i, c) for i, c in zip(infos, clouds)])
    assert frame_records([], []) == []


def test_poses_file_is_the_frame_by_frame_file(tmp_path, monkeypatch) -> None:
    """The dataset's poses file, made in blocks, is byte for byte the file written one frame
    at a time (a sequence longer than a block, so the block boundary is crossed)."""
    from lidarsim_core.dataset import poses as poses_module
    from lidarsim_core.records.groundtruth import ground_truth

    sim = _sequence("flyaround-50m", 9)
    cloud = "frames/{:06d}.ply".format
    head = ground_truth([sim.frame_info(0)], [cloud(0)])
    head.pop("frames")
    text = json.dumps(head, indent=1)[:-2] + ',\n "frames": ['
    text += ",".join("\n  " + json.dumps(frame_record(sim.frame_info(f), cloud(f)))
                     for f in range(9)) + "\n ]\n}\n"
    monkeypatch.setattr(poses_module, "_BLOCK_FRAMES", 4)
    with poses_module.PosesFile(sim, 9, cloud) as made:
        made.save(tmp_path / "poses.json")
    assert (tmp_path / "poses.json").read_text(encoding="utf-8") == text
    assert len(json.loads(text)["frames"]) == 9


@pytest.mark.parametrize("name", sorted(TRAJECTORIES))
def test_every_trajectory_gives_each_time_the_bits_it_gives_alone(name: str) -> None:
    """What frame_infos relies on: a built-in trajectory's poses at many times are, row by row,
    its poses at two times (keyframe SLERP and splines, closed forms, HCW, look-at)."""
    trajectory = _trajectory(*TRAJECTORIES[name])
    times = np.concatenate([np.linspace(-0.5, 2.5, 61), [0.4, 0.4 + 5e-7]])
    many = trajectory.poses_at(times)
    for i in range(0, len(times) - 1, 2):
        two = trajectory.poses_at(times[i:i + 2])
        assert many.position[i:i + 2].tobytes() == two.position.tobytes()
        assert many.rotation.as_quat()[i:i + 2].tobytes() == two.rotation.as_quat().tobytes()


def test_frames_take_their_metadata_from_a_block(tmp_path, monkeypatch) -> None:
    """``Simulation.frame_ahead`` (dataset frame jobs, ``run_frame``) looks the poses up a
    block ahead; each frame still gets exactly its own metadata, frames asked out of order or
    twice are right too, and a frame's metadata is its own (not shared with the block)."""
    from lidarsim_core.dataset.frames import FrameJob, simulate_frame_job
    from lidarsim_core.pipeline import frameinfo, simulation

    monkeypatch.setattr(simulation, "FRAME_BLOCK", 4)
    sim = _sequence("tumbling-rose", 10)
    scenario_json = sim.scenario.model_dump_json()
    calls = []
    real = frameinfo.pose_records

    def counted(ctx, times, poses=None):
        if ctx is not sim.context:  # the jobs' own simulation
            calls.append(len(times) // 2)
        return real(ctx, times, poses)

    monkeypatch.setattr(simulation, "pose_records", counted)
    order = [0, 1, 2, 3, 4, 9, 5, 5, 7]
    for frame in order:
        job = FrameJob("s", frame, str(tmp_path / f"{frame}.ply"), scenario_json, None, "ply")
        spool, info = simulate_frame_job(job)
        spool.close()
        assert info.to_dict() == sim.frame_info(frame).to_dict()
    # the jobs' simulation (not ``sim``): blocks of 4 from frames 0, 4, 9 (the last frame)
    # and 5; the second 5 and the 7 come from the block of 5
    assert calls == [4, 4, 1, 4]
    first = sim.run_frame(0).frame
    first.sensor_pose_start["translation_m"][0] = 1e9  # a user's edit stays in its cloud
    assert sim.run_frame(0).frame.to_dict() == sim.frame_info(0).to_dict()


def test_kept_metadata_is_handed_out_once_and_is_what_the_frame_makes():
    """A dataset's poses file makes every frame's metadata before the frames run; kept with
    the simulation (keep_frame_infos), each frame takes its own once instead of making it
    again, the same to the bit; metadata kept for another trajectory or another frame timing
    is not used."""
    reference = _sequence("tumbling-risley", 6)
    made = [reference.frame_ahead(f) for f in range(6)]
    sim = _sequence("tumbling-risley", 6)
    infos = sim.frame_infos(range(6))
    sim.keep_frame_infos(infos[:4])
    got = [sim.frame_ahead(f) for f in range(6)]
    assert [(i.to_dict(), clear) for i, clear in got] == \
        [(i.to_dict(), clear) for i, clear in made]
    assert all(got[f][0] is infos[f] for f in range(4))  # handed out, not made again
    assert got[4][0] is not infos[4]
    again = sim.frame_ahead(0)[0]  # once only: a second call makes its own
    assert again is not infos[0] and again.to_dict() == made[0][0].to_dict()

    other = _sequence("tumbling-risley", 6)
    kept = other.frame_infos(range(6))
    other.keep_frame_infos(kept)
    other.sensor_trajectory = _sequence("tumbling-rose", 6).sensor_trajectory
    assert other.frame_ahead(1)[0] is not kept[1]
    timed = _sequence("tumbling-risley", 6)
    kept = timed.frame_infos(range(6))
    timed.keep_frame_infos(kept)
    timed.scenario.scan.frame_rate_hz = 5.0  # the frames start at other times
    assert timed.frame_ahead(1)[0] is not kept[1]
