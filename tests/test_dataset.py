"""Dataset generation: files, manifest checksums, poses, resume, refusal of a changed
scenario, bit-for-bit regeneration, self-contained inputs, and splits by trajectory."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from lidarsim_core.base.errors import ConfigError, OutputError
from lidarsim_core.dataset import generate_dataset, read_manifest
from lidarsim_core.dataset.config import SplitFractions
from lidarsim_core.dataset.lock import dataset_lock
from lidarsim_core.dataset.splits import assign_splits, split_counts
from lidarsim_core.io.groundtruth import read_ground_truth
from lidarsim_core.records.groundtruth import pose_from_record

SCENARIO = {
    "seed": 4,
    "sensor": {"datasheet": "livox-mid70-rose", "pose": {"position_m": [0, 0, 0]}},
    "targets": [
        {"name": "envisat", "mesh": {"model": "envisat", "options": {"detail": "coarse"}},
         "pose": {"position_m": [30, -8, 0], "euler_deg": [0, 0, 90]}},
        {"name": "debris", "mesh": {"model": "box", "options": {"extents_m": [1.2, 0.8, 0.4]}},
         "trajectory": {"kind": "constant_velocity", "position_m": [20, -2, 0],
                        "velocity_m_s": [0, 2, 0], "angular_velocity_deg_s": [10, 20, 5]}}],
    "scan": {"duration_s": 0.02, "frame_period_s": 0.1, "frames": 3},
    "backend": "numpy",
}


def write_yaml(path: Path, data) -> Path:
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def tree(root: Path) -> dict[str, str]:
    """Relative path → SHA-256 of every file (hidden ones included)."""
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture
def scenario_file(tmp_path) -> Path:
    return write_yaml(tmp_path / "scene.yaml", SCENARIO)


def test_dataset_files_manifest_checksums_and_poses(scenario_file, tmp_path):
    out = tmp_path / "ds"
    result = generate_dataset(scenario_file, out)
    assert (result.frames_total, result.frames_written, result.frames_skipped) == (3, 3, 0)
    names = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file()}
    frames = {f"frames/frame_00000{i}.ply" for i in range(3)}
    assert frames | {f + ".json" for f in frames} | {"manifest.json", "scenario.yaml",
                                                      "poses.json"} <= names
    assert not [n for n in names if n.endswith(".part")]
    manifest = read_manifest(out / "manifest.json")
    assert manifest["complete"] is True and manifest["splits"] is None
    entries = manifest["sequences"][0]["frames"]
    assert [e["file"] for e in entries] == sorted(frames)
    for entry in entries:
        data = (out / entry["file"]).read_bytes()
        assert hashlib.sha256(data).hexdigest() == entry["sha256"]
        assert len(data) == entry["bytes"]
    assert manifest["totals"]["points"] == sum(e["points"] for e in entries) > 0
    ident = manifest["identity"]
    assert ident["software"].startswith("lidarsim-core ") and "numpy" in ident["packages"]
    assert ident["sequences"][0]["plugins"]["ray_backend/numpy"].startswith("lidarsim-core")
    # the poses file is the ground-truth format, one record per frame with its cloud
    poses = read_ground_truth(out / "poses.json")
    assert [f["cloud"] for f in poses["frames"]] == sorted(frames)
    debris = [pose_from_record(f["targets"][1], "target_in_scene") for f in poses["frames"]]
    # the debris moves 2 m/s along +y: 0.2 m between frames 0.1 s apart
    np.testing.assert_allclose(debris[2].position[0] - debris[0].position[0], [0, 0.4, 0],
                               atol=1e-12)
    assert poses["config_hash"] == manifest["sequences"][0]["config_hash"]


def test_rerun_skips_everything_and_changes_nothing(scenario_file, tmp_path):
    out = tmp_path / "ds"
    generate_dataset(scenario_file, out)
    before = tree(out)
    again = generate_dataset(scenario_file, out)
    assert (again.frames_written, again.frames_skipped) == (0, 3)
    assert tree(out) == before


def test_missing_or_corrupt_frames_are_regenerated_identically(scenario_file, tmp_path):
    out = tmp_path / "ds"
    generate_dataset(scenario_file, out)
    before = tree(out)
    (out / "frames/frame_000001.ply").unlink()
    (out / "frames/frame_000002.ply.json").unlink()
    assert generate_dataset(scenario_file, out).frames_written == 2
    assert tree(out) == before
    path = out / "frames/frame_000000.ply"
    data = bytearray(path.read_bytes())
    data[-1] ^= 0xFF  # same size, wrong bytes: only --verify notices
    path.write_bytes(bytes(data))
    assert generate_dataset(scenario_file, out).frames_written == 0
    assert generate_dataset(scenario_file, out, verify=True).frames_written == 1
    assert tree(out) == before


def test_changed_scenario_is_refused_with_the_fields_named(scenario_file, tmp_path):
    out = tmp_path / "ds"
    generate_dataset(scenario_file, out)
    before = tree(out)
    changed = write_yaml(tmp_path / "scene.yaml", {**SCENARIO, "seed": 5})
    with pytest.raises(OutputError, match=r"made differently \(seed: 4 → 5\)"):
        generate_dataset(changed, out)
    with pytest.raises(OutputError, match=r"scan\.frames: 3 → 4"):
        generate_dataset(scenario_file, out, frames=4)
    with pytest.raises(OutputError, match=r"exporter\.name: \"ply\" → \"npz\""):
        generate_dataset(write_yaml(tmp_path / "scene.yaml", SCENARIO), out, format="npz")
    with pytest.raises(OutputError, match=r"exporter\.options\.xyz_dtype: \(absent\)"):
        generate_dataset(scenario_file, out, format="pcd", exporter_options={})
    assert tree(out) == before


def test_foreign_directory_and_concurrent_runs_are_refused(scenario_file, tmp_path):
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    with pytest.raises(OutputError, match="not empty and holds no lidarsim dataset"):
        generate_dataset(scenario_file, foreign)
    out = tmp_path / "ds"
    out.mkdir()
    with dataset_lock(out):
        with pytest.raises(OutputError, match="another 'lidarsim dataset' run"):
            generate_dataset(scenario_file, out)


def test_any_frame_regenerates_bit_for_bit_from_the_copy_even_when_moved(tmp_path):
    import trimesh

    from lidarsim_core.pipeline import Simulation
    from lidarsim_core.scenario import load_scenario

    meshes = tmp_path / "meshes"
    meshes.mkdir()
    trimesh.creation.box(extents=[2, 3, 1]).export(meshes / "block.stl")
    data = json.loads(json.dumps(SCENARIO))
    data["targets"][1]["mesh"] = {"path": "meshes/block.stl"}
    scenario_file = write_yaml(tmp_path / "scene.yaml", data)
    out = tmp_path / "ds"
    generate_dataset(scenario_file, out, format="npz")
    copy = yaml.safe_load((out / "scenario.yaml").read_text())
    assert copy["targets"][1]["mesh"]["path"].startswith("inputs/")
    assert copy["backend"]["name"] == "numpy"
    moved = tmp_path / "elsewhere" / "ds"
    moved.parent.mkdir()
    shutil.move(str(out), str(moved))
    shutil.rmtree(meshes)  # the dataset no longer needs the original inputs
    sim = Simulation(load_scenario(moved / "scenario.yaml"))
    for frame in (0, 2):
        target = tmp_path / f"again_{frame}.npz"
        sim.run_frame(frame).save(target)
        assert target.read_bytes() == (moved / f"frames/frame_00000{frame}.npz").read_bytes()
    # and the moved dataset resumes as itself
    assert generate_dataset(moved / "scenario.yaml", moved).frames_skipped == 3


# ---- several sequences and splits ------------------------------------------------------------
def _dataset_file(tmp_path, scenario_file, **extra) -> Path:
    data = {"sequences": [
        {"scenario": scenario_file.name, "name": "cross", "seeds": [1, 2, 3], "frames": 2},
        {"scenario": scenario_file.name, "name": "fast", "frames": 2,
         "set": {"targets.1.trajectory.velocity_m_s": [0, 3, 0]}},
        {"scenario": scenario_file.name, "name": "slow", "frames": 1,
         "set": {"targets.1.trajectory.velocity_m_s": [0, 1, 0]}},
        {"scenario": scenario_file.name, "name": "spin", "frames": 1,
         "set": {"targets.1.trajectory.angular_velocity_deg_s": [0, 0, 40]}}],
        "format": "npz", **extra}
    return write_yaml(tmp_path / "dataset.yaml", data)


def test_splits_keep_trajectories_whole(scenario_file, tmp_path):
    out = tmp_path / "ds"
    generate_dataset(_dataset_file(tmp_path, scenario_file), out)
    splits = json.loads((out / "splits.json").read_text())
    # the three seeds of one trajectory form one group, so one split
    groups = {tuple(g["sequences"]): g["split"] for g in splits["groups"].values()}
    assert ("cross_s1", "cross_s2", "cross_s3") in groups and len(groups) == 4
    assignment = {seq: split for split, seqs in splits["splits"].items() for seq in seqs}
    assert sorted(assignment) == ["cross_s1", "cross_s2", "cross_s3", "fast", "slow", "spin"]
    assert sorted(set(groups.values())) == ["test", "train", "val"]  # 4 groups: 2/1/1
    listed = {}
    for split in ("train", "val", "test"):
        for line in (out / "splits" / f"{split}.txt").read_text().split():
            seq = line.split("/")[1]
            assert assignment[seq] == split  # every frame of a sequence in its split
            listed[line] = split
            assert (out / line).is_file()
    assert len(listed) == 3 * 2 + 2 + 1 + 1 == read_manifest(out / "manifest.json")[
        "totals"]["frames"]
    manifest = read_manifest(out / "manifest.json")
    seeds = {s["name"]: s["seed"] for s in manifest["sequences"]}
    assert seeds["cross_s2"] == 2 and seeds["fast"] == SCENARIO["seed"]
    # the noise differs between seeds of the same trajectory, the poses do not
    a = np.load(out / "sequences/cross_s1/frames/frame_000000.npz")
    b = np.load(out / "sequences/cross_s2/frames/frame_000000.npz")
    assert not np.array_equal(a["range"], b["range"])
    pa = read_ground_truth(out / "sequences/cross_s1/poses.json")["frames"]
    pb = read_ground_truth(out / "sequences/cross_s2/poses.json")["frames"]
    assert pa[1]["targets"] == pb[1]["targets"]
    # rerunning the expanded copy of the dataset file resumes the same dataset
    before = tree(out)
    assert generate_dataset(out / "dataset.yaml", out).frames_skipped == 10
    assert tree(out) == before


def test_pinned_splits_and_conflicting_pins(scenario_file, tmp_path):
    groups = {"g1": ["a1", "a2"], "g2": ["b"], "g3": ["c"]}
    fractions = SplitFractions(train=1, val=0, test=0)
    got = assign_splits(groups, {"a2": "test"}, fractions, 0, source="d")
    assert got == {"a1": "test", "a2": "test", "b": "train", "c": "train"}
    with pytest.raises(ConfigError, match="share trajectory group 'g1'.*different splits"):
        assign_splits(groups, {"a1": "val", "a2": "test"}, fractions, 0, source="d")
    # the shuffle is a function of the seed only
    fractions = SplitFractions()
    many = {f"g{i}": [f"s{i}"] for i in range(10)}
    first = assign_splits(many, {}, fractions, 7, source="d")
    assert first == assign_splits(dict(reversed(list(many.items()))), {}, fractions, 7,
                                  source="d")
    assert sorted(first.values()).count("train") == 8


@pytest.mark.parametrize("n, expected", [(10, (8, 1, 1)), (3, (1, 1, 1)), (4, (2, 1, 1)),
                                         (2, (2, 0, 0)), (0, (0, 0, 0)), (20, (16, 2, 2))])
def test_split_counts(n, expected):
    counts = split_counts(n, SplitFractions())
    assert (counts["train"], counts["val"], counts["test"]) == expected


def test_dataset_file_errors_name_file_and_field(scenario_file, tmp_path):
    bad = write_yaml(tmp_path / "bad.yaml", {"sequences": [
        {"scenario": scenario_file.name, "set": {"targets.7.name": "x"}}]})
    with pytest.raises(ConfigError, match=r"bad\.yaml: field 'sequences\.0\.set\.targets\.7"):
        generate_dataset(bad, tmp_path / "ds")
    dup = write_yaml(tmp_path / "dup.yaml", {"sequences": [
        {"scenario": scenario_file.name}, {"scenario": scenario_file.name}]})
    with pytest.raises(ConfigError, match="names must be unique; repeated: scene"):
        generate_dataset(dup, tmp_path / "ds")
    missing = write_yaml(tmp_path / "missing.yaml", {"sequences": [{"scenario": "nope.yaml"}]})
    with pytest.raises(ConfigError, match=r"missing\.yaml: field 'sequences\.0\.scenario'"):
        generate_dataset(missing, tmp_path / "ds")


def run_cli(*args: str) -> subprocess.CompletedProcess:
    """The real entry point (``python -m lidarsim_core.cli`` would not load the command
    modules into the app it runs)."""
    code = "import sys; from lidarsim_core.cli import main; main(sys.argv[1:])"
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", "COLUMNS": "200"}
    return subprocess.run([sys.executable, "-c", code, *args], env=env, capture_output=True,
                          text=True, timeout=120)


def test_cli_dataset_quiet_and_refusal_exit_codes(scenario_file, tmp_path):
    out = tmp_path / "ds"
    res = run_cli("dataset", str(scenario_file), "--out", str(out), "--quiet",
                  "--format", "pcd")
    assert res.returncode == 0, res.stderr
    assert res.stdout == "" and len(list((out / "frames").glob("*.pcd"))) == 3
    res = run_cli("dataset", str(scenario_file), "--out", str(out))  # resumes as pcd
    assert res.returncode == 0 and "(0 written, 3 already done)" in res.stdout
    res = run_cli("dataset", str(scenario_file), "--out", str(out), "--format", "ply")
    assert res.returncode == 2
    assert "made differently (exporter.name" in res.stderr and "Traceback" not in res.stderr


def test_a_finished_run_leaves_no_lock_file_and_the_lock_still_excludes(scenario_file,
                                                                        tmp_path):
    out = tmp_path / "ds"
    generate_dataset(scenario_file, out)
    assert not (out / ".lidarsim-dataset.lock").exists()
    assert not any(p.name.startswith(".") for p in out.rglob("*"))  # nothing hidden is left
    with dataset_lock(out):
        assert (out / ".lidarsim-dataset.lock").is_file()
        with pytest.raises(OutputError, match="another 'lidarsim dataset' run"):
            with dataset_lock(out):
                pass
        assert (out / ".lidarsim-dataset.lock").is_file()  # the refused run removed nothing
    assert not (out / ".lidarsim-dataset.lock").exists()
    generate_dataset(scenario_file, out)  # resumes (nothing to do) and cleans up again
    assert not (out / ".lidarsim-dataset.lock").exists()
