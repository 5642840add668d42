"""lidarsim's files in the command-line tools point-cloud people open first (marked ``tools``):
CloudCompare in silent command-line mode under ``xvfb-run`` (Debian's ``cloudcompare``) and
PCL's converters and error tool (``pcl-tools``). ``.ci/run`` installs them and runs
``pytest -m tools`` with ``LIDARSIM_REQUIRE_TOOLS=1``, which turns a missing tool into a
failure; elsewhere these tests skip when the tools are absent.

CloudCompare's view of a file is read from its own ASCII export (``-C_EXPORT_FMT ASC -SEP
SEMICOLON -ADD_HEADER``): the header names x, y, z and every scalar field, colour and normal it
loaded, in its naming (``_`` shown as a space). What these tests measure is the table in
docs/outputs.md ("Which tools read what").
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import lidarsim_core as ls
from lidarsim_core.io.dialects import cloudcompare_label
from lidarsim_core.io.pcd import read_pcd_columns
from lidarsim_core.io.points import CloudPoints
from lidarsim_core.io.write import write_points_file
from lidarsim_core.plugins.resolve import exporter_for
from lidarsim_core.records.pointcloud import POINT_FIELDS
from lidarsim_core.scenario.load import load_scenario

pytestmark = pytest.mark.tools

EXAMPLE = Path(__file__).parents[1] / "examples" / "envisat_mid70.yaml"
#: Words of CloudCompare's and PCL's logs that report dropped, guessed or broken data.
WARNING_WORDS = ("warning", "error", "corrupted", "ignored", "failed", "can't", "unhandled")
COLUMNS = list(POINT_FIELDS)


def need(*tools: str) -> None:
    """Skip (or fail, with ``LIDARSIM_REQUIRE_TOOLS=1``) unless every tool is on the PATH."""
    missing = [tool for tool in tools if shutil.which(tool) is None]
    if missing:
        message = (f"{', '.join(missing)} not installed (Debian: apt-get install cloudcompare "
                   "pcl-tools xvfb)")
        if os.environ.get("LIDARSIM_REQUIRE_TOOLS") == "1":
            pytest.fail(message + "; LIDARSIM_REQUIRE_TOOLS=1 requires them")
        pytest.skip(message)


@pytest.fixture(scope="module")
def cloud() -> ls.PointCloud:
    """The README's example scene (Envisat face-on, bright glints), 0.2 s on the NumPy
    backend: every column of the point record, ~800 points."""
    scenario = load_scenario(EXAMPLE).with_updates(scan={"duration_s": 0.2},
                                                   backend={"name": "numpy"})
    out = ls.Simulation(scenario).run_frame(0)
    assert len(out) > 300 and list(out.columns) == COLUMNS
    return out


@pytest.fixture(scope="module")
def files(cloud, tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("tools")
    out = {}
    for key, name, options in (("ply", "c.ply", None), ("pcd", "c.pcd", None),
                               ("csv", "c.csv", None),
                               ("ply-cc", "cc.ply", {"dialect": "cloudcompare"}),
                               ("csv-cc", "cc.csv", {"dialect": "cloudcompare"})):
        path = root / name
        write_points_file(CloudPoints(cloud), path, exporter_for(path, options=options))
        out[key] = path
    return out


def _quiet(log: str) -> list[str]:
    """The lines of ``log`` that warn (PCL's result line "RMSE Error: ..." is no warning)."""
    return [line for line in log.splitlines() if "RMSE Error:" not in line
            and any(word in line.lower() for word in WARNING_WORDS)]


# ---- CloudCompare -------------------------------------------------------------------------
def cloudcompare(path: Path, tmp_path: Path) -> tuple[list[str], np.ndarray, str]:
    """(column names, values, log) of ``path`` as CloudCompare loads it, from its ASCII export."""
    need("CloudCompare", "xvfb-run")
    out = tmp_path / f"{path.name}.cc.txt"
    proc = subprocess.run(["xvfb-run", "-a", "CloudCompare", "-SILENT", "-O", str(path),
                           "-C_EXPORT_FMT", "ASC", "-SEP", "SEMICOLON", "-ADD_HEADER",
                           "-SAVE_CLOUDS", "FILE", str(out)],
                          capture_output=True, text=True, timeout=300)
    log = (proc.stdout + proc.stderr).replace(str(path.parent), "<dir>").replace(
        str(tmp_path), "<dir>")
    assert out.exists(), f"CloudCompare wrote nothing for {path.name}: {log[-2000:]}"
    header = out.read_text().split("\n", 1)[0]
    assert header.startswith("//")
    return header[2:].split(";"), np.loadtxt(out, delimiter=";", skiprows=1, ndmin=2), log


def _loaded_as_cloudcompare_says(cloud, names, values, labels):
    """x, y, z within float32 rounding (CloudCompare's coordinates are float32) and each
    scalar field equal to the column rounded to float32 (its scalar type)."""
    assert values.shape == (len(cloud), len(names))
    for i, axis in enumerate("xyz"):
        exact = cloud[axis]
        assert np.all(np.abs(values[:, i] - exact) <= np.spacing(np.abs(exact).astype(
            np.float32)).astype(np.float64) / 2 + 1e-11), axis
    for column, label in labels.items():
        got = values[:, names.index(label)]
        np.testing.assert_allclose(got, cloud[column].astype(np.float32).astype(np.float64),
                                   rtol=0, atol=1e-9, err_msg=column)


def test_cloudcompare_loads_every_column_of_the_cloudcompare_ply(cloud, files, tmp_path):
    names, values, log = cloudcompare(files["ply-cc"], tmp_path)
    labels = {c: cloudcompare_label(c) for c in COLUMNS[3:]}
    assert names == ["X", "Y", "Z", *labels.values()]  # 21 columns: x, y, z + 18 fields
    assert len(names) == len(COLUMNS) == 21
    _loaded_as_cloudcompare_says(cloud, names, values, labels)
    assert not _quiet(log), _quiet(log)


def test_cloudcompare_keeps_four_columns_of_the_standard_ply(cloud, files, tmp_path):
    """Why the dialect exists: CloudCompare's PLY filter loads a property as a scalar field
    only when its name holds 'scal' or 'intensity'; the rest is dropped without a word."""
    names, values, log = cloudcompare(files["ply"], tmp_path)
    assert names == ["X", "Y", "Z", "intensity"]
    _loaded_as_cloudcompare_says(cloud, names, values, {"intensity": "intensity"})


def test_cloudcompare_loads_every_column_of_the_cloudcompare_csv(cloud, files, tmp_path):
    names, values, log = cloudcompare(files["csv-cc"], tmp_path)
    labels = {c: cloudcompare_label("scalar_" + c) for c in COLUMNS[3:]}
    assert names == ["X", "Y", "Z", *labels.values()]  # no R, G, B, Nx, Ny, Nz
    _loaded_as_cloudcompare_says(cloud, names, values, labels)
    assert not _quiet(log), _quiet(log)


def test_cloudcompare_guesses_the_standard_csv(files, tmp_path):
    """Why the dialect exists: without a '//' header line CloudCompare reads no name and
    guesses columns from their values (colours, normals)."""
    names, _, log = cloudcompare(files["csv"], tmp_path)
    assert "Line 1 is corrupted" in log
    assert not set(names) & {cloudcompare_label(c) for c in COLUMNS[3:]}
    assert {"R", "G", "B"} <= set(names) or {"Nx", "Ny", "Nz"} <= set(names)


# ---- PCL ----------------------------------------------------------------------------------
def pcl(tool: str, *args: Path) -> str:
    """Run a PCL tool; its output, after checking it exited 0 and warned of nothing."""
    need(tool)
    proc = subprocess.run([tool, *map(str, args)], capture_output=True, text=True,
                          timeout=300)
    log = proc.stdout + proc.stderr
    for arg in args:  # a test's directory name is no warning
        log = log.replace(str(arg.parent), "<dir>")
    assert proc.returncode == 0, log
    assert not _quiet(log), _quiet(log)
    return log


def _rmse(log: str) -> float:
    lines = [line for line in log.splitlines() if "RMSE Error:" in line]
    assert len(lines) == 1, log
    return float(lines[0].split(":")[1])


def test_pcl_converts_the_pcd_and_the_ply_bit_for_bit(cloud, files, tmp_path):
    plyfile = pytest.importorskip("plyfile")
    pcl("pcl_pcd2ply", files["pcd"], tmp_path / "p.ply")
    vertex = plyfile.PlyData.read(str(tmp_path / "p.ply"))["vertex"]
    pcd_name = {"part": "label", "channel": "ring"}
    assert [p.name for p in vertex.properties] == [pcd_name.get(c, c) for c in COLUMNS]
    for column in COLUMNS:
        expected = cloud[column].astype(np.float32) if column in "xyz" else cloud[column]
        np.testing.assert_array_equal(vertex[pcd_name.get(column, column)], expected,
                                      err_msg=column)
    for key in ("ply", "ply-cc"):
        out = tmp_path / f"{key}.pcd"
        pcl("pcl_ply2pcd", files[key], out)
        columns, _ = read_pcd_columns(out)
        prefix = "scalar_" if key == "ply-cc" else ""
        for column in COLUMNS:
            name = column if column in "xyz" else prefix + column
            np.testing.assert_array_equal(columns[name], cloud[column], err_msg=column)


def test_pcl_cloud_error_is_zero_against_itself(files, tmp_path):
    log = pcl("pcl_compute_cloud_error", files["pcd"], files["pcd"], tmp_path / "e.pcd")
    assert _rmse(log) == 0.0
    # PCD → PLY → PCD through PCL's converters: the same float32 points
    pcl("pcl_pcd2ply", files["pcd"], tmp_path / "p.ply")
    pcl("pcl_ply2pcd", tmp_path / "p.ply", tmp_path / "p.pcd")
    log = pcl("pcl_compute_cloud_error", files["pcd"], tmp_path / "p.pcd", tmp_path / "e2.pcd")
    assert _rmse(log) == 0.0


def test_pcl_typed_tools_need_the_pcd_float32_coordinates(files, tmp_path):
    """A PLY converted by pcl_ply2pcd keeps float64 x, y, z, which PCL's PointXYZ tools do not
    match ("Failed to find match for field 'x'"): use the PCD exporter for them."""
    pcl("pcl_ply2pcd", files["ply"], tmp_path / "d.pcd")
    need("pcl_compute_cloud_error")
    proc = subprocess.run(["pcl_compute_cloud_error", str(tmp_path / "d.pcd"),
                           str(tmp_path / "d.pcd"), str(tmp_path / "e.pcd")],
                          capture_output=True, text=True, timeout=300)
    assert "Failed to find match for field 'x'" in proc.stdout + proc.stderr


@pytest.mark.parametrize("suffix", [".las", ".pcd"])
def test_cloudcompare_of_debian_opens_no_las_or_pcd(files, tmp_path, suffix):
    """Debian's CloudCompare 2.11.3 is built without its LAS filter and its PCL plugin: it
    refuses .las and .pcd by extension (docs/outputs.md sends those users to PLY)."""
    need("CloudCompare", "xvfb-run")
    path = tmp_path / f"c{suffix}"
    if suffix == ".pcd":
        path.write_bytes(files["pcd"].read_bytes())
    else:
        pytest.importorskip("laspy")
        write_points_file(CloudPoints(ls.read(files["pcd"])), path, exporter_for(path))
    proc = subprocess.run(["xvfb-run", "-a", "CloudCompare", "-SILENT", "-O", str(path)],
                          capture_output=True, text=True, timeout=300)
    assert f"unhandled file extension '{suffix[1:]}'" in proc.stdout + proc.stderr
