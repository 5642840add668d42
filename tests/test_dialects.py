"""The ``cloudcompare`` dialect of the PLY and CSV exporters: every column but x, y, z named
``scalar_<column>`` (and a ``//`` header line in CSV), read back by plyfile and pandas under
those names and by ``ls.read`` under the point-record names; the standard files are unchanged.
CloudCompare itself reads them in ``tests/test_tools.py``."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
import yaml
from helpers import CLI_SCENARIO

import lidarsim_core as ls
from lidarsim_core.io.dialects import column_name, record_names
from lidarsim_core.plugins.resolve import exporter_for
from lidarsim_core.plugins.shortcuts import write_cloud
from lidarsim_core.records.pointcloud import POINT_FIELDS

CC_NAMES = ["x", "y", "z", *("scalar_" + name for name in list(POINT_FIELDS)[3:])]


@pytest.fixture(scope="module")
def cloud() -> ls.PointCloud:
    scenario = ls.demo_scenario(duration_s=0.05, backend="numpy", detail="coarse", seed=3)
    return ls.Simulation(scenario).run_frame(0)


def _write(cloud, path, dialect):
    from lidarsim_core.io.points import CloudPoints
    from lidarsim_core.io.write import write_points_file

    write_points_file(CloudPoints(cloud), path, exporter_for(path, options={"dialect": dialect}))
    return path


def _same(a: ls.PointCloud, b: ls.PointCloud) -> None:
    assert a.frame == b.frame and list(a.columns) == list(b.columns)
    for name in a.columns:
        assert a[name].dtype == b[name].dtype, name
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_ply_cloudcompare_dialect_names_and_values(cloud, tmp_path):
    plyfile = pytest.importorskip("plyfile")
    standard = write_cloud(cloud, tmp_path / "s.ply")
    cc = _write(cloud, tmp_path / "c.ply", "cloudcompare")
    assert list(POINT_FIELDS)[:3] == ["x", "y", "z"]
    vertex = plyfile.PlyData.read(str(cc))["vertex"]
    assert [p.name for p in vertex.properties] == CC_NAMES
    plain = plyfile.PlyData.read(str(standard))["vertex"]
    assert [p.name for p in plain.properties] == list(POINT_FIELDS)
    # the same bytes but for the property names
    assert cc.read_bytes().split(b"end_header\n", 1)[1] == \
        standard.read_bytes().split(b"end_header\n", 1)[1]
    _same(ls.read(cc), ls.read(standard))
    _same(ls.read(cc), cloud)


def test_csv_cloudcompare_dialect_names_and_values(cloud, tmp_path):
    pandas = pytest.importorskip("pandas")
    standard = write_cloud(cloud, tmp_path / "s.csv")
    cc = _write(cloud, tmp_path / "c.csv", "cloudcompare")
    first = cc.read_text().split("\n", 1)[0]
    assert first == "//" + ",".join(CC_NAMES)
    assert standard.read_text().split("\n", 1)[0] == ",".join(POINT_FIELDS)
    assert cc.read_text().split("\n", 1)[1] == standard.read_text().split("\n", 1)[1]
    frame = pandas.read_csv(cc)
    assert list(frame.columns) == ["//x", *CC_NAMES[1:]]
    np.testing.assert_array_equal(frame["scalar_part"], cloud["part"])
    _same(ls.read(cc), cloud)


def test_record_names_map_only_known_columns_back():
    known = set(POINT_FIELDS)
    assert record_names(["x", "scalar_range", "scalar_mine", "scalar_"], known) == \
        ["x", "range", "scalar_mine", "scalar_"]
    # a file holding a column under both names keeps both as written
    assert record_names(["range", "scalar_range"], known) == ["range", "scalar_range"]
    assert column_name("x", "cloudcompare") == "x"
    assert column_name("part", "standard") == "part"


def _cli(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", "COLUMNS": "200"}
    return subprocess.run([sys.executable, "-m", "lidarsim_core", *args], env=env,
                          capture_output=True, text=True, timeout=300)


def test_cli_dialect_flag(tmp_path):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(yaml.safe_dump(CLI_SCENARIO))
    res = _cli("simulate", str(scenario), "-o", str(tmp_path / "c.ply"), "--dialect",
               "cloudcompare")
    assert res.returncode == 0, res.stderr
    assert b"property double scalar_range\n" in (tmp_path / "c.ply").read_bytes()[:4000]
    assert ls.read(tmp_path / "c.ply")["range"].size > 100
    res = _cli("simulate", str(scenario), "-o", str(tmp_path / "c.las"), "--dialect",
               "cloudcompare")
    assert res.returncode == 2 and "c.las" in res.stderr and "--dialect" in res.stderr
    assert not (tmp_path / "c.las").exists()
    res = _cli("simulate", str(scenario), "-o", str(tmp_path / "d.csv"), "--dialect", "qgis")
    assert res.returncode == 2 and "dialect" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "d.csv").exists()


def test_standard_dialect_is_left_out_of_recorded_options():
    """Dataset manifests record the exporter's options: the default dialect is not among
    them, so a dataset written before the option existed keeps its identity and resumes
    (tests/test_golden_outputs.py holds such a manifest)."""
    from lidarsim_core.io.csv_exporter import CsvOptions
    from lidarsim_core.io.ply import PlyOptions

    for options in (PlyOptions, CsvOptions):
        assert options().model_dump(mode="json") == {}
        chosen = options(dialect="cloudcompare")
        assert chosen.model_dump(mode="json") == {"dialect": "cloudcompare"}
        assert options.model_validate(chosen.model_dump(mode="json")) == chosen
        assert options.model_validate({}) == options()
