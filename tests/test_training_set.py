"""Training sets (issue 23): randomised dataset files, fixed-N samples, tar shards, the reader.

Truth is independent of the code under test: the Haar measure's rotation-angle law
(θ − sin θ)/π, SciPy's KS and binomial tests, ``ls.read`` of the same frames written as PLY
files, ``poses.json``, the range image of the read cloud, the standard library's ``tarfile``
and a spawned process pool standing in for a ``DataLoader``'s workers.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import pickle
import signal
import subprocess
import sys
import tarfile
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy import stats
from scipy.spatial.transform import Rotation
from test_dataset import run_cli, tree

import lidarsim_core as ls
from lidarsim_core.base.errors import ConfigError
from lidarsim_core.dataset import generate_dataset, load_plan
from lidarsim_core.dataset.samples import (
    SampleSettings,
    farthest_point_indices,
    make_sample,
)

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "datasets" / "training.yaml"
CODE = "import sys; from lidarsim_core.cli import main; main(sys.argv[1:])"

SCENE = {
    "seed": 0,
    "sensor": {"datasheet": "ball-vns-flash",
               "trajectory": {"kind": "static", "position_m": [0, 0, 0]}},
    "targets": [{"name": "envisat", "mesh": {"model": "envisat",
                                             "options": {"detail": "coarse"}},
                 "trajectory": {"kind": "torque_free", "position_m": [40, 0, 0],
                                "quaternion_xyzw": [0, 0, 0, 1],
                                "inertia_kg_m2": [17000, 124000, 129000],
                                "angular_velocity_deg_s": [0, 0, 2.67]}}],
    "scan": {"duration_s": 1 / 30, "frame_rate_hz": 2, "frames": 2},
    "backend": "numpy",
}


#: Points per sample of the small dataset: more than the far frames have (~9,000: padded),
#: fewer than the near ones (~30,000: sampled).
N = 16384


def dataset_file(tmp_path: Path, *, fmt: str = "shards", count: int = 3, points: int = N,
                 sampling: str = "uniform", shard_frames: int = 4) -> Path:
    """A small randomised dataset file: a flash sensor (range images), Envisat 15–60 m."""
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump(SCENE, sort_keys=False))
    data = {"seed": 5, "format": fmt,
            "sequences": [{"scenario": "scene.yaml", "name": "t", "count": count,
                           "randomize": {
                               "targets.0.trajectory.quaternion_xyzw": {"so3": "uniform"},
                               "targets.0.trajectory.position_m":
                                   {"vector": [{"uniform": [15, 60]}, 0, 0]}}}],
            "splits": {"train": 0.6, "val": 0.4, "test": 0.0}}
    if fmt == "shards":
        data["samples"] = {"points": points, "sampling": sampling, "labels": True,
                           "body_frame": True, "range_image": True,
                           "shard_frames": shard_frames}
    else:  # the same sequences, one PLY file per frame, with the body-frame columns
        data["sequences"][0]["set"] = {"scan.body_frame_truth": True}
    path = tmp_path / f"{fmt}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def haar_angle_cdf(theta: np.ndarray) -> np.ndarray:
    """CDF of the rotation angle of a Haar-random rotation."""
    return (theta - np.sin(theta)) / np.pi


# --- randomisation ------------------------------------------------------------------------

def test_example_draws_fifty_sequences_reproducibly_and_records_them():
    plan = load_plan(EXAMPLE)
    again = load_plan(EXAMPLE)
    assert len(plan.sequences) == 50
    assert sum(s.scenario.scan.frames for s in plan.sequences) == 1000
    assert [s.drawn for s in plan.sequences] == [s.drawn for s in again.sequences]
    # a sequence's draws do not depend on how many are drawn
    more = load_plan(EXAMPLE, sequences=60)
    assert [s.drawn for s in more.sequences[:50]] == [s.drawn for s in plan.sequences]
    seq = plan.sequences[7]
    target = seq.scenario.targets[0].trajectory_config()
    assert list(target.quaternion_xyzw) == seq.drawn["targets.0.trajectory.quaternion_xyzw"]
    assert seq.scenario.seed == seq.drawn["seed"]
    assert seq.scenario.sensor.datasheet == seq.drawn["sensor.datasheet"]
    assert seq.scenario.scan.body_frame_truth  # samples.body_frame asks for the columns


@pytest.mark.parametrize("count", [50, 3000])
def test_drawn_attitudes_ranges_and_sensors_follow_their_laws(count):
    plan = load_plan(EXAMPLE, sequences=count)
    quats = np.array([s.drawn["targets.0.trajectory.quaternion_xyzw"] for s in plan.sequences])
    theta = Rotation.from_quat(quats).magnitude()
    assert stats.kstest(theta, haar_angle_cdf).pvalue > 0.01
    # the axis is uniform too: its z component is uniform on [-1, 1]
    axis_z = Rotation.from_quat(quats).as_rotvec()[:, 2] / theta
    assert stats.kstest(axis_z, stats.uniform(-1, 2).cdf).pvalue > 0.01
    ranges = np.array([s.drawn["targets.0.trajectory.position_m"][0] for s in plan.sequences])
    assert ranges.min() >= 10 and ranges.max() <= 100
    assert stats.kstest(ranges, stats.uniform(10, 90).cdf).pvalue > 0.01
    first = sum(s.drawn["sensor.datasheet"] == "ouster-os1-64" for s in plan.sequences)
    assert stats.binomtest(first, count, 0.5).pvalue > 0.01
    rates = np.linalg.norm([s.drawn["targets.0.trajectory.angular_velocity_deg_s"]
                            for s in plan.sequences], axis=1)
    assert rates.min() >= 0.5 and rates.max() <= 6


def test_a_haar_test_that_can_fail():
    """The same test rejects attitudes that are uniform in Euler angles (not Haar)."""
    rng = np.random.default_rng(0)
    euler = rng.uniform([-np.pi, -np.pi / 2, -np.pi], [np.pi, np.pi / 2, np.pi], (3000, 3))
    theta = Rotation.from_euler("xyz", euler).magnitude()
    assert stats.kstest(theta, haar_angle_cdf).pvalue < 0.01


def test_bad_distribution_names_file_and_field(tmp_path):
    path = dataset_file(tmp_path)
    data = yaml.safe_load(path.read_text())
    data["sequences"][0]["randomize"]["targets.0.trajectory.position_m"] = {"uniform": [5, 1]}
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError) as err:
        load_plan(path)
    assert str(path) in str(err.value) and "randomize" in str(err.value)
    res = run_cli("dataset", str(path), "--out", str(tmp_path / "out"), "--quiet")
    assert res.returncode == 2 and not (tmp_path / "out").exists()


# --- samples ------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    base = tmp_path_factory.mktemp("training")
    shards = base / "shards_ds"
    ply = base / "ply_ds"
    generate_dataset(dataset_file(base), shards)
    generate_dataset(dataset_file(base, fmt="ply"), ply)
    return shards, ply


def test_samples_equal_the_frames_ls_read_and_poses_json_give(generated):
    shards, ply = generated
    manifest = json.loads((shards / "manifest.json").read_text())
    assert all("drawn" in s for s in manifest["sequences"])
    ds = ls.open_dataset(shards, split=None)
    assert len(ds) == 6
    checked_pixels = 0
    padded = 0
    for i in range(len(ds)):
        sample = ds[i]
        meta = sample["meta"]
        seq_dir = ply / "sequences" / meta["sequence"]
        cloud = ls.read(seq_dir / "frames" / f"frame_{meta['frame']:06d}.ply")
        mask = sample["mask"].astype(bool)
        assert len(mask) == N and sample["points"].shape == (N, 3)
        assert mask.sum() == min(len(cloud), N) and mask[:mask.sum()].all()
        assert meta["points_in_frame"] == len(cloud)
        padded += len(cloud) < N
        rows = sample["index"][mask]
        assert len(np.unique(rows)) == len(rows)
        np.testing.assert_array_equal(sample["points"][mask], cloud.xyz[rows])
        np.testing.assert_array_equal(sample["points"][~mask], 0.0)
        np.testing.assert_array_equal(sample["part"][mask], cloud["part"][rows])
        np.testing.assert_array_equal(sample["target"][mask], cloud["target"][rows])
        np.testing.assert_array_equal(sample["return_number"][mask],
                                      cloud["return_number"][rows])
        np.testing.assert_array_equal(sample["false_alarm"][mask], cloud["target"][rows] < 0)
        body = np.column_stack([cloud["x_body"], cloud["y_body"], cloud["z_body"]])[rows]
        np.testing.assert_array_equal(sample["body"][mask], body)
        poses = ds.poses(meta["sequence"])["frames"][meta["frame"]]
        ply_poses = json.loads((seq_dir / "poses.json").read_text())["frames"][meta["frame"]]
        assert poses["targets"] == ply_poses["targets"]
        assert poses["cloud"] == f"{meta['sequence']}/{meta['frame']:06d}"
        truth = poses["targets"][0]
        np.testing.assert_allclose(sample["pose_quaternion"][0], truth["q_target_in_sensor"],
                                   rtol=0, atol=1e-12)
        np.testing.assert_allclose(sample["pose_translation"][0],
                                   truth["r_target_in_sensor_m"], rtol=0, atol=1e-9)
        image = cloud.range_image()
        np.testing.assert_array_equal(sample["range_image"], image.range)
        np.testing.assert_array_equal(sample["range_part"], image.part)
        np.testing.assert_array_equal(sample["range_index"], image.point_index)
        assert sample["range_image"].shape == (256, 256)
        checked_pixels += int(np.isfinite(image.range).sum())
        # intrinsics: the direction of every pixel with a return is its point's direction
        hit = image.point_index >= 0
        np.testing.assert_allclose(sample["range_azimuth"][hit],
                                   cloud["azimuth"][image.point_index[hit]], atol=1e-12)
        np.testing.assert_allclose(sample["range_elevation"][hit],
                                   cloud["elevation"][image.point_index[hit]], atol=1e-12)
        assert np.isfinite(sample["range_azimuth"]).all()
    assert checked_pixels > 1000
    assert 0 < padded < len(ds)  # both padded and sampled frames were checked


def test_shards_are_plain_tar_files_of_npy_members(generated):
    shards, _ = generated
    manifest = json.loads((shards / "manifest.json").read_text())
    frames = sum(s["frame_count"] for s in manifest["sequences"])
    files = [s["file"] for s in manifest["shards"]]
    assert len(files) <= -(-frames // 4) + 2  # 4 frames per shard, split by split
    # one shard per 4 frames (per split), and three files more: no file per sequence
    every = sorted(p.relative_to(shards).as_posix() for p in shards.rglob("*")
                   if p.is_file() and not p.name.startswith("."))
    assert every == sorted(["manifest.json", "splits.json", "sequences.tar", *files])
    members: dict[str, set[str]] = {}
    for entry in manifest["shards"]:
        with tarfile.open(shards / entry["file"]) as tar:
            names = tar.getnames()
        keys = {n.rsplit("/", 1)[0] + "/" + n.rsplit("/", 1)[1].split(".")[0] for n in names}
        assert len(keys) == entry["samples"]
        assert all(n.endswith((".npy", ".json")) for n in names)
        members[entry["file"]] = set(names)
    for seq in manifest["sequences"]:  # every frame's entry names the shard that holds it
        assert [f["frame"] for f in seq["frames"]] == list(range(seq["frame_count"]))
        for f in seq["frames"]:
            assert f"{f['key']}.points.npy" in members[f["file"]]


def test_padding_and_farthest_point_sampling():
    scenario = ls.load_scenario(ROOT / "examples" / "datasets" / "envisat_training_scene.yaml")
    sim = ls.Simulation(scenario)
    cloud = sim.run_frame(0)
    n_frame = len(cloud)
    padded = make_sample(cloud, SampleSettings(points=n_frame + 100), seed=1)
    assert padded["mask"].sum() == n_frame and padded["mask"][n_frame:].sum() == 0
    np.testing.assert_array_equal(padded["index"][:n_frame], np.arange(n_frame))
    assert (padded["index"][n_frame:] == -1).all() and (padded["part"][n_frame:] == -1).all()
    fps = make_sample(cloud, SampleSettings(points=64, sampling="farthest"), seed=1)
    rows = fps["index"]
    xyz = cloud.xyz
    assert fps["mask"].all() and len(np.unique(rows)) == 64
    # each chosen point is the farthest from those before it (brute force)
    for k in range(1, 64):
        d = np.min(np.linalg.norm(xyz[:, None] - xyz[rows[:k]][None], axis=2), axis=1)
        assert np.isclose(d[rows[k]], d.max())
    assert (farthest_point_indices(xyz, 64, int(rows[0])) == rows).all()
    uni = make_sample(cloud, SampleSettings(points=64), seed=1)
    again = make_sample(cloud, SampleSettings(points=64), seed=1)
    np.testing.assert_array_equal(uni["index"], again["index"])
    assert not np.array_equal(uni["index"], make_sample(cloud, SampleSettings(points=64),
                                                        seed=2)["index"])


# --- the reader under loader workers --------------------------------------------------------

def _read(args):
    ds, i = args
    sample = ds[i]
    return i, {k: v for k, v in sample.items() if k != "meta"}, sample["meta"]


def test_reader_under_spawned_workers_gives_the_same_samples_in_order(generated):
    shards, _ = generated
    ds = ls.open_dataset(shards, split="train")
    order = np.random.default_rng(11).permutation(len(ds))
    serial = [ds[int(i)] for i in order]
    pickle.dumps(ds)  # the open shard files are not pickled
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        parallel = pool.map(_read, [(ds, int(i)) for i in order], chunksize=1)
    assert [p[0] for p in parallel] == [int(i) for i in order]
    for want, (_, arrays, meta) in zip(serial, parallel):
        assert meta == want["meta"]
        for key, value in arrays.items():
            np.testing.assert_array_equal(value, want[key])


def test_pytorch_dataloader_when_installed(generated):
    torch = pytest.importorskip("torch")
    shards, _ = generated
    ds = ls.open_dataset(shards, split="train")
    loader = torch.utils.data.DataLoader(ds, batch_size=2, num_workers=2,
                                         multiprocessing_context="spawn")
    assert sum(len(batch["points"]) for batch in loader) == len(ds)


# --- generation: rerun, resume, workers -----------------------------------------------------

def test_rerun_is_a_no_op_and_a_changed_draw_is_refused(generated, tmp_path):
    shards, _ = generated
    before = tree(shards)
    path = dataset_file(shards.parent)
    result = generate_dataset(path, shards)
    assert result.frames_written == 0 and tree(shards) == before
    # a damaged shard is found by --verify (its checksum in the manifest) and written again
    victim = sorted((shards / "shards").glob("*.tar"))[-1]
    data = bytearray(victim.read_bytes())
    data[1000] ^= 0xFF
    victim.write_bytes(bytes(data))
    assert generate_dataset(path, shards).frames_written == 0  # without --verify: trusted
    result = generate_dataset(path, shards, verify=True)
    assert result.frames_written > 0 and tree(shards) == before
    data = yaml.safe_load(path.read_text())
    data["seed"] = 6  # other draws: another dataset
    other = tmp_path / "other.yaml"
    (tmp_path / "scene.yaml").write_text((shards.parent / "scene.yaml").read_text())
    other.write_text(yaml.safe_dump(data))
    res = run_cli("dataset", str(other), "--out", str(shards), "--quiet")
    assert res.returncode == 2 and "made differently" in res.stderr
    assert tree(shards) == before


def test_resume_after_sigkill_mid_shard_is_byte_identical(generated, tmp_path):
    shards, _ = generated
    reference = tree(shards)
    path = dataset_file(shards.parent)
    out = tmp_path / "ds"
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1"}
    proc = subprocess.Popen([sys.executable, "-c", CODE, "dataset", str(path), "--out",
                             str(out), "--quiet"], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    try:  # wait until a shard is being written (its hidden .part file exists)
        while time.monotonic() < deadline and proc.poll() is None:
            if list((out / "shards").glob(".*.part")) if (out / "shards").is_dir() else []:
                break
            time.sleep(0.005)
        assert proc.poll() is None, "the run ended before a shard was being written"
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
        proc.stdout.close()
        proc.stderr.close()
    # killed before the end: the manifest is the first one, without shards
    assert not json.loads((out / "manifest.json").read_text())["complete"]
    res = run_cli("dataset", str(path), "--out", str(out), "--quiet")
    assert res.returncode == 0, res.stderr
    assert tree(out) == reference


def test_dask_workers_write_the_same_bytes(generated, tmp_path):
    pytest.importorskip("distributed")
    shards, _ = generated
    out = tmp_path / "ds"
    generate_dataset(dataset_file(shards.parent), out, workers=2)
    assert tree(out) == tree(shards)


# --- the tutorial (docs/training.md) --------------------------------------------------------

def _tutorial_blocks() -> list[str]:
    import re

    text = (ROOT / "docs" / "training.md").read_text(encoding="utf-8")
    return re.findall(r'```python(?: title="example")?\n(.*?)```', text, re.S)


def test_tutorial_code_runs(generated, capsys, tmp_path, monkeypatch):
    shards, _ = generated
    blocks = _tutorial_blocks()
    assert len(blocks) == 3 and blocks[2].startswith("# example: pytorch")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "training_set").symlink_to(shards)  # the folder the page's blocks name
    namespace: dict = {}
    for block in blocks[:2]:  # the reader and the NumPy training loop
        exec(compile(block, "docs/training.md", "exec"), namespace)
    out = capsys.readouterr().out
    assert f"trained on {len(namespace['train'])} samples" in out
    assert np.isfinite(namespace["w"]).all() and np.abs(namespace["w"]).sum() > 0
    try:
        import torch  # noqa: F401
    except ImportError:
        compile(blocks[2], "docs/training.md", "exec")  # shown, not a dependency: it parses
    else:
        namespace["range"] = lambda *a: iter([0])  # one epoch
        exec(compile(blocks[2], "docs/training.md", "exec"), namespace)


def test_shards_without_samples_and_sequences_without_randomize_are_refused(tmp_path):
    path = dataset_file(tmp_path, fmt="ply")
    res = run_cli("dataset", str(path), "--out", str(tmp_path / "a"), "--quiet",
                  "--format", "shards")
    assert res.returncode == 2 and "samples" in res.stderr and str(path) in res.stderr
    data = yaml.safe_load(path.read_text())
    del data["sequences"][0]["randomize"], data["sequences"][0]["count"]
    path.write_text(yaml.safe_dump(data))
    res = run_cli("dataset", str(path), "--out", str(tmp_path / "b"), "--quiet",
                  "--sequences", "3")
    assert res.returncode == 2 and "randomize" in res.stderr
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_range_images_of_a_sensor_without_layout_are_refused(tmp_path):
    path = dataset_file(tmp_path)
    data = yaml.safe_load(path.read_text())
    data["sequences"][0]["set"] = {"sensor.datasheet": "livox-mid70-rose"}
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match="no regular layout") as err:
        generate_dataset(path, tmp_path / "out")
    assert err.value.field == "samples.range_image" and str(path) in str(err.value)
    assert not (tmp_path / "out").exists()


def test_each_distribution_follows_its_law():
    """Nine tests on one stream: each at p > 0.001 (Bonferroni for ~1 % over the family)."""
    from pydantic import TypeAdapter

    from lidarsim_core.dataset.randomize import Distribution

    adapter = TypeAdapter(Distribution)
    rng = np.random.default_rng(3)

    def draws(spec, n=4000):
        dist = adapter.validate_python(spec)
        return [dist.draw(rng) for _ in range(n)]

    direction = np.array(draws({"sphere": "uniform", "radius": 2.0}))
    assert np.allclose(np.linalg.norm(direction, axis=1), 2.0)
    assert stats.kstest(direction[:, 2] / 2, stats.uniform(-1, 2).cdf).pvalue > 0.001
    azimuth = np.arctan2(direction[:, 1], direction[:, 0])
    assert stats.kstest(azimuth, stats.uniform(-np.pi, 2 * np.pi).cdf).pvalue > 0.001
    log = draws({"log_uniform": [0.1, 1000]})
    assert stats.kstest(log, stats.loguniform(0.1, 1000).cdf).pvalue > 0.001
    assert stats.kstest(log, stats.uniform(0.1, 999.9).cdf).pvalue < 1e-6  # not uniform
    bounded = draws({"normal": [0, 1], "bounds": [-0.5, 2]})
    assert stats.kstest(bounded, stats.truncnorm(-0.5, 2).cdf).pvalue > 0.001
    integers = draws({"uniform": [0, 10], "integer": True, "bounds": [1, 9]})
    assert set(integers) == set(range(1, 10)) and all(isinstance(v, int) for v in integers)
    picks = draws({"choice": ["a", "b", "c"], "weights": [1, 2, 1]})
    counts = [picks.count(v) for v in "abc"]
    assert stats.chisquare(counts, np.array([1, 2, 1]) / 4 * len(picks)).pvalue > 0.001
    assert stats.chisquare(counts, [len(picks) / 3] * 3).pvalue < 1e-6  # the weights matter
    quats = np.array(draws({"so3": "uniform"}))
    assert (quats[:, 3] >= 0).all()
    assert stats.kstest(Rotation.from_quat(quats).magnitude(), haar_angle_cdf).pvalue > 0.001
    assert draws({"vector": [{"choice": [7]}, 0, "x"]}, 1) == [[7, 0, "x"]]
