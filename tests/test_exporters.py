"""Exporters: every file read back by an independent reader gives the same coordinates and
fields; streaming in chunks gives the same bytes as writing a whole cloud; metadata in the
file where the format has room and always in the sidecar."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import struct
import subprocess
import sys

import numpy as np
import pytest

from lidarsim_core.base.errors import OutputError
from lidarsim_core.io.points import CloudPoints, PointSpool
from lidarsim_core.io.sidecar import read_sidecar, sidecar_path
from lidarsim_core.io.write import write_points_file
from lidarsim_core.plugins.resolve import exporter_for
from lidarsim_core.plugins.shortcuts import write_cloud
from lidarsim_core.records.pointcloud import POINT_FIELDS, PointCloud

FORMATS = ["ply", "npz", "pcd", "las", "laz", "csv"]


@pytest.fixture(scope="module")
def cloud() -> PointCloud:
    """A noisy Envisat scan: several parts, every column populated."""
    from lidarsim_core.pipeline import Simulation
    from lidarsim_core.scenario import demo_scenario

    scenario = demo_scenario(duration_s=0.05, backend="numpy", detail="coarse", seed=3)
    result = Simulation(scenario).run_frame(0)
    assert len(result) > 300 and len(set(result["part"].tolist())) >= 2
    return result


def _needs(fmt: str) -> None:
    if fmt in ("las", "laz"):
        pytest.importorskip("laspy")
    if fmt == "laz":
        pytest.importorskip("lazrs")


def _with_column(cloud: PointCloud, name: str, values: np.ndarray) -> PointCloud:
    return PointCloud({**cloud.columns, name: values}, cloud.frame)


# ---- independent readers -------------------------------------------------------------------
def test_ply_read_by_plyfile_has_every_field_and_metadata(cloud, tmp_path):
    plyfile = pytest.importorskip("plyfile")
    path = write_cloud(cloud, tmp_path / "c.ply")
    ply = plyfile.PlyData.read(str(path))
    vertex = ply["vertex"]
    assert vertex.count == len(cloud)
    for name in POINT_FIELDS:
        np.testing.assert_array_equal(vertex[name], cloud[name], err_msg=name)
    meta = "".join(c.split(" ", 1)[1] for c in ply.comments if c.startswith("lidarsim-frame "))
    assert json.loads(meta) == cloud.frame.to_dict()


def test_npz_read_by_numpy(cloud, tmp_path):
    path = write_cloud(cloud, tmp_path / "c.npz")
    with np.load(path, allow_pickle=False) as data:
        for name in POINT_FIELDS:
            assert data[name].dtype == np.dtype(POINT_FIELDS[name])
            np.testing.assert_array_equal(data[name], cloud[name], err_msg=name)
        assert json.loads(str(data["frame_json"])) == cloud.frame.to_dict()
        assert list(data["part_names"]) == cloud.frame.part_names


def test_las_and_laz_read_by_laspy(cloud, tmp_path):
    laspy = pytest.importorskip("laspy")
    pytest.importorskip("lazrs")
    for suffix in (".las", ".laz"):
        path = write_cloud(cloud, tmp_path / f"c{suffix}")
        las = laspy.read(str(path))
        header = las.header
        assert (header.version.major, header.version.minor) == (1, 4)
        assert header.point_format.id == 6 and header.point_count == len(cloud)
        scale = 1e-4
        np.testing.assert_allclose(header.scales, scale)
        for axis in "xyz":  # integers of 0.1 mm, rounded to nearest
            err = np.abs(np.asarray(las[axis]) - cloud[axis])
            assert err.max() <= scale / 2 + 1e-9, axis
        np.testing.assert_array_equal(las.gps_time, cloud["timestamp"])
        np.testing.assert_array_equal(las.return_number, cloud["return_number"])
        np.testing.assert_array_equal(las.number_of_returns, cloud["number_of_returns"])
        np.testing.assert_array_equal(las.classification, cloud["part"] + 64)
        # intensity (apparent reflectivity, 0..1 for diffuse surfaces) scaled to 0..65535
        np.testing.assert_array_equal(las.intensity, np.round(np.clip(
            cloud["intensity"].astype(np.float64), 0, 1) * 65535))
        extras = set(las.point_format.extra_dimension_names)
        expected = set(POINT_FIELDS) - {"x", "y", "z", "timestamp", "return_number",
                                        "number_of_returns", "part", "intensity"}
        assert extras == expected | {"reflectivity"}  # + the exact float intensity
        for name in expected:
            assert las[name].dtype == np.dtype(POINT_FIELDS[name]), name
            np.testing.assert_array_equal(las[name], cloud[name], err_msg=name)
        np.testing.assert_array_equal(las["reflectivity"], cloud["intensity"])
        vlrs = {(v.user_id, v.record_id): v for v in header.vlrs}
        frame = json.loads(bytes(vlrs[("lidarsim", 1)].record_data).decode())
        assert frame == cloud.frame.to_dict()
        if suffix == ".las":
            raw = _raw_vlrs(path)[("LASF_Spec", 0)]  # 16-byte (class, name[15]) records
            lookup = {c: n.rstrip(b"\0").decode() for c, n in struct.iter_unpack("<B15s", raw)}
            assert lookup == {64 + i: p.rsplit("/", 1)[-1][:15]
                              for i, p in enumerate(cloud.frame.part_names)}
        names = bytes(vlrs[("lidarsim", 2)].record_data).decode().split("\n")
        assert names == cloud.frame.part_names  # exact, whatever the lookup's 15 characters
        assert header.creation_date is None  # day/year 0: reruns give the same bytes


def _raw_vlrs(path):
    """VLR payloads read straight from the LAS 1.4 header layout (ASPRS spec, not laspy)."""
    raw = path.read_bytes()
    header_size, = struct.unpack_from("<H", raw, 94)
    count, = struct.unpack_from("<I", raw, 100)
    out, pos = {}, header_size
    for _ in range(count):
        _, user, record, length = struct.unpack_from("<H16sHH", raw, pos)
        out[(user.rstrip(b"\0").decode(), record)] = raw[pos + 54:pos + 54 + length]
        pos += 54 + length
    return out


def _parse_pcd(path):
    """A minimal PCD v0.7 reader written from the format description (not lidarsim's)."""
    raw = path.read_bytes()
    header, pos, comments = {}, 0, []
    order = []
    while True:
        end = raw.index(b"\n", pos)
        line = raw[pos:end].decode("ascii" if not raw[pos:end].startswith(b"#") else "utf-8")
        pos = end + 1
        if line.startswith("#"):
            comments.append(line)
            continue
        key, *values = line.split(" ")
        header[key] = values
        order.append(key)
        if key == "DATA":
            break
    return header, order, comments, raw[pos:]


def test_pcd_header_follows_pcl_and_open3d_and_data_reads_back(cloud, tmp_path):
    path = write_cloud(cloud, tmp_path / "c.pcd")
    header, order, comments, body = _parse_pcd(path)
    # the entry order PCL writes and Open3D's reader expects
    assert order == ["VERSION", "FIELDS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT",
                     "VIEWPOINT", "POINTS", "DATA"]
    assert header["VERSION"] == ["0.7"] and header["DATA"] == ["binary"]
    fields = header["FIELDS"]
    assert len(fields) == len(header["SIZE"]) == len(header["TYPE"]) == len(header["COUNT"])
    n = int(header["POINTS"][0])
    assert n == len(cloud) == int(header["WIDTH"][0]) * int(header["HEIGHT"][0])
    assert [float(v) for v in header["VIEWPOINT"]] == [0, 0, 0, 1, 0, 0, 0]
    types = dict(zip(fields, zip(header["TYPE"], header["SIZE"])))
    assert types["x"] == types["y"] == types["z"] == ("F", "4")  # pcl::PointXYZ
    assert types["label"] == ("U", "4") and types["ring"] == ("U", "2")
    kinds = {"F": "f", "I": "i", "U": "u"}
    dtype = np.dtype([(f, f"<{kinds[t]}{s}") for f, (t, s) in types.items()])
    assert len(body) == n * dtype.itemsize  # nothing missing, nothing extra
    data = np.frombuffer(body, dtype=dtype)
    for axis in "xyz":
        np.testing.assert_array_equal(data[axis], cloud[axis].astype(np.float32))
    np.testing.assert_array_equal(data["label"], cloud["part"])
    np.testing.assert_array_equal(data["ring"], cloud["channel"])
    for name in set(POINT_FIELDS) - {"x", "y", "z", "part", "channel"}:
        np.testing.assert_array_equal(data[name], cloud[name], err_msg=name)
    meta = "".join(c[len("# lidarsim-frame "):] for c in comments
                   if c.startswith("# lidarsim-frame "))
    assert json.loads(meta) == cloud.frame.to_dict()
    assert max(len(c) for c in comments) < 200  # Open3D reads header lines in 1 KB pieces


def test_pcd_float64_option_keeps_full_precision(cloud, tmp_path):
    from lidarsim_core.io.pcd import PcdExporter, read_pcd

    exporter = PcdExporter.from_config({"xyz_dtype": "float64"})
    write_points_file(CloudPoints(cloud), tmp_path / "c.pcd", exporter=exporter)
    back = read_pcd(tmp_path / "c.pcd")
    for name in POINT_FIELDS:
        np.testing.assert_array_equal(back[name], cloud[name], err_msg=name)
    assert back.frame == cloud.frame


def test_csv_read_by_the_csv_module_gives_exact_values(cloud, tmp_path):
    import csv

    path = write_cloud(cloud, tmp_path / "c.csv")
    with open(path, newline="") as stream:
        rows = list(csv.reader(stream))
    assert rows[0] == list(POINT_FIELDS)
    assert len(rows) == len(cloud) + 1
    columns = list(zip(*rows[1:]))
    for i, name in enumerate(POINT_FIELDS):
        values = np.array([float(v) for v in columns[i]])
        np.testing.assert_array_equal(values, cloud[name].astype(np.float64), err_msg=name)


@pytest.mark.parametrize("fmt", FORMATS)
def test_sidecar_holds_metadata_and_checksum(cloud, tmp_path, fmt):
    _needs(fmt)
    path = write_cloud(cloud, tmp_path / f"c.{fmt}")
    side = read_sidecar(path)
    assert sidecar_path(path).name == f"c.{fmt}.json"
    assert side["file"] == path.name and side["exporter"] == fmt
    assert side["points"] == len(cloud) and side["bytes"] == path.stat().st_size
    assert side["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert side["frame"] == cloud.frame.to_dict()
    assert side["columns"] == [[k, np.dtype(v).name] for k, v in POINT_FIELDS.items()]


# ---- streaming -----------------------------------------------------------------------------
@pytest.mark.parametrize("fmt", FORMATS)
def test_streamed_through_a_spilled_spool_gives_the_same_bytes(cloud, tmp_path, fmt):
    _needs(fmt)
    whole = write_cloud(cloud, tmp_path / f"whole.{fmt}", sidecar=False)
    # uneven chunks, spilled to disk after the first: the bytes must not depend on chunking
    with PointSpool(cloud.frame, memory_limit=4096) as spool:
        for lo, hi in ((0, 7), (7, 200), (200, len(cloud))):
            spool.append({k: v[lo:hi] for k, v in cloud.columns.items()})
        assert spool.spilled and len(spool) == len(cloud)
        streamed = tmp_path / f"streamed.{fmt}"
        write_points_file(spool, streamed, exporter_for(streamed), sidecar=False)
    assert streamed.read_bytes() == whole.read_bytes()


def test_spool_rechunks_exactly_and_keeps_memory_bounded(cloud):
    with PointSpool(cloud.frame, memory_limit=10_000) as spool:
        for _ in range(20):
            spool.append(cloud.columns)
        assert spool.spilled and spool._parts == []  # nothing of it held in memory
        sizes = [len(c["x"]) for c in spool.iter_chunks(["x"], size=1000)]
        assert sizes[:-1] == [1000] * (len(sizes) - 1) and sum(sizes) == 20 * len(cloud)
        x = np.concatenate([c["x"] for c in spool.iter_chunks(["x", "part"], size=333)])
    np.testing.assert_array_equal(x, np.tile(cloud["x"], 20))


# ---- choosing, extending, failing ---------------------------------------------------------
def test_exporters_chosen_by_suffix_or_name(tmp_path):
    names = {s: exporter_for(f"a{s}").name for s in (".ply", ".npz", ".pcd", ".las", ".laz",
                                                     ".csv", ".LAZ")}
    assert names == {".ply": "ply", ".npz": "npz", ".pcd": "pcd", ".las": "las",
                     ".laz": "laz", ".csv": "csv", ".LAZ": "laz"}
    assert exporter_for("a.bin", "pcd").name == "pcd"
    with pytest.raises(OutputError, match=r"no exporter for suffix '\.xyz'.*\.las.*\.laz.*\.pcd"):
        exporter_for("a.xyz")


def test_new_columns_flow_through_exporters(cloud, tmp_path):
    laspy = pytest.importorskip("laspy")
    rng = np.random.default_rng(0)
    intensity = rng.uniform(0, 1, len(cloud)).astype(np.float32)
    extended = _with_column(cloud, "intensity", intensity)
    write_cloud(extended, tmp_path / "c.las")
    las = laspy.read(str(tmp_path / "c.las"))
    np.testing.assert_array_equal(las.intensity, np.round(intensity.astype(np.float64) * 65535))
    write_cloud(extended, tmp_path / "c.pcd")
    header, _, _, body = _parse_pcd(tmp_path / "c.pcd")
    assert "intensity" in header["FIELDS"]
    write_cloud(extended, tmp_path / "c.npz")
    np.testing.assert_array_equal(np.load(tmp_path / "c.npz")["intensity"], intensity)
    write_cloud(extended, tmp_path / "c.csv")
    assert "intensity" in (tmp_path / "c.csv").read_text().split("\n")[0].split(",")


def test_las_with_more_parts_than_classes_keeps_part_as_extra_bytes(cloud, tmp_path):
    laspy = pytest.importorskip("laspy")
    names = [f"t/p{i}" for i in range(200)]
    frame = dataclasses.replace(cloud.frame, part_names=names)
    many = PointCloud(dict(cloud.columns), frame)
    write_cloud(many, tmp_path / "c.las")
    las = laspy.read(str(tmp_path / "c.las"))
    np.testing.assert_array_equal(las.classification, 1)
    np.testing.assert_array_equal(las["part"], cloud["part"])


def test_values_that_do_not_fit_fail_and_leave_nothing(cloud, tmp_path):
    big = cloud["ray_index"] + 2 ** 33
    with pytest.raises(OutputError, match="ray_index.*PCD"):
        write_cloud(_with_column(cloud, "ray_index", big), tmp_path / "c.pcd")
    assert list(tmp_path.iterdir()) == []


def test_exporter_without_streaming_still_works(cloud, tmp_path):
    from lidarsim_core.io.base import Exporter

    class Lines(Exporter):
        name = "lines"
        suffixes = (".txt",)

        def write(self, c, stream):
            stream.write(f"{len(c)}\n".encode())

    with PointSpool(cloud.frame) as spool:
        spool.append(cloud.columns)
        write_points_file(spool, tmp_path / "a.txt", exporter=Lines(), sidecar=False)
    assert (tmp_path / "a.txt").read_text() == f"{len(cloud)}\n"


def test_importing_and_registering_does_not_import_laspy_or_dask():
    code = ("import sys, lidarsim_core; from lidarsim_core.plugins import get_registry; "
            "get_registry(); import lidarsim_core.dataset; "
            "print([m for m in sys.modules if m.split('.')[0] in ('laspy', 'lazrs', 'dask', "
            "'distributed')])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"
