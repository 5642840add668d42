"""Same seed, same bytes: output files do not depend on the run, the process, the chunk size,
the thread count, the Dask worker count or whether a frame streamed through a temporary file;
across ray backends every point where the hits agree carries the same noise; and the sidecar
(or a dataset's manifest) records enough to regenerate a file bit for bit."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

import lidarsim_core as ls
from lidarsim_core.io.sidecar import read_sidecar, sha256_file

# two targets (one moving), the datasheet's full noise chain, a few thousand points
SCENARIO = {
    "seed": 11,
    "sensor": {"datasheet": "livox-mid70-rose", "pose": {"position_m": [0, 0, 0]}},
    "targets": [
        {"name": "envisat", "mesh": {"model": "envisat", "options": {"detail": "coarse"}},
         "pose": {"position_m": [14, -3, 0], "euler_deg": [0, 0, 90]}},
        {"name": "debris", "mesh": {"model": "box", "options": {"extents_m": [1.2, 0.8, 0.4]}},
         "trajectory": {"kind": "constant_velocity", "position_m": [6, 2, 0.5],
                        "velocity_m_s": [0, 2, 0], "angular_velocity_deg_s": [10, 20, 5]}}],
    "scan": {"duration_s": 0.05},
    "backend": "numpy",
}
FORMATS = ["ply", "npz", "pcd", "csv"] + (["las", "laz"] if __import__("importlib.util").util
                                          .find_spec("laspy") else [])


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("scene") / "scene.yaml"
    path.write_text(yaml.safe_dump(SCENARIO, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def reference(scene, tmp_path_factory) -> dict[str, str]:
    """SHA-256 of every format written from one run with the default settings."""
    out = tmp_path_factory.mktemp("reference")
    cloud = ls.simulate(scene)
    assert len(cloud) > 1000 and len(set(cloud["target"].tolist())) == 2
    return {fmt: sha(cloud.save(out / f"cloud.{fmt}")) for fmt in FORMATS}


def _write_all(cloud, out: Path) -> dict[str, str]:
    out.mkdir(parents=True, exist_ok=True)
    return {fmt: sha(cloud.save(out / f"cloud.{fmt}")) for fmt in FORMATS}


def test_repeated_runs_give_identical_files(scene, reference, tmp_path):
    assert _write_all(ls.simulate(scene), tmp_path) == reference


@pytest.mark.parametrize("chunk_rays", [61, 977, 4999, 10 ** 6])
def test_chunk_size_does_not_change_a_byte(scene, reference, tmp_path, chunk_rays):
    sim = ls.Simulation(ls.load_scenario(scene))
    assert _write_all(sim.run_frame(0, chunk_rays=chunk_rays), tmp_path) == reference


def test_one_ray_pieces_of_a_moving_target_give_the_same_bits():
    """A piece of a single ray sees a moving target through a one-pose transform; it must
    give the bits a longer piece gives (it used to differ in the last bit)."""
    from lidarsim_core.scenario import scenario_from_dict

    data = {**SCENARIO, "scan": {"duration_s": 0.004}, "targets": [
        {"name": "tumbler", "mesh": {"model": "box", "options": {"extents_m": [8, 8, 8]}},
         "trajectory": {"kind": "constant_velocity", "position_m": [7, 0.3, -0.2],
                        "velocity_m_s": [0.5, 2, 0], "angular_velocity_deg_s": [40, 70, 25]}}]}
    sim = ls.Simulation(scenario_from_dict(data))
    whole, single = sim.run_frame(0), sim.run_frame(0, chunk_rays=1)
    assert len(whole) == whole.frame.rays_emitted == 400  # every ray sees the moving box
    for name, column in whole.columns.items():
        np.testing.assert_array_equal(single[name], column, err_msg=name)


@pytest.mark.parametrize("threads", ["1", "2", "5"])
def test_thread_count_does_not_change_a_byte(scene, reference, tmp_path, monkeypatch, threads):
    monkeypatch.setenv("LIDARSIM_THREADS", threads)
    assert _write_all(ls.simulate(scene, chunk_rays=3000), tmp_path) == reference


def test_separate_processes_with_different_hash_seeds_write_identical_files(scene, reference,
                                                                             tmp_path):
    """The CLI (streaming through its spool) in two fresh interpreters, with different
    PYTHONHASHSEED, writes the bytes the API writes."""
    for hash_seed, fmt in (("1", "ply"), ("987654", "npz")):
        env = {**os.environ, "PYTHONHASHSEED": hash_seed, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1"}
        res = subprocess.run([sys.executable, "-m", "lidarsim_core", "simulate", str(scene),
                              "--out", str(tmp_path / f"cloud.{fmt}")], env=env,
                             capture_output=True, text=True, timeout=120)
        assert res.returncode == 0, res.stderr
        assert sha(tmp_path / f"cloud.{fmt}") == reference[fmt]


def test_streamed_through_a_temporary_file_gives_the_same_bytes(scene, reference, tmp_path,
                                                                monkeypatch):
    """``lidarsim simulate`` with a spool budget far below the frame's size."""
    from typer.testing import CliRunner

    from lidarsim_core import cli
    from lidarsim_core.cli import simulate as cli_simulate
    from lidarsim_core.io.points import PointSpool

    monkeypatch.setattr(cli_simulate, "SPOOL_MEMORY_BYTES", 4096)
    spilled: list[bool] = []
    close = PointSpool.close
    monkeypatch.setattr(PointSpool, "close",
                        lambda self: (spilled.append(self.spilled), close(self))[1])
    for fmt in FORMATS:
        target = tmp_path / f"cloud.{fmt}"
        result = CliRunner().invoke(cli.app, ["simulate", str(scene), "--out", str(target)],
                                    catch_exceptions=False)
        assert result.exit_code == 0, result.stderr
        assert sha(target) == reference[fmt], fmt
    assert spilled and all(spilled)


def test_backends_agree_point_for_point_where_their_hits_agree(scene):
    from lidarsim_core.plugins import get_registry

    if not get_registry().get("ray_backend", "embree").is_available()[0]:
        pytest.skip("embree is not installed")
    base = ls.load_scenario(scene)
    clouds = {name: ls.simulate(base.with_updates(backend={"name": name}))
              for name in ("numpy", "embree")}
    a, b = clouds["numpy"], clouds["embree"]
    common, ia, ib = np.intersect1d(a["ray_index"], b["ray_index"], return_indices=True)
    # float32 Embree may lose or gain a ray grazing a silhouette, nothing more
    assert len(common) >= 0.999 * max(len(a), len(b))
    same_face = a["face_index"][ia] == b["face_index"][ib]
    assert same_face.mean() > 0.99
    ia, ib = ia[same_face], ib[same_face]
    # the noise of a ray depends on its index only: the error draws are the same
    err_a = a["range"][ia] - a["range_true"][ia]
    err_b = b["range"][ib] - b["range_true"][ib]
    np.testing.assert_allclose(err_a, err_b, rtol=0, atol=1e-9)
    for col in ("azimuth", "elevation", "timestamp", "channel", "part", "target"):
        np.testing.assert_array_equal(a[col][ia], b[col][ib])
    rtol = get_registry().get("ray_backend", "embree").distance_rtol
    for col in ("x", "y", "z", "x_true", "y_true", "z_true", "range_true"):
        np.testing.assert_allclose(a[col][ia], b[col][ib], rtol=0,
                                   atol=10 * rtol * 30 + 1e-9)  # 30 m: the scene's size
    assert a.frame.config_hash != b.frame.config_hash  # the backend is part of the identity


@pytest.fixture(scope="module")
def sequence(tmp_path_factory) -> tuple[Path, dict[str, str]]:
    """A four-frame sequence file and the tree of its serial dataset."""
    from test_dataset import tree

    from lidarsim_core.dataset import generate_dataset

    root = tmp_path_factory.mktemp("sequence")
    data = {**SCENARIO, "scan": {"duration_s": 0.02, "frame_period_s": 0.1, "frames": 4}}
    path = root / "seq.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    generate_dataset(path, root / "serial", format="ply")
    return path, tree(root / "serial")


@pytest.mark.parametrize("workers", [1, 3])  # test_dataset_dask.py runs 2
def test_dask_worker_count_does_not_change_a_byte(sequence, tmp_path, workers):
    pytest.importorskip("dask.distributed")
    from test_dataset import tree

    from lidarsim_core.dataset import generate_dataset

    path, serial = sequence
    generate_dataset(path, tmp_path / "ds", format="ply", workers=workers)
    assert tree(tmp_path / "ds") == serial


def test_sidecar_records_enough_to_regenerate_the_file(scene, tmp_path):
    """From the sidecar and the scenario alone: the same configuration (hash), seed, frame,
    backend, noise chain and software give a file with the recorded SHA-256."""
    from typer.testing import CliRunner

    from lidarsim_core import cli
    target = tmp_path / "cloud.npz"
    result = CliRunner().invoke(cli.app, ["simulate", str(scene), "--out", str(target),
                                          "--seed", "42"], catch_exceptions=False)
    assert result.exit_code == 0, result.stderr
    record = read_sidecar(target)
    frame = record["frame"]
    assert record["sha256"] == sha256_file(target) and record["exporter"] == "npz"
    assert frame["seed"] == 42 and frame["backend"] == "numpy"
    assert frame["noise"] == ["angular", "range"]
    assert frame["software"] == f"lidarsim-core {ls.__version__}"
    # rebuild from what the sidecar says
    scenario = ls.load_scenario(scene).with_updates(seed=frame["seed"],
                                                    backend={"name": frame["backend"]})
    assert scenario.config_hash() == frame["config_hash"]
    again = ls.Simulation(scenario).run_frame(frame["frame"])
    (tmp_path / "again").mkdir()
    assert sha256_file(again.save(tmp_path / "again" / "cloud.npz")) == record["sha256"]


def test_dataset_manifest_names_everything_a_rerun_needs(scene, tmp_path):
    from lidarsim_core.dataset import generate_dataset, read_manifest

    data = {**SCENARIO, "scan": {"duration_s": 0.02, "frame_period_s": 0.1, "frames": 2}}
    path = tmp_path / "seq.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp_path / "ds"
    generate_dataset(path, out, format="npz")
    manifest = read_manifest(out / "manifest.json")
    text = json.dumps(manifest)
    assert manifest["complete"] is True
    assert "Philox" in text  # the seed scheme
    for package in ("numpy", "scipy", "lidarsim-core"):
        assert package in text, package
    frames = [f for seq in manifest["sequences"] for f in seq["frames"]]
    assert len(frames) == 2 and all(len(f["sha256"]) == 64 for f in frames)
    for f in frames:
        assert sha256_file(next(out.rglob(f["file"]))) == f["sha256"]
