"""Hostile input, one test per class (issue 15): sizes refused before allocation, the bounded
reader, the error boundary (OS errors, output paths, numeric warnings, markup, options, seeds)
and ``dataset`` validation and clean-up.

Every command runs through the real entry point (:func:`lidarsim_core.cli.main`, with its
usage-error handling) in process; :func:`run` returns the exit status and what was printed.
"""

from __future__ import annotations

import errno
import json
import os
import struct
from pathlib import Path

import numpy as np
import pytest
import yaml

from lidarsim_core import cli

BASE = yaml.safe_load((Path(__file__).parent / "bad_inputs" / "files" /
                       "base_scenario.yaml").read_text())
SHEET = yaml.safe_load((Path(__file__).parent / "bad_inputs" / "files" /
                        "base_datasheet.yaml").read_text())


def run(argv: list[str], capsys) -> tuple[int, str, str]:
    capsys.readouterr()
    with pytest.raises(SystemExit) as stop:
        cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return stop.value.code, out, err


def refused(argv: list[str], capsys, *fragments: str) -> str:
    """Run ``argv``; assert exit 2 and exactly one line containing every fragment."""
    code, _, err = run(argv, capsys)
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ")
    for fragment in fragments:
        assert fragment in lines[0], f"{fragment!r} not in {lines[0]!r}"
    return lines[0]


def scenario(tmp_path: Path, name: str = "scene.yaml", **changes) -> Path:
    data = json.loads(json.dumps(BASE))
    for dotted, value in changes.items():
        node = data
        keys = dotted.split("__")
        for key in keys[:-1]:
            node = node[int(key)] if isinstance(node, list) else node.setdefault(key, {})
        if isinstance(node, list):
            node[int(keys[-1])] = value
        else:
            node[keys[-1]] = value
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for key in [k for k in os.environ if k.startswith("LIDARSIM_MAX_")] + ["LIDARSIM_THREADS"]:
        monkeypatch.delenv(key, raising=False)


def _entries(directory: Path) -> set[str]:
    return {p.relative_to(directory).as_posix() for p in directory.rglob("*")}


# ---- the resource budget -------------------------------------------------------------------
def test_point_rate_times_duration_is_refused_before_any_chunk(tmp_path, capsys):
    sheet = dict(SHEET, point_rate_hz=1e15)
    path = scenario(tmp_path, sensor__datasheet=sheet, scan={"duration_s": 1e6})
    line = refused(["simulate", path, "--out", "o.ply"], capsys, "scene.yaml",
                   "scan.duration_s", "1e+21 rays", "LIDARSIM_MAX_RAYS_PER_FRAME")
    assert "1e+15 Hz" in line
    assert _entries(tmp_path) == {"scene.yaml"}


def test_the_budget_follows_its_environment_variable(tmp_path, capsys, monkeypatch):
    path = scenario(tmp_path)  # 10 kHz... the rose MID-70: 100 kHz × 0.01 s = 1,000 rays
    monkeypatch.setenv("LIDARSIM_MAX_RAYS_PER_FRAME", "999")
    refused(["simulate", path, "--out", "o.ply"], capsys, "1,000 rays", "999")
    monkeypatch.setenv("LIDARSIM_MAX_RAYS_PER_FRAME", "1000")
    assert run(["simulate", path, "--out", "o.ply"], capsys)[0] == 0
    monkeypatch.setenv("LIDARSIM_MAX_RAYS_PER_FRAME", "lots")
    refused(["simulate", path, "--out", "p.ply"], capsys, "environment",
            "LIDARSIM_MAX_RAYS_PER_FRAME", "positive number")


@pytest.mark.parametrize("scan, field", [
    ({"duration_s": 0.01, "frames": 1.0e14}, "scan.frames"),
    ({"duration_s": 1e-300, "sequence_duration_s": 1e300}, "scan"),
])
def test_absurd_sequences_are_refused(tmp_path, capsys, scan, field):
    path = scenario(tmp_path, scan=scan)
    refused(["simulate", path, "--out", "o_{frame}.ply"], capsys, "scene.yaml", field,
            "LIDARSIM_MAX_FRAMES")


def test_frames_option_of_dataset_is_budgeted(tmp_path, capsys):
    path = scenario(tmp_path)
    refused(["dataset", path, "--out", "ds", "--frames", "100000000000000"], capsys,
            "--frames", "LIDARSIM_MAX_FRAMES")
    assert not (tmp_path / "ds").exists()


def test_chunk_lists_are_budgeted(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("LIDARSIM_MAX_CHUNKS_PER_FRAME", "100")
    path = scenario(tmp_path, chunk_rays=1)
    refused(["simulate", path, "--out", "o.ply"], capsys, "chunk_rays", "1,000 chunks")


@pytest.mark.parametrize("argv, fragments", [
    (["pattern", "livox-mid70", "--duration", "1e6", "--out", "p.npz"],
     ["--duration", "100,000,000,000 rays", "LIDARSIM_MAX_PATTERN_RAYS"]),
    (["coverage", "livox-mid70", "--time", "0.1", "--cell-deg", "1e-7"],
     ["--cell-deg", "cells", "LIDARSIM_MAX_COVERAGE_CELLS"]),
    (["coverage", "livox-mid70", "--time", "1e6"],
     ["--time", "100,000,000,000 rays", "LIDARSIM_MAX_RAYS_PER_FRAME"]),
    (["coverage", "livox-mid70", "--time", "0.1", "--bin-deg", "1e-9"],
     ["--bin-deg", "bins", "LIDARSIM_MAX_PROFILE_BINS"]),
    (["coverage", "ouster-os1-128", "--time", "0.01", "--cell-deg", "1e-300"],
     ["--cell-deg", "an infinite number of cells"]),
    (["pattern", "livox-mid70", "--duration", "0.01", "--start", "1e300", "--out", "p.npz"],
     ["--start", "2^53"]),
])
def test_pattern_and_coverage_sizes_are_refused(tmp_path, capsys, argv, fragments):
    refused(argv, capsys, *fragments)
    assert _entries(tmp_path) == set()


def test_coverage_cells_are_computed_like_the_grid():
    """The budget's cell count equals the grid fov_coverage builds, for every catalogue
    sensor (an independent count: the grid's own arrays)."""
    from lidarsim_core.patterns.fov import _Grid, coverage_cells
    from lidarsim_core.plugins import get_registry
    from lidarsim_core.plugins import pattern_for

    for entry in get_registry().iter("sensor"):
        pattern = pattern_for(entry.obj)
        for cell in (2.0, 0.7, 0.25):
            grid = _Grid(pattern, cell)
            assert coverage_cells(entry.obj, cell) == grid.nu * grid.nv


def test_torque_free_integration_is_budgeted(tmp_path, capsys):
    trajectory = {"kind": "torque_free", "inertia_kg_m2": [1, 2, 2.5],
                  "angular_velocity_deg_s": [1e9, 0, 0]}
    target = dict(BASE["targets"][0], trajectory=trajectory)
    del target["pose"]
    path = scenario(tmp_path, targets=[target])
    refused(["simulate", path, "--out", "o.ply"], capsys,
            "targets.0.trajectory.angular_velocity_deg_s", "rad", "LIDARSIM_MAX_INTEGRATION_RAD")
    # a slow body far from its reference time needs as many pieces as the time span
    trajectory.update(angular_velocity_deg_s=[5, 0, 0], t_ref_s=-1e9)
    path = scenario(tmp_path, targets=[target])
    refused(["simulate", path, "--out", "o.ply"], capsys, "integrated over")


@pytest.mark.parametrize("value, fragment", [("99999999", "99,999,999 threads"),
                                             ("abc", "positive integer"),
                                             ("0", "positive integer")])
def test_thread_count_is_checked(tmp_path, capsys, monkeypatch, value, fragment):
    monkeypatch.setenv("LIDARSIM_THREADS", value)
    path = scenario(tmp_path)
    refused(["simulate", path, "--out", "o.ply"], capsys, "environment", "LIDARSIM_THREADS",
            fragment)
    assert not (tmp_path / "o.ply").exists()


def test_keyframe_rows_and_mesh_triangles_are_budgeted(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("LIDARSIM_MAX_KEYFRAME_ROWS", "3")
    (tmp_path / "kf.csv").write_text("t_s,x_m,y_m,z_m\n" + "".join(
        f"{t},30,0,0\n" for t in range(5)))
    target = dict(BASE["targets"][0], trajectory={"kind": "keyframes", "file": "kf.csv"})
    del target["pose"]
    refused(["simulate", scenario(tmp_path, targets=[target]), "--out", "o.ply"], capsys,
            "kf.csv", "LIDARSIM_MAX_KEYFRAME_ROWS")
    # a binary STL whose header announces 10^8 triangles is refused before trimesh reads it
    monkeypatch.setenv("LIDARSIM_MAX_DATA_BYTES", str(2 ** 40))
    stl = tmp_path / "big.stl"
    with open(stl, "wb") as out:
        out.write(b"x" * 80 + struct.pack("<I", 10 ** 8))
        out.truncate(84 + 50 * 10 ** 8)  # sparse: the size matches the header
    target = dict(BASE["targets"][0], mesh={"path": "big.stl"})
    refused(["simulate", scenario(tmp_path, targets=[target]), "--out", "o.ply"], capsys,
            "big.stl", "100,000,000 triangles", "LIDARSIM_MAX_MESH_TRIANGLES")


# ---- the bounded reader --------------------------------------------------------------------
def _special(path: Path, kind: str) -> None:
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "device":
        os.symlink("/dev/zero", path)
    elif kind == "loop":
        os.symlink(path.name, path)
    elif kind == "directory":
        path.mkdir()
    elif kind == "dangling":
        os.symlink("gone.yaml", path)


SPECIAL_WORDS = {"fifo": "named pipe (FIFO)", "device": "is a device",
                 "loop": "symbolic link loop", "directory": "is a directory",
                 "dangling": "dangling symbolic link"}


@pytest.mark.parametrize("kind", list(SPECIAL_WORDS))
def test_special_files_are_named_for_what_they_are(tmp_path, capsys, kind):
    """Scenarios, meshes and keyframe files that are FIFOs, devices, link loops, directories
    or dangling links: never read (a FIFO would block, /dev/zero never ends), never called
    'not found'."""
    _special(tmp_path / "scene.yaml", kind)
    line = refused(["simulate", "scene.yaml", "--out", "o.ply"], capsys, "scene.yaml",
                   SPECIAL_WORDS[kind])
    assert "not found" not in line
    (tmp_path / "scene.yaml").unlink() if kind != "directory" else (tmp_path / "scene.yaml").rmdir()
    _special(tmp_path / "m.stl", kind)
    target = dict(BASE["targets"][0], mesh={"path": "m.stl"})
    refused(["simulate", scenario(tmp_path, targets=[target]), "--out", "o.ply"], capsys,
            "targets.0.mesh.path", "m.stl", SPECIAL_WORDS[kind])
    _special(tmp_path / "kf.csv", kind)
    target = dict(BASE["targets"][0], trajectory={"kind": "keyframes", "file": "kf.csv"})
    del target["pose"]
    refused(["simulate", scenario(tmp_path, targets=[target]), "--out", "o.ply"], capsys,
            "kf.csv", SPECIAL_WORDS[kind])


def test_inputs_over_the_size_limit_are_refused(tmp_path, capsys, monkeypatch):
    path = scenario(tmp_path)
    monkeypatch.setenv("LIDARSIM_MAX_CONFIG_BYTES", "100")
    refused(["simulate", path, "--out", "o.ply"], capsys, "scene.yaml",
            f"{path.stat().st_size:,} bytes", "LIDARSIM_MAX_CONFIG_BYTES")


def test_the_reader_never_reads_past_its_limit(tmp_path):
    """A file that reports a small size but grows (or a /proc-like file) is cut at the
    limit + 1 byte and refused."""
    from lidarsim_core.base.config_io import read_bytes_file
    from lidarsim_core.base.errors import ConfigError

    path = tmp_path / "big.yaml"
    path.write_bytes(b"x" * 1000)
    assert len(read_bytes_file(path)) == 1000
    os.environ["LIDARSIM_MAX_CONFIG_BYTES"] = "999"
    try:
        with pytest.raises(ConfigError, match="over the limit of 999"):
            read_bytes_file(path)
    finally:
        del os.environ["LIDARSIM_MAX_CONFIG_BYTES"]


# ---- the error boundary --------------------------------------------------------------------
@pytest.mark.parametrize("error", [errno.ENOSPC, errno.EDQUOT, errno.EIO])
def test_write_errors_name_the_file_and_leave_nothing(tmp_path, capsys, monkeypatch, error):
    path = scenario(tmp_path)

    def failing_fsync(fd):
        raise OSError(error, os.strerror(error))

    monkeypatch.setattr(os, "fsync", failing_fsync)
    # the error is injected into Python's os calls: the compiled writer (io.filegroup, its
    # own real-error tests in test_filegroup.py) is left out
    monkeypatch.setattr("lidarsim_core.io.filegroup._write_compiled", lambda paths, data: 0)
    refused(["simulate", path, "--out", "o.ply"], capsys, "o.ply", "cannot write")
    assert _entries(tmp_path) == {"scene.yaml"}


def test_dataset_write_error_on_a_first_run_leaves_no_directory(tmp_path, capsys, monkeypatch):
    path = scenario(tmp_path)
    real = os.fsync
    calls = {"n": 0}

    def fsync(fd):
        calls["n"] += 1
        if calls["n"] > 3:  # after the scenario copy and the first files
            raise OSError(errno.ENOSPC, "No space left on device")
        real(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    # files a dataset run syncs together: a failing syncfs falls back to an fsync of each
    monkeypatch.setattr("lidarsim_core.base.atomic._syncfs", lambda directories: False)
    refused(["dataset", path, "--out", "ds", "-q"], capsys, "no space left on the device")
    assert _entries(tmp_path) == {"scene.yaml"}


def test_output_paths_are_checked_before_simulating(tmp_path, capsys, monkeypatch):
    from lidarsim_core import pipeline

    def never(*args, **kwargs):
        raise AssertionError("simulated before the output path was checked")

    monkeypatch.setattr(pipeline.Simulation, "__init__", never)
    path = scenario(tmp_path)
    refused(["simulate", path, "--out", "a" * 250 + ".ply"], capsys, "file name too long")
    os.symlink("self.ply", tmp_path / "self.ply")
    refused(["simulate", path, "--out", "self.ply"], capsys, "self.ply", "symbolic link",
            "--overwrite")
    (tmp_path / "target.ply").write_bytes(b"mine")
    os.symlink("target.ply", tmp_path / "link.ply")
    refused(["simulate", path, "--out", "link.ply"], capsys, "link.ply", "symbolic link")
    assert (tmp_path / "target.ply").read_bytes() == b"mine"
    refused(["pattern", "livox-mid70", "--duration", "0.01", "--out", "b" * 250 + ".npz"],
            capsys, "file name too long")
    real_statvfs = os.statvfs

    class ReadOnly:
        def __init__(self, result):
            self.f_flag = result.f_flag | os.ST_RDONLY

    monkeypatch.setattr(os, "statvfs", lambda p: ReadOnly(real_statvfs(p)))
    refused(["simulate", path, "--out", "o.ply"], capsys, "o.ply", "read-only file system")
    refused(["dataset", path, "--out", "ds"], capsys, "ds", "read-only file system")
    assert not (tmp_path / "ds").exists()


def test_far_or_overflowing_geometry_prints_no_warning(tmp_path, capsys):
    """Numerical warnings never reach the user: a target 1e308 m away is an empty frame with
    the usual note, a mesh with ±1e308 or infinite coordinates is refused for what it is."""
    target = dict(BASE["targets"][0], pose={"position_m": [1e308, 0, 0]})
    code, out, err = run(["simulate", scenario(tmp_path, targets=[target]), "--out", "o.ply"],
                         capsys)
    assert code == 0 and err == "" and "empty" in out
    (tmp_path / "big.obj").write_text("v 1e308 0 0\nv -1e308 1 0\nv 0 0 1e308\nf 1 2 3\n")
    target = dict(BASE["targets"][0], mesh={"path": "big.obj"})
    line = refused(["simulate", scenario(tmp_path, targets=[target]), "--out", "p.ply"],
                   capsys, "big.obj", "coordinates reach 1e+308 m")
    assert "degenerate" not in line
    (tmp_path / "inf.stl").write_text("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
                                      "vertex inf 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
                                      "endsolid x\n")
    target = dict(BASE["targets"][0], mesh={"path": "inf.stl"})
    refused(["simulate", scenario(tmp_path, targets=[target]), "--out", "p.ply"], capsys,
            "inf.stl", "non-finite")


@pytest.mark.parametrize("name, extra, fragments", [
    ("scene.yaml", {"[/x]": 1}, ["field '[/x]'"]),
    ("scene.yaml", {"extra_[b]key": 1}, ["field 'extra_[b]key'"]),
    ("[red]scene.yaml", {"bogus": 1}, ["[red]scene.yaml", "bogus"]),
])
def test_user_text_is_printed_verbatim(tmp_path, capsys, name, extra, fragments):
    path = scenario(tmp_path, name=name, **extra)
    refused(["simulate", path.name, "--out", "o.ply"], capsys, *fragments)


def test_markup_in_output_names_is_printed_verbatim(tmp_path, capsys):
    path = scenario(tmp_path)
    refused(["simulate", path, "--out", "x.[/i]"], capsys, "x.[/i]", "no exporter")
    code, out, _ = run(["simulate", path, "--out", "[red]o.ply"], capsys)
    assert code == 0 and "[red]o.ply" in out
    code, out, _ = run(["pattern", "livox-mid70", "--duration", "0.01", "--out", "[b]p.npz"],
                       capsys)
    assert code == 0 and "[b]p.npz" in out


@pytest.mark.parametrize("changes, field, fragment", [
    ({"scan": {"duration_s": "1e308"}}, "scan.duration_s", "rays"),
    ({"scan": {"duration_s": 0.01, "start_s": 1e308}}, "scan.start_s", "2^53"),
    ({"targets__0__pose": {"position_m": [30, 0, 0], "euler_deg": [1, 2, 3],
                           "euler_sequence": "xxz"}},
     "targets.0.pose.euler_sequence", "repeats an axis"),
    ({"seed": 2 ** 64 + 1}, "seed", "less than or equal to 18446744073709551615"),
])
def test_former_internal_errors_are_user_errors(tmp_path, capsys, changes, field, fragment):
    refused(["simulate", scenario(tmp_path, **changes), "--out", "o.ply"], capsys, field,
            fragment)


def test_fixed_attitude_euler_sequence_is_checked():
    from pydantic import ValidationError

    from lidarsim_core.trajectories.attitude import FixedAttitude

    with pytest.raises(ValidationError, match="repeats an axis"):
        FixedAttitude(euler_deg=(1, 2, 3), euler_sequence="yyx")


@pytest.mark.parametrize("argv, fragments", [
    (["pattern", "livox-mid70", "--duration", "0.01", "--start", "nan", "--out", "p.npz"],
     ["--start", "finite"]),
    (["pattern", "livox-mid70", "--duration", "inf", "--out", "p.npz"], ["--duration"]),
    (["coverage", "livox-mid70", "--time", "0.1", "--bin-deg", "inf"], ["--bin-deg"]),
    (["coverage", "livox-mid70", "--time", "0.1", "--cell-deg", "1e308"], ["--cell-deg", "<= 360"]),
    (["coverage", "livox-mid70", "--time", "0.1", "--start", "-1"], ["--start", ">= 0"]),
    (["simulate", "scene.yaml", "--out", "o.ply", "--seed", "-1"], ["--seed", "2^64 - 1"]),
    (["simulate", "scene.yaml", "--out", "o.ply", "--seed", str(2 ** 64 + 1)], ["--seed"]),
    (["simulate", "scene.yaml", "--out", "o.ply", "--frame", "abc"], ["--frame"]),
    (["simulate", "scene.yaml", "--out", "o.ply", "--format", "nope"], ["'format'"]),
    (["simulate", "scene.yaml", "--out", "o.ply", "--bogus"], ["--bogus"]),
    (["pattern", "livox-mid70", "--duration", "0.01", "--out", "p.npz", "--option",
      "b=[unclosed"], ["--option b", "malformed YAML"]),
    (["pattern", "livox-mid70", "--duration", "0.01", "--out", "p.npz", "--option",
      "b=!!python/object/apply:os.system [ls]"], ["--option b", "not allowed"]),
    (["demo", "--out", "d", "--duration", "nan"], ["--duration"]),
    (["demo", "--out", "d", "--seed", "-5"], ["--seed"]),
    (["report", "nowhere", "--cell-deg", "inf"], ["--cell-deg"]),
])
def test_options_are_validated_at_the_edge(tmp_path, capsys, argv, fragments):
    scenario(tmp_path)
    refused(argv, capsys, *fragments)
    assert _entries(tmp_path) == {"scene.yaml"}


def test_corrupt_frame_json_in_a_run_is_named(tmp_path, capsys):
    (tmp_path / "run").mkdir()
    path = scenario(tmp_path / "run", name="scenario.yaml")
    assert run(["simulate", path, "--out", tmp_path / "run" / "c.npz"], capsys)[0] == 0
    cloud = dict(np.load(tmp_path / "run" / "c.npz", allow_pickle=False))
    cloud["frame_json"] = np.array('{"frame": 0, broken')
    np.savez(tmp_path / "run" / "c.npz", **cloud)
    refused(["report", "run", "--no-3d"], capsys, "c.npz", "frame_json", "cannot read",
            "Expecting property name")  # the JSON parser's own words


# ---- dataset -------------------------------------------------------------------------------
def test_dataset_names_the_users_files_and_creates_nothing(tmp_path, capsys):
    (tmp_path / "junk.stl").write_bytes(b"\x00\x01junk" * 3)
    target = dict(BASE["targets"][0], mesh={"path": "junk.stl"})
    path = scenario(tmp_path, targets=[target])
    line = refused(["dataset", path, "--out", "ds"], capsys, str(tmp_path / "junk.stl"),
                   "targets.0.mesh.path")
    assert "inputs" not in line and "/ds/" not in line
    assert not (tmp_path / "ds").exists()


def test_dataset_file_overrides_are_blamed_on_the_dataset_file(tmp_path, capsys):
    scenario(tmp_path)
    (tmp_path / "set.yaml").write_text(yaml.safe_dump({"sequences": [
        {"scenario": "scene.yaml", "name": "a", "set": {"scan.duration_s": -1}}]}))
    refused(["dataset", "set.yaml", "--out", "ds"], capsys, "set.yaml",
            "sequences.0.set.scan.duration_s")
    (tmp_path / "seed.yaml").write_text(yaml.safe_dump({"sequences": [
        {"scenario": "scene.yaml", "seeds": [1, 2 ** 64]}]}))
    refused(["dataset", "seed.yaml", "--out", "ds"], capsys, "seed.yaml", "sequences.0.seeds.1")
    (tmp_path / "splits.yaml").write_text("sequences: [{scenario: scene.yaml}]\n"
                                          "splits: {train: .inf}\n")
    refused(["dataset", "splits.yaml", "--out", "ds"], capsys, "splits.yaml", "splits.train")
    (tmp_path / "nul.yaml").write_text('sequences: [{scenario: "\\0"}]\n')
    refused(["dataset", "nul.yaml", "--out", "ds"], capsys, "nul.yaml", "sequences.0.scenario",
            "NUL character")
    assert not (tmp_path / "ds").exists()


def test_failed_first_dataset_run_leaves_nothing(tmp_path, capsys, monkeypatch):
    """A failure after the directory was set up (here: a frame fails) removes the directory
    a first run created, and empties a directory that was empty."""
    from lidarsim_core.dataset import executors

    def fail(*args, **kwargs):
        raise OSError(errno.EIO, "Input/output error", str(tmp_path / "x"))

    monkeypatch.setattr(executors, "simulate_frame_job", fail)  # the serial loop's first step
    path = scenario(tmp_path)
    code, _, err = run(["dataset", path, "--out", "ds", "-q"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "ds").exists()
    (tmp_path / "empty").mkdir()
    code, _, err = run(["dataset", path, "--out", "empty", "-q"], capsys)
    assert code == 2
    assert list((tmp_path / "empty").iterdir()) == []


def test_refusing_a_foreign_directory_leaves_no_lock(tmp_path, capsys):
    path = scenario(tmp_path)
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("mine")
    refused(["dataset", path, "--out", "mine"], capsys, "mine", "holds no lidarsim dataset")
    assert _entries(tmp_path / "mine") == {"notes.txt"}


def test_every_limit_is_documented():
    from lidarsim_core.base.limits import LIMITS

    text = (Path(__file__).parents[1] / "docs" / "reliability.md").read_text()
    for spec in LIMITS.values():
        assert f"`{spec.env}`" in text, spec.env
