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
             "las": ["huge count", "VLR count flipped", "truncated", "metadata VLR not UTF-8",
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


# ---- internal errors that are user errors --------------------------------------------------
@pytest.mark.parametrize("detail", ["99", "-1", "true"])
def test_mesh_detail_out_of_range_is_one_line(tmp_path, capsys, detail):
    refused(["mesh", "envisat", "--option", f"detail={detail}", "--out", tmp_path / "e.obj"],
            capsys, "--option.detail", "integer 0..32")
    assert not list(tmp_path.glob("e.*"))


@pytest.mark.parametrize("variable, value, fragment", [
    ("LIDARSIM_MAX_CONFIG_BYTES", "1e300", "largest value lidarsim accepts"),
    ("LIDARSIM_MAX_THREADS", "100000", "largest value lidarsim accepts"),
    ("LIDARSIM_THREADS", "٣", "positive integer"),  # a Unicode digit int() would take
])
def test_environment_values_are_validated(tmp_path, capsys, monkeypatch, variable, value,
                                          fragment):
    monkeypatch.setenv(variable, value)
    if variable == "LIDARSIM_MAX_THREADS":
        monkeypatch.setenv("LIDARSIM_THREADS", "100000")
    refused(["simulate", scenario(tmp_path), "--out", "o.ply"], capsys, "environment",
            variable, fragment)
    assert not (tmp_path / "o.ply").exists()


def test_a_raised_config_limit_reads_only_the_files_size(tmp_path, monkeypatch):
    """``read_bytes_file`` asks for the file's size + 1 byte, never the bound: a 4 GiB bound
    under a 1 GiB address space still reads a small file."""
    import subprocess

    path = scenario(tmp_path)
    code = ("import resource\n"
            "resource.setrlimit(resource.RLIMIT_AS, (2**30, 2**30))\n"
            "from lidarsim_core.base.config_io import read_bytes_file\n"
            f"print(len(read_bytes_file({str(path)!r})))\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path),
           "LIDARSIM_MAX_CONFIG_BYTES": str(2 ** 33)}
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, timeout=120)
    assert res.stdout.strip() == str(path.stat().st_size), res.stderr


def _bag_scene(tmp_path: Path, **scan) -> Path:
    data = json.loads(json.dumps(BASE))
    data["scan"].update(scan)
    path = tmp_path / "bag.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_bag_start_time_beyond_ros_time_is_one_line(tmp_path, capsys):
    pytest.importorskip("rosbags")
    refused(["simulate", _bag_scene(tmp_path, start_s=3e9), "--out", tmp_path / "b.mcap"],
            capsys, "bag.yaml", "scan.start_s", "signed 32-bit")
    assert not list(tmp_path.glob("*b.mcap*"))


def test_bag_of_a_twelve_million_point_frame_is_refused_by_size(tmp_path, capsys):
    """A ROS message holds a whole frame: 12 M rays (MID-70, 120 s) are refused by the
    ``bag_frame_points`` bound before anything is simulated."""
    pytest.importorskip("rosbags")
    refused(["simulate", _bag_scene(tmp_path, duration_s=120.0), "--out", tmp_path / "b.mcap"],
            capsys, "bag.yaml", "12,000,000 rays", "LIDARSIM_MAX_BAG_FRAME_POINTS")
    assert not list(tmp_path.glob("*b.mcap*"))


def test_huge_divergence_and_retro_reflectivity_are_refused(tmp_path, capsys):
    data = json.loads(json.dumps(BASE))
    data["sensor"]["beam"] = {"divergence_deg": [1e308, 1e308]}
    path = tmp_path / "div.yaml"
    path.write_text(yaml.safe_dump(data))
    refused(["simulate", path, "--out", "o.ply"], capsys, "div.yaml",
            "sensor.beam.divergence_deg", "wider than 90")
    data = json.loads(json.dumps(BASE))
    name = data["targets"][0]["mesh"]["model"]
    data["targets"][0]["materials"] = {name: {"retro_reflectivity": 1e308}}
    path = tmp_path / "retro.yaml"
    path.write_text(yaml.safe_dump(data))
    refused(["simulate", path, "--out", "o.ply"], capsys, "retro.yaml", "retro_reflectivity")
    assert not (tmp_path / "o.ply").exists()


# ---- hangs: files a mesh references --------------------------------------------------------
TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def _mesh_scene(tmp_path: Path, mesh: Path) -> Path:
    data = json.loads(json.dumps(BASE))
    data["targets"][0]["mesh"] = {"path": str(mesh)}
    return scenario(tmp_path, "mesh_scene.yaml", targets=data["targets"])


@pytest.mark.skipif(sys.platform != "linux", reason="FIFOs")
@pytest.mark.parametrize("kind", ["mtllib fifo", "texture fifo", "mtllib outside",
                                  "mtllib absolute", "gltf buffer fifo", "gltf buffer url"])
def test_files_a_mesh_references_go_through_the_bounded_reader(tmp_path, kind):
    from lidarsim_core.base.errors import MeshError
    from lidarsim_core.scene.mesh import load_mesh_file

    folder = tmp_path / "model"
    folder.mkdir()
    if kind.startswith("gltf"):
        uri = "buffer.bin" if kind.endswith("fifo") else "http://example.invalid/b.bin"
        if kind.endswith("fifo"):
            os.mkfifo(folder / "buffer.bin")
        gltf = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
                "nodes": [{"mesh": 0, "name": "part"}],
                "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
                "buffers": [{"uri": uri, "byteLength": 36}],
                "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}],
                "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3,
                               "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}]}
        mesh = folder / "m.gltf"
        mesh.write_text(json.dumps(gltf))
        fragment = "buffer.bin" if kind.endswith("fifo") else "URI"
    else:
        mtl = {"mtllib fifo": "m.mtl", "texture fifo": "m.mtl",
               "mtllib outside": "../secret.mtl", "mtllib absolute": "/etc/hostname"}[kind]
        (tmp_path / "secret.mtl").write_text("newmtl x\nKd 1 0 0\n")
        if kind == "mtllib fifo":
            os.mkfifo(folder / "m.mtl")
        elif kind == "texture fifo":
            (folder / "m.mtl").write_text("newmtl red\nKd 1 0 0\nmap_Kd tex.png\n")
            os.mkfifo(folder / "tex.png")
        mesh = folder / "m.obj"
        mesh.write_text(f"mtllib {mtl}\nusemtl red\n{TRIANGLE}")
        fragment = {"mtllib fifo": "named pipe", "texture fifo": "named pipe",
                    "mtllib outside": "outside the mesh's folder",
                    "mtllib absolute": "outside the mesh's folder"}[kind]
    with pytest.raises(MeshError) as caught:  # a FIFO would block forever: the bound holds
        load_mesh_file(mesh)
    assert str(caught.value).startswith(str(mesh)) and fragment in str(caught.value)


def test_an_obj_without_its_mtl_still_loads(tmp_path):
    from lidarsim_core.scene.mesh import load_mesh_file

    (tmp_path / "m.obj").write_text(f"mtllib missing.mtl\n{TRIANGLE}")
    assert len(load_mesh_file(tmp_path / "m.obj").faces) == 1


# ---- inputs and devices never replaced -----------------------------------------------------
@pytest.mark.parametrize("command", ["simulate", "poses", "bag"])
def test_an_output_that_is_an_input_is_refused_even_with_overwrite(tmp_path, capsys, command):
    path = scenario(tmp_path)
    before = path.read_bytes()
    if command == "simulate":
        argv = ["simulate", path, "--out", path, "--format", "ply", "--overwrite"]
    elif command == "poses":
        argv = ["poses", path, "--out", tmp_path / "link.json", "--overwrite"]
        (tmp_path / "link.json").symlink_to(path)  # the input under another name
    else:
        pytest.importorskip("rosbags")
        argv = ["simulate", path, "--out", path, "--format", "mcap", "--overwrite"]
    refused(argv, capsys, "input of this command", "even with --overwrite")
    assert path.read_bytes() == before


def test_an_output_that_is_a_mesh_the_scenario_reads_is_refused(tmp_path, capsys):
    mesh = tmp_path / "m.ply"
    (tmp_path / "m.obj").write_text(TRIANGLE)
    from lidarsim_core.scene.mesh import load_mesh_file
    from lidarsim_core.io.meshfile import export_mesh

    export_mesh(load_mesh_file(tmp_path / "m.obj"), mesh)
    before = mesh.read_bytes()
    path = _mesh_scene(tmp_path, mesh)
    refused(["simulate", path, "--out", mesh, "--overwrite"], capsys, "input of this command")
    assert mesh.read_bytes() == before


@pytest.mark.skipif(not os.path.exists("/dev/null"), reason="no /dev/null")
def test_overwrite_replaces_regular_files_only(tmp_path, capsys):
    path = scenario(tmp_path)
    refused(["simulate", path, "--out", "/dev/null", "--format", "ply", "--overwrite"], capsys,
            "/dev/null", "is a device", "regular files only")
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    os.mkfifo(tmp_path / "pipe.ply")
    refused(["simulate", path, "--out", tmp_path / "pipe.ply", "--overwrite"], capsys,
            "named pipe")
    assert stat.S_ISFIFO(os.stat(tmp_path / "pipe.ply").st_mode)


# ---- terminal injection ---------------------------------------------------------------------
ESC = "\x1b[2J\x1b]0;owned\x07"


def test_the_error_line_escapes_control_characters(capsys):
    from lidarsim_core.cli.errors import fail_code

    assert fail_code(f"target 'evil{ESC}' is bad", 2) == 2
    err = capsys.readouterr().err
    assert "\x1b" not in err and "\x07" not in err
    assert "evil\\x1b[2J\\x1b]0;owned\\x07" in err


def test_part_names_from_a_mesh_file_are_escaped_in_listings(tmp_path, capsys):
    (tmp_path / "m.obj").write_text(f"o evil{ESC}\n{TRIANGLE}o other\nv 0 0 1\nv 1 0 1\n"
                                    "v 0 1 1\nf 4 5 6\n")
    path = _mesh_scene(tmp_path, tmp_path / "m.obj")
    code, out, err = run(["mesh", path, "--out", tmp_path / "out.ply"], capsys)
    assert code == 0, err
    assert "\x1b" not in out + err and "evil\\x1b[2J" in out


def test_control_characters_in_options_and_plugins_are_escaped(tmp_path, capsys, monkeypatch):
    line = refused(["mesh", "envisat", "--option", f"det{ESC}ail=3", "--out", "e.obj"],
                   capsys)
    assert "\\x1b" in line
    monkeypatch.setenv("LIDARSIM_THREADS", f"4{ESC}")
    line = refused(["simulate", scenario(tmp_path), "--out", "o.ply"], capsys)
    assert "\\x1b" in line


def test_terminal_safe_shows_every_control_as_an_escape():
    from lidarsim_core.base.terminal import terminal_safe

    assert terminal_safe("a\x1b[2Jb\x9b\u202e\r\n") == "a\\x1b[2Jb\\x9b\\u202e\\x0d\\x0a"
    assert terminal_safe("Envisat — ASAR é 日本") == "Envisat — ASAR é 日本"


def test_listings_escape_names(capsys):
    from lidarsim_core.cli.output import Column, plain_table, print_table

    assert "\x1b" not in plain_table([Column("name")], [[f"x{ESC}"]])
    print_table([Column("name")], [[f"x{ESC}"]])
    assert "\x1b" not in capsys.readouterr().out


# ---- partial files ---------------------------------------------------------------------------
def test_mesh_group_is_checked_before_any_file_is_written(tmp_path, capsys):
    (tmp_path / "e.mtl").write_text("mine")
    refused(["mesh", "envisat", "--option", "detail=coarse", "--out", tmp_path / "e.obj"],
            capsys, "e.mtl", "exists")
    assert not (tmp_path / "e.obj").exists()
    assert (tmp_path / "e.mtl").read_text() == "mine"


def test_mesh_on_a_full_disk_leaves_neither_file(tmp_path, capsys, monkeypatch):
    import errno

    real = os.fsync
    calls = []

    def full(fd):
        calls.append(fd)
        if len(calls) == 2:  # the second file (the OBJ after its MTL) hits a full disk
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(fd)

    monkeypatch.setattr(os, "fsync", full)
    refused(["mesh", "envisat", "--option", "detail=coarse", "--out", tmp_path / "e.obj"],
            capsys, "no space left")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_range_image_group_is_checked_before_the_cloud_is_written(tmp_path, capsys):
    data = json.loads(json.dumps(BASE))
    data["sensor"] = {"datasheet": "velodyne-vlp16", "pose": {"position_m": [0, 0, 0]}}
    data["scan"] = {"duration_s": 0.05}
    path = tmp_path / "spin.yaml"
    path.write_text(yaml.safe_dump(data))
    (tmp_path / "c.range.png").write_bytes(b"mine")
    refused(["simulate", path, "--out", tmp_path / "c.ply", "--range-image"], capsys,
            "c.range.png", "exists")
    assert not (tmp_path / "c.ply").exists()


def test_no_progress_bar_when_stderr_is_not_a_terminal(tmp_path, capsys):
    """A failing dataset run prints one line: no bar drawn around it in a pipe."""
    data = json.loads(json.dumps(BASE))
    data["scan"] = {"duration_s": 0.01, "frame_period_s": 0.1, "frames": 2}
    path = tmp_path / "seq.yaml"
    path.write_text(yaml.safe_dump(data))
    code, _, err = run(["dataset", path, "--out", tmp_path / "ds"], capsys)
    assert code == 0 and "━" not in err and "frames/s" not in err, err


# ---- memory: dataset reruns under a 4 GiB address space ------------------------------------
def _limited(args: list, cwd: Path) -> "subprocess.CompletedProcess[str]":
    """``lidarsim ARGS`` in a subprocess whose address space is capped at 4 GiB
    (``ulimit -v 4194304``, set with ``resource.setrlimit`` before it starts)."""
    import resource
    import subprocess

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (4 * 2 ** 30, 4 * 2 ** 30))

    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path),
           "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", "LIDARSIM_THREADS": "2"}
    code = "import sys; from lidarsim_core.cli import main; main(sys.argv[1:])"
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300, preexec_fn=cap)


@pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_AS and flock semantics")
def test_dataset_reruns_work_under_a_4_gib_address_space(tmp_path):
    import fcntl

    data = json.loads(json.dumps(BASE))
    data["scan"] = {"duration_s": 0.01, "frame_period_s": 0.1, "frames": 2}
    scene = tmp_path / "seq.yaml"
    scene.write_text(yaml.safe_dump(data))
    out = tmp_path / "ds"
    first = _limited(["dataset", scene, "--out", out], tmp_path)
    assert first.returncode == 0, first.stderr
    # resume: every frame already done, the manifest read back under the cap
    again = _limited(["dataset", scene, "--out", out], tmp_path)
    assert again.returncode == 0, again.stderr
    assert "2 already done" in again.stdout and "MemoryError" not in again.stderr
    # concurrent-run refusal: another process holds the lock
    with open(out / ".lidarsim-dataset.lock", "a+") as held:
        fcntl.flock(held.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        busy = _limited(["dataset", scene, "--out", out], tmp_path)
    assert busy.returncode == 2 and "another 'lidarsim dataset' run" in busy.stderr, \
        busy.stderr
    assert len(busy.stderr.strip().splitlines()) == 1
    # corrupt-manifest refusal
    (out / "manifest.json").write_text('{"format": ')
    corrupt = _limited(["dataset", scene, "--out", out], tmp_path)
    assert corrupt.returncode == 2, corrupt.stderr
    assert "manifest.json" in corrupt.stderr and "MemoryError" not in corrupt.stderr
    assert len(corrupt.stderr.strip().splitlines()) == 1


@pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_AS and sparse files")
def test_a_sparse_stl_of_40_million_triangles_is_refused_by_memory(tmp_path):
    """The file really is 2 GB long (sparse), so its header count matches its length: it is
    refused because loading it needs ~520 bytes a triangle, more than a 4 GiB address space
    leaves, before trimesh allocates anything."""
    import subprocess

    path = tmp_path / "sparse.stl"
    with open(path, "wb") as stream:
        stream.write(b"\0" * 80 + (40_000_000).to_bytes(4, "little"))
        stream.truncate(84 + 50 * 40_000_000)
    code = ("import resource\n"
            "resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, 4 * 2**30))\n"
            "from lidarsim_core.base.errors import MeshError\n"
            "from lidarsim_core.scene.mesh import load_mesh_file\n"
            f"try:\n    load_mesh_file({str(path)!r})\n"
            "except MeshError as exc:\n    print(exc)\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, timeout=120)
    assert "40,000,000 triangles needs about" in res.stdout, res.stdout + res.stderr
    assert res.stdout.startswith(str(path))


def test_a_bag_on_a_full_disk_names_the_bag_and_leaves_nothing(tmp_path, capsys, monkeypatch):
    pytest.importorskip("rosbags")
    import errno

    from rosbags.rosbag2 import Writer

    def full(self, *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")  # no file name, as in a writer

    monkeypatch.setattr(Writer, "write", full)
    refused(["simulate", _bag_scene(tmp_path), "--out", tmp_path / "b.mcap"], capsys,
            "b.mcap", "no space left")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag.yaml"]


def test_an_npy_pattern_table_declaring_2_36_rows_is_refused_by_its_length(tmp_path):
    import io

    from lidarsim_core.base.errors import PatternFileError
    from lidarsim_core.patterns.table_io import read_pattern_table

    buffer = io.BytesIO()
    np.lib.format.write_array(buffer, np.zeros((5, 3)))
    path = tmp_path / "table.npy"
    path.write_bytes(buffer.getvalue().replace(b"(5, 3)", b"(68719476736, 3)"))
    with pytest.raises(PatternFileError, match="1,649,267,441,664 bytes"):
        read_pattern_table(path)


@pytest.mark.parametrize("values, dtype, fragment", [
    ([1.0, float("nan")], "i8", "not finite"), ([0.5], "i4", "fraction"),
    ([300], "u1", "do not fit"), ([2.0 ** 70], "i8", "do not fit")])
def test_integer_columns_never_wrap_or_take_nan(values, dtype, fragment):
    """A float column read into an integer record column (a PCD field whose TYPE says F,
    PLY's double ray_index) is refused when a value does not fit, never cast to garbage
    with a RuntimeWarning (found by the reader fuzzer)."""
    from lidarsim_core.io.columns import cast_column

    with pytest.raises(ConfigError, match=fragment):
        cast_column(np.array(values), dtype, source="c.pcd", field="ring")
    assert cast_column(np.array([1.0, 2.0]), "i2", source="c", field="f").dtype == np.int16
