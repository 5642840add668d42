"""Hostile input, round three (issue 27): the readers, the dataset checks, the evaluation
inputs and the output paths. One test per class of the issue; each malformed input must end
in one line naming the file (exit 2 from the command line, :class:`ConfigError` or another
:class:`UserInputError` from the API), leave nothing partial, replace no input or device, and
print no raw control character.
"""

from __future__ import annotations

import json
import os
import shutil
import stat
import sys
from pathlib import Path

import hostile_files as hostile
import numpy as np
import pytest
import yaml

from lidarsim_core import cli
from lidarsim_core.base.errors import ConfigError, UserInputError

BASE = yaml.safe_load((Path(__file__).parent / "bad_inputs" / "files" /
                       "base_scenario.yaml").read_text())
FORMATS = ("ply", "pcd", "las", "npz")


def run(argv: list, capsys) -> tuple[int, str, str]:
    capsys.readouterr()
    with pytest.raises(SystemExit) as stop:
        cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return stop.value.code, out, err


def refused(argv: list, capsys, *fragments: str) -> str:
    """Run ``argv``; exit 2, exactly one line, every fragment in it, no control character."""
    code, out, err = run(argv, capsys)
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ")
    for fragment in fragments:
        assert fragment in lines[0], f"{fragment!r} not in {lines[0]!r}"
    assert not any(ord(c) < 32 and c != "\n" for c in out + err), repr(out + err)
    return lines[0]


def scenario(tmp_path: Path, name: str = "scene.yaml", **top) -> Path:
    data = json.loads(json.dumps(BASE))
    data.update(top)
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.fixture(scope="module")
def clouds(tmp_path_factory) -> dict[str, bytes]:
    """The bytes of one valid cloud per format, written by ``lidarsim simulate``."""
    root = tmp_path_factory.mktemp("clouds")
    path = root / "scene.yaml"
    path.write_text(yaml.safe_dump(BASE))
    out = {}
    for fmt in FORMATS:
        with pytest.raises(SystemExit) as stop:
            cli.main(["simulate", str(path), "--out", str(root / f"c.{fmt}")])
        assert stop.value.code == 0
        out[fmt] = (root / f"c.{fmt}").read_bytes()
    out["sidecar"] = (root / "c.ply.json").read_bytes()
    return out


CASES = {"ply": hostile.ply_cases, "pcd": hostile.pcd_cases, "las": hostile.las_cases,
         "npz": hostile.npz_cases}


def _case_ids() -> list[tuple[str, str]]:
    names = {"ply": ["huge count", "negative count", "non-integer count",
                     "element without count", "duplicate property", "truncated record",
                     "comment not JSON"],
             "pcd": ["huge count", "negative count", "missing FIELDS", "unknown TYPE",
                     "truncated record"],
             "las": ["huge count", "truncated", "metadata VLR not UTF-8",
                     "metadata VLR not JSON"],
             "npz": ["zip bomb", "truncated zip", "columns of different lengths",
                     "text column", "2-D column", "pickle", "NPY shape 2**36",
                     "frame_json not JSON"]}
    return [(fmt, name) for fmt, cases in names.items() for name in cases]


# ---- readers that raised raw exceptions or allocated declared counts -----------------------
@pytest.mark.parametrize("fmt, case", _case_ids())
def test_malformed_clouds_are_refused_naming_file_and_defect(clouds, tmp_path, fmt, case):
    import lidarsim_core as ls

    if fmt == "las":
        pytest.importorskip("laspy")
    data, fragment = CASES[fmt](clouds[fmt])[case]
    path = tmp_path / f"bad.{fmt}"
    path.write_bytes(data)
    (tmp_path / f"bad.{fmt}.json").write_bytes(clouds["sidecar"])
    with pytest.raises(ConfigError) as caught:
        ls.read(path)
    assert str(caught.value).startswith(f"{path}: "), caught.value
    assert fragment in str(caught.value)


def test_the_valid_clouds_still_read(clouds, tmp_path):
    import lidarsim_core as ls

    for fmt in FORMATS:
        path = tmp_path / f"ok.{fmt}"
        path.write_bytes(clouds[fmt])
        cloud = ls.read(path)
        assert len(cloud) > 0 and cloud["x"].flags.writeable


def test_declared_counts_are_refused_without_allocating(clouds, tmp_path):
    """The 2^40-vertex header is refused under a 1 GiB address-space cap in a subprocess:
    the check compares with the file's length before any buffer exists."""
    path = tmp_path / "huge.ply"
    path.write_bytes(CASES["ply"](clouds["ply"])["huge count"][0])
    code = ("import resource, lidarsim_core as ls\n"
            "resource.setrlimit(resource.RLIMIT_AS, (2**30, 2**30))\n"
            "from lidarsim_core.base.errors import ConfigError\n"
            f"try:\n    ls.read({str(path)!r})\nexcept ConfigError as e:\n    print('refused')\n")
    import subprocess

    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, timeout=120)
    assert res.stdout.strip() == "refused", res.stderr


@pytest.mark.skipif(sys.platform != "linux", reason="FIFOs")
def test_a_fifo_named_as_cloud_is_refused_without_blocking(tmp_path):
    import lidarsim_core as ls

    os.mkfifo(tmp_path / "pipe.ply")
    with pytest.raises(ConfigError, match="named pipe"):
        ls.read(tmp_path / "pipe.ply")


def test_view_names_the_malformed_file(clouds, tmp_path, capsys):
    pytest.importorskip("pyvista")
    import lidarsim_core.cli.view  # noqa: F401  (registers the command)

    path = tmp_path / "bad.ply"
    path.write_bytes(CASES["ply"](clouds["ply"])["negative count"][0])
    refused(["view", path, "--screenshot", tmp_path / "shot.png"], capsys, str(path), "'-5'")
    assert not (tmp_path / "shot.png").exists()


# ---- datasets trusted only after verification ----------------------------------------------
SCENE = {
    "seed": 3,
    "sensor": {"datasheet": "livox-mid70-rose", "pose": {"position_m": [0, 0, 0]}},
    "targets": [{"name": "box", "mesh": {"model": "box", "options": {"extents_m": [2, 2, 2]}},
                 "pose": {"position_m": [12, 0, 0]}}],
    "scan": {"duration_s": 0.02, "frame_period_s": 0.1, "frames": 3},
    "backend": "numpy",
}


@pytest.fixture(scope="module")
def dataset_dir(tmp_path_factory) -> Path:
    from lidarsim_core.dataset import generate_dataset

    root = tmp_path_factory.mktemp("ds27")
    scene = root / "scene.yaml"
    scene.write_text(yaml.safe_dump(SCENE, sort_keys=False))
    generate_dataset(scene, root / "ds", quiet=True)
    return root / "ds"


@pytest.fixture()
def ds(dataset_dir, tmp_path) -> Path:
    """A private copy of the dataset to break."""
    copy = tmp_path / "ds"
    shutil.copytree(dataset_dir, copy, symlinks=True)
    return copy


def _manifest(ds: Path) -> dict:
    return json.loads((ds / "manifest.json").read_text())


def _frame_files(ds: Path) -> list[Path]:
    return [ds / f["file"] for f in _manifest(ds)["sequences"][0]["frames"]]


def _edit_manifest(ds: Path, change) -> None:
    data = _manifest(ds)
    change(data)
    (ds / "manifest.json").write_text(json.dumps(data))


def _edit_poses(ds: Path, change) -> None:
    path = ds / "poses.json"
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))  # json writes NaN as NaN, as a careless tool would


def _evaluate_refused(ds: Path, capsys, *fragments: str, extra: tuple = ()) -> None:
    pytest.importorskip("matplotlib")
    out = ds.parent / "ev"
    refused(["evaluate", ds, "--estimator", "gt_noise", "--out", out, "--quiet", *extra],
            capsys, *fragments)
    assert not out.exists()  # nothing half-written


def test_evaluate_refuses_a_frame_outside_the_dataset(ds, capsys):
    (ds.parent / "outside.npz").write_bytes(_frame_files(ds)[0].read_bytes())

    def out(data):
        data["sequences"][0]["frames"][0]["file"] = "../outside.npz"
    _edit_manifest(ds, out)
    _evaluate_refused(ds, capsys, "manifest.json", "sequences.0.frames.0.file",
                      "not a path inside the dataset")


def test_evaluate_refuses_a_symbolic_link_out_of_the_dataset(ds, capsys):
    first = _frame_files(ds)[0]
    outside = ds.parent / "elsewhere.npz"
    shutil.copy(first, outside)
    first.unlink()
    first.symlink_to(outside)
    _evaluate_refused(ds, capsys, "manifest.json", "symbolic link out of the dataset")


def test_evaluate_verifies_checksums_and_can_skip_them(ds, capsys):
    frames = _frame_files(ds)
    shutil.copy(frames[2], frames[0])  # frame 2's cloud in frame 0's file
    _evaluate_refused(ds, capsys, str(frames[0]), "SHA-256 differs")
    code, _, err = run(["evaluate", ds, "--estimator", "gt_noise", "--out", ds.parent / "ev2",
                        "--quiet", "--no-verify"], capsys)
    assert code == 0, err  # the opt-out: the user chose speed over the check


def test_evaluate_refuses_a_truncated_frame_before_writing(ds, capsys):
    frame = _frame_files(ds)[1]
    frame.write_bytes(frame.read_bytes()[:100])
    _evaluate_refused(ds, capsys, str(frame), "SHA-256 differs")


@pytest.mark.parametrize("change, field, fragment", [
    (lambda d: d["frames"][1].update(t_start_s=float("nan")), "frames.1.t_start_s",
     "not a finite number"),
    (lambda d: d["frames"][0]["targets"][0].update(q_target_in_sensor=[0, 0, 0, 0]),
     "frames.0.targets.0.q_target_in_sensor", "not a unit quaternion"),
    (lambda d: d["frames"][2]["targets"][0].update(r_target_in_sensor_m=[float("nan"), 0, 0]),
     "frames.2.targets.0.r_target_in_sensor_m", "not finite"),
    (lambda d: d.update(target_names=[]), "target_names", "lists no targets"),
    (lambda d: d["frames"][0].update(targets=[]), "frames.0.targets", "0 target records"),
    (lambda d: d["frames"][1].update(t_end_s=-1.0), "frames.1.t_end_s", "before it starts"),
])
def test_evaluate_validates_poses_json_naming_it(ds, capsys, change, field, fragment):
    _edit_poses(ds, change)
    _evaluate_refused(ds, capsys, "poses.json", field, fragment, extra=("--no-verify",))
