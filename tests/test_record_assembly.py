"""Assembling a frame's point cloud (``PointCloud.concatenate``, ``Simulation.run_frame``):
the columns are the pieces' values joined in order, no two columns share memory, and the
metadata is the frame's own, whatever the pieces, chunks and copies avoided."""

from __future__ import annotations

import json
from itertools import combinations

import numpy as np
import pytest
from test_frameinfo import _one_frame, _sequence

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.pipeline import Simulation
from lidarsim_core.pipeline import simulation as pipeline_module
from lidarsim_core.records.pointcloud import POINT_FIELDS, PointCloud
from lidarsim_core.scenario import demo_scenario, scenario_from_dict


def _part(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {k: (rng.normal(size=n) * 100).astype(v) for k, v in POINT_FIELDS.items()}


def _no_two_share_memory(cloud: PointCloud) -> None:
    for (a, x), (b, y) in combinations(cloud.columns.items(), 2):
        assert not np.shares_memory(x, y), (a, b)


def test_one_part_is_taken_as_it_is_when_it_can_be() -> None:
    part = _part(50)
    part["bounces"] = np.arange(50, dtype=np.uint8)  # an optional column
    expected = {k: v.copy() for k, v in part.items()}
    cloud = PointCloud.concatenate([part], None)
    assert list(cloud.columns) == [*POINT_FIELDS, "bounces"]
    for key, column in cloud.columns.items():
        assert column is part[key], key  # its dtype, contiguous, alone: not copied
        assert column.tobytes() == expected[key].tobytes()
    _no_two_share_memory(cloud)


def test_one_part_is_copied_where_it_must_be() -> None:
    part = _part(40, seed=1)
    xyz = np.random.default_rng(2).normal(size=(40, 3))
    buffer = np.arange(80, dtype=np.float64)
    readonly = np.linspace(0.0, 1.0, 40)
    readonly.flags.writeable = False
    part.update({
        "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2],  # strided
        "range": part["range"].astype(np.float32),  # another dtype
        "intensity": part["intensity"].astype(np.float64),
        "x_true": buffer[0:40], "y_true": buffer[20:60],  # overlap
        "number_of_returns": part["return_number"],  # the same array twice
        "azimuth": readonly,
    })
    cloud = PointCloud.concatenate([part], None)
    for key, dtype in POINT_FIELDS.items():
        column = cloud[key]
        assert column.dtype == np.dtype(dtype) and column.flags.c_contiguous
        assert column.flags.writeable
        np.testing.assert_array_equal(column, part[key].astype(dtype), err_msg=key)
    _no_two_share_memory(cloud)
    assert cloud["x_true"] is part["x_true"]  # the first of two overlapping arrays is kept
    assert cloud["intensity"].dtype == np.float32


def test_many_parts_are_joined_in_order() -> None:
    parts = [_part(n, seed=n) for n in (7, 0, 13)]
    parts[0]["channel"] = parts[0]["channel"].astype(np.int64)  # a wider piece
    for part in parts:
        part["x_body"] = part["x"] * 2.0
    parts[1]["only_here"] = np.zeros(0)
    cloud = PointCloud.concatenate(parts, None)
    assert len(cloud) == 20 and "x_body" in cloud.columns and "only_here" not in cloud.columns
    for key, dtype in POINT_FIELDS.items():
        assert cloud[key].dtype == np.dtype(dtype)
        assert cloud[key].tolist() == [v for p in parts for v in p[key].astype(dtype).tolist()]
    _no_two_share_memory(cloud)


@pytest.mark.parametrize("name", ["tumbling-rose", "flyaround-50m", "two-targets"])
def test_run_frame_metadata_is_the_frames_own(name: str) -> None:
    """run_frame looks the frame's poses up once for its inside check and its metadata: the
    metadata is frame_info's, and each pose that of the trajectories asked alone."""
    sim = _sequence(name, 3)
    for frame in (0, 2):
        info = sim.run_frame(frame).frame
        assert info.to_dict() == sim.frame_info(frame).to_dict()
        ref = _one_frame(sim, frame)
        assert json.dumps({key: getattr(info, key) for key in ref}) == json.dumps(ref)
        assert info.t_start == sim.scenario.scan.frame_interval(frame)[0]


def test_run_frame_is_its_chunks_joined(monkeypatch) -> None:
    """Pieces joined once in run_frame give the bytes of the chunks iter_chunks yields."""
    data = demo_scenario(duration_s=0.05, detail="coarse").model_dump(mode="json")
    sim = Simulation(scenario_from_dict(data))
    monkeypatch.setenv("LIDARSIM_THREADS", "2")
    monkeypatch.setattr(pipeline_module, "PIECE_RAYS", 907)
    chunks = list(sim.iter_chunks(0, 2500))
    assert len(chunks) == 2
    cloud = sim.run_frame(0, 2500)
    assert len(cloud) > 100
    for key in POINT_FIELDS:
        joined = np.concatenate([c[key] for c in chunks]).astype(POINT_FIELDS[key])
        assert cloud[key].tobytes() == joined.tobytes(), key
    _no_two_share_memory(cloud)


@pytest.mark.parametrize("motion", ["per_ray", "frozen"])
def test_run_frame_refuses_a_sensor_inside_a_closed_target(motion: str) -> None:
    data = demo_scenario(duration_s=0.01).model_dump(mode="json")
    data["targets"][0] = {"name": "hull", "mesh": {"model": "box",
                                                   "options": {"extents_m": [4, 4, 4]}},
                          "pose": {"position_m": [0.5, 0, 0]}}
    data["scan"]["motion"] = motion
    sim = Simulation(scenario_from_dict(data))
    with pytest.raises(ConfigError, match="inside the closed target 'hull'") as caught:
        sim.run_frame(0)
    assert caught.value.field == "targets.0.pose"
