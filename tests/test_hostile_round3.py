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
