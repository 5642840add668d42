"""The lean frame write of datasets: a frame encoded in memory and written with one call gives
the same file and sidecar as streaming it to the file, refuses the same targets with the same
line, and leaves nothing half-written; the sidecar's fast JSON is json.dumps's text."""

from __future__ import annotations

import hashlib
import json
import math
import os
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lidarsim_core.base import atomic
from lidarsim_core.base.atomic import atomic_output, write_bytes_atomic
from lidarsim_core.base.errors import OutputError
from lidarsim_core.base.jsontext import indented_json
from lidarsim_core.io import write as write_module
from lidarsim_core.io.points import CloudPoints, PointSpool
from lidarsim_core.io.sidecar import read_sidecar, sha256_file
from lidarsim_core.io.write import write_points_file
from lidarsim_core.plugins.resolve import exporter_named

# ---- the sidecar's JSON ------------------------------------------------------------------

_leaves = (st.none() | st.booleans() | st.integers(-10 ** 20, 10 ** 20)
           | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=12))
_values = st.recursive(_leaves, lambda inner: st.lists(inner, max_size=4)
                       | st.dictionaries(st.text(max_size=6), inner, max_size=4)
                       | st.tuples(inner, inner), max_leaves=30)


@settings(max_examples=400, deadline=None)
@given(_values)
def test_indented_json_is_json_dumps_text(value):
    assert indented_json(value) == json.dumps(value, indent=1, sort_keys=True)


@pytest.mark.parametrize("value", [
    {2: "a", 10: "b"}, {"x": {1.5: 1, 0.5: 2}}, {"x": [np.float64(1.5), 3]},
    {"nan": math.nan, "inf": [math.inf, -math.inf, -0.0, 5e-324]}, [True, 1, 1.0, "1"],
    {"é": "\u2028\x00\"\\/"}, ([], {}, [[]], [{}]), "text", 3, None])
def test_indented_json_matches_on_unusual_values(value):
    assert indented_json(value) == json.dumps(value, indent=1, sort_keys=True)


def test_indented_json_memo_never_mixes_equal_keys():
    # (1,), (1.0,) and (True,) are equal as keys, as are (0.0,) and (-0.0,): not their texts
    for value in [(1,), (1.0,), (True,), (0.0,), (-0.0,), ("a",), (("a", "b"),), (("a",),),
                  {"c": (("x", "float64"),)}, {"c": (("x", "float64"),)}]:
        assert indented_json(value) == json.dumps(value, indent=1, sort_keys=True)
        assert indented_json([value]) == json.dumps([value], indent=1, sort_keys=True)


def test_indented_json_raises_what_json_raises():
    with pytest.raises(TypeError):
        indented_json({"a": object()})
    with pytest.raises(TypeError):
        indented_json({1: "a", "b": 2})  # keys that do not sort
    loop: list = []
    loop.append(loop)
    with pytest.raises(ValueError, match="Circular"):
        indented_json(loop)


# ---- one write call ---------------------------------------------------------------------

def test_write_bytes_atomic_writes_and_replaces(tmp_path):
    path = tmp_path / "a.bin"
    write_bytes_atomic(path, b"one")
    write_bytes_atomic(path, memoryview(b"two!"))
    assert path.read_bytes() == b"two!"
    assert os.listdir(tmp_path) == ["a.bin"]


def _refusal(call) -> str:
    with pytest.raises(OutputError) as info:
        call()
    return str(info.value)


@pytest.mark.parametrize("case", ["directory", "missing folder", "exists", "link to folder"])
def test_write_bytes_atomic_refuses_what_atomic_output_refuses(tmp_path, case):
    overwrite = True
    if case == "directory":
        path = tmp_path / "d"
        path.mkdir()
    elif case == "missing folder":
        path = tmp_path / "nowhere" / "f.bin"
    elif case == "exists":
        path = tmp_path / "f.bin"
        path.write_bytes(b"old")
        overwrite = False
    else:
        (tmp_path / "d").mkdir()
        path = tmp_path / "link"
        path.symlink_to(tmp_path / "d")

    def stream() -> None:
        with atomic_output(path, overwrite=overwrite) as out:
            out.write(b"new")

    expected = _refusal(stream)
    assert _refusal(lambda: write_bytes_atomic(path, b"new", overwrite=overwrite)) == expected
    assert not [p for p in tmp_path.rglob("*") if p.name.endswith(".part")]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="FIFOs")
def test_write_bytes_atomic_never_replaces_a_fifo(tmp_path):
    path = tmp_path / "pipe.ply"
    os.mkfifo(path)
    assert "FIFO" in _refusal(lambda: write_bytes_atomic(path, b"x"))
    assert path.is_fifo()


def test_a_failed_write_leaves_the_old_file_and_no_part(tmp_path, monkeypatch):
    path = tmp_path / "f.bin"
    path.write_bytes(b"old")

    def full(fd, data):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(atomic.os, "write", full)
    assert "no space left" in _refusal(lambda: write_bytes_atomic(path, b"new"))
    monkeypatch.undo()
    assert path.read_bytes() == b"old"
    assert os.listdir(tmp_path) == ["f.bin"]


def test_deferred_sync_collects_instead_of_syncing(tmp_path, monkeypatch):
    synced: list[int] = []
    monkeypatch.setattr(atomic.os, "fsync", synced.append)
    paths: list[Path] = []
    with atomic.deferred_sync(paths):
        write_bytes_atomic(tmp_path / "a", b"a")
    assert paths == [tmp_path / "a"] and synced == []
    write_bytes_atomic(tmp_path / "b", b"b")
    assert len(synced) == 1


# ---- frames in memory and streamed give the same files ---------------------------------

def _cloud_points(n: int = 300) -> CloudPoints:
    from lidarsim_core.records.pointcloud import POINT_FIELDS, FrameInfo, PointCloud

    rng = np.random.default_rng(5)
    columns = {}
    for name, dtype in POINT_FIELDS.items():
        dtype = np.dtype(dtype)
        if dtype.kind == "f":
            columns[name] = rng.normal(size=n).astype(dtype)
        elif dtype.kind == "b":
            columns[name] = rng.integers(0, 2, n).astype(dtype)
        else:
            columns[name] = rng.integers(1, 3, n).astype(dtype)
    pose = {"translation_m": [0.0, 1.0, 2.0], "quaternion_xyzw": [0.0, 0.0, 0.0, 1.0]}
    frame = FrameInfo(frame=3, t_start=0.0, t_end=0.1, sensor="s", seed=7, config_hash="c",
                      backend="numpy", noise=[], motion="frozen", target_names=["t"],
                      part_names=["a", "b", "c"], rays_emitted=n, sensor_pose_start=pose,
                      sensor_pose_end=pose, target_poses_start=[pose],
                      target_poses_end=[pose], targets_in_sensor=[pose])
    return CloudPoints(PointCloud(columns, frame))


@pytest.mark.parametrize("name", ["ply", "pcd", "csv", "npz", "las", "laz"])
def test_a_frame_in_memory_writes_the_streamed_bytes(tmp_path, monkeypatch, name):
    if name in ("las", "laz"):
        pytest.importorskip("laspy" if name == "las" else "lazrs")
    exporter = exporter_named(name, {})
    cloud = _cloud_points()
    spool = PointSpool(cloud.frame)
    spool.extend(cloud.iter_chunks(size=128))  # several parts, joined for the encoder
    memory = write_points_file(spool, tmp_path / f"m.{name}", exporter)
    monkeypatch.setattr(write_module, "BUFFER_LIMIT", 0)  # the streamed path
    streamed = write_points_file(spool, tmp_path / f"s.{name}", exporter)
    assert (tmp_path / f"m.{name}").read_bytes() == (tmp_path / f"s.{name}").read_bytes()
    assert {**memory, "file": None} == {**streamed, "file": None}
    assert memory["sha256"] == sha256_file(tmp_path / f"m.{name}")
    assert memory["bytes"] == (tmp_path / f"m.{name}").stat().st_size
    assert read_sidecar(tmp_path / f"m.{name}")["sha256"] == \
        hashlib.sha256((tmp_path / f"m.{name}").read_bytes()).hexdigest()


def test_ply_from_a_spool_keeps_the_range_checks(tmp_path):
    cloud = _cloud_points()
    cloud.cloud.columns["face_index"][5] = 2 ** 40  # beyond PLY's int
    spool = PointSpool(cloud.frame)
    spool.extend(cloud.iter_chunks())
    message = _refusal(lambda: write_points_file(spool, tmp_path / "f.ply",
                                                 exporter_named("ply", {})))
    assert "face_index" in message and "f.ply" in message
    assert os.listdir(tmp_path) == []


def test_ply_from_a_spool_of_several_chunks_is_the_column_by_column_file(tmp_path):
    import io

    cloud = _cloud_points(70_000)  # more than one chunk of 65,536 points
    spool = PointSpool(cloud.frame)
    spool.extend(cloud.iter_chunks(size=30_000))
    exporter = exporter_named("ply", {})
    from_records, by_columns = io.BytesIO(), io.BytesIO()
    exporter.write_points(spool, from_records)
    exporter.write_points(cloud, by_columns)  # CloudPoints: no records, column by column
    assert spool.records() is not None and cloud.records() is None
    assert from_records.getvalue() == by_columns.getvalue()
