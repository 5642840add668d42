"""Built-in plugin: binary PCD (Point Cloud Data v0.7) with PCL's field conventions.

Fields follow what PCL point types and ROS drivers expect, so ``pcl::io::loadPCDFile`` fills
``pcl::PointXYZ``/``PointXYZI``/``PointXYZL`` and Open3D reads the coordinates:

=================  ======================  ==============================================
point record       PCD field (TYPE SIZE)   why
=================  ======================  ==============================================
x, y, z            x, y, z (F 4)           PCL's float coordinates (option ``xyz_dtype``
                                           ``float64`` writes F 8 instead)
part               label (U 4)             ``pcl::PointXYZL::label``; index into the
                                           frame's ``part_names``
channel            ring (U 2)              the ROS LiDAR drivers' laser ring
intensity          intensity (F 4)         ``pcl::PointXYZI`` (only when the column exists)
ray_index          ray_index (U 4)         unsigned 32-bit (larger values are an error)
face_index         face_index (I 4)        32-bit (larger values are an error)
every other column its own name            same type (F 8, U 1, I 2, ...)
=================  ======================  ==============================================

The frame metadata is in header comments ``# lidarsim-frame <piece>`` of under 200 characters
(:mod:`lidarsim_core.io.headermeta`; PCL and Open3D skip lines starting with ``#``, and
Open3D reads header lines in 1 KB pieces). Points are in the sensor frame, so ``VIEWPOINT`` is the identity.
:func:`read_pcd` reads the files back into point-record columns.
"""

from __future__ import annotations

from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import Field

from ..base.components import ComponentOptions
from ..base.errors import ConfigError, OutputError
from ..hookspecs import hookimpl
from .base import Exporter
from .columns import (
    cast_column,
    check_input,
    check_record_count,
    header_lines,
    reader_errors,
)
from .headermeta import metadata_from_lines, metadata_lines

if TYPE_CHECKING:
    from ..records.pointcloud import PointCloud
    from .points import PointSource

#: Point-record column → PCD field name, where PCL/ROS use another name.
PCD_NAMES: dict[str, str] = {"part": "label", "channel": "ring"}
#: Columns written with a fixed PCD type (NumPy dtype) whatever their record dtype.
_FIXED_TYPES: dict[str, str] = {"part": "<u4", "channel": "<u2", "intensity": "<f4",
                                "ray_index": "<u4", "face_index": "<i4"}
_PCD_TYPE_CHAR = {"f": "F", "i": "I", "u": "U"}
_METADATA_PREFIX = "# lidarsim-frame "


class PcdOptions(ComponentOptions):
    """Options of the PCD exporter."""

    xyz_dtype: Literal["float32", "float64"] = Field(
        "float32", description="Type of the measured x, y, z: float32 as PCL's point types "
                               "(rounded by ≤ 3.8 µm at 100 m), or float64 for full precision.")


def pcd_layout(fields: dict[str, np.dtype], xyz_dtype: str = "float32"
               ) -> list[tuple[str, str, np.dtype]]:
    """``(record column, PCD field name, written little-endian dtype)`` for each column."""
    layout = []
    for column, dtype in fields.items():
        if column in ("x", "y", "z"):
            out = np.dtype(xyz_dtype).newbyteorder("<")
        elif column in _FIXED_TYPES:
            out = np.dtype(_FIXED_TYPES[column])
        else:
            out = np.dtype(dtype).newbyteorder("<")
            if out.kind not in _PCD_TYPE_CHAR:
                raise OutputError(f"column '{column}' of type {dtype} has no PCD type",
                                  field=column)
        layout.append((column, PCD_NAMES.get(column, column), out))
    return layout


def pcd_header(layout: list[tuple[str, str, np.dtype]], count: int,
               metadata: dict[str, Any]) -> str:
    """The ASCII header of a binary PCD v0.7 file."""
    lines = ["# .PCD v0.7 - Point Cloud Data file format",
             *metadata_lines(metadata, _METADATA_PREFIX),
             "VERSION 0.7",
             "FIELDS " + " ".join(name for _, name, _ in layout),
             "SIZE " + " ".join(str(dt.itemsize) for _, _, dt in layout),
             "TYPE " + " ".join(_PCD_TYPE_CHAR[dt.kind] for _, _, dt in layout),
             "COUNT " + " ".join("1" for _ in layout),
             f"WIDTH {count}", "HEIGHT 1", "VIEWPOINT 0 0 0 1 0 0 0", f"POINTS {count}",
             "DATA binary"]
    return "\n".join(lines) + "\n"


def _check_fits(column: str, values: np.ndarray, out: np.dtype) -> None:
    if out.kind in "iu" and len(values):
        info = np.iinfo(out)
        if values.min() < info.min or values.max() > info.max:
            raise OutputError(f"column '{column}' does not fit PCD type {out.kind.upper()} "
                              f"{out.itemsize}; use .npz", field=column)


class PcdExporter(Exporter):
    """Binary PCD v0.7 with PCL field names (x y z, label, ring) and metadata in a comment."""

    name = "pcd"
    suffixes = (".pcd",)
    memory_stream = True
    Options = PcdOptions
    options: PcdOptions

    def write_points(self, points: "PointSource", stream: IO[bytes]) -> None:
        layout = pcd_layout(points.fields, self.options.xyz_dtype)
        stream.write(pcd_header(layout, len(points), points.frame.to_dict()).encode("ascii"))
        record = np.dtype([(name, out) for _, name, out in layout])
        for chunk in points.iter_chunks([column for column, _, _ in layout]):
            data = np.empty(len(chunk["x"]), dtype=record)
            for column, name, out in layout:
                _check_fits(column, chunk[column], out)
                data[name] = chunk[column]
            stream.write(data.tobytes())


def read_pcd_columns(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, Any] | None]:
    """The fields of a binary PCD as point-record columns, and its lidarsim frame metadata
    (``None`` when the header has none).

    PCD field names are mapped back to point-record columns (``label`` → ``part``, ``ring`` →
    ``channel``) and cast to the record's dtypes; x, y, z are as precise as the file.

    Raises
    ------
    ConfigError
        If the file is not a binary PCD.
    """
    from ..records.pointcloud import POINT_FIELDS

    path = Path(path)
    size = check_input(path, "PCD file")
    header: dict[str, list[str]] = {}
    comments: list[str] = []
    with open(path, "rb") as stream, reader_errors(path, "PCD file"):
        for line in header_lines(stream, path, "PCD", "DATA"):
            if line.startswith("#"):
                comments.append(line)
            elif line.strip():
                key, *values = line.split()
                if key in header:
                    raise ConfigError(f"PCD header has two {key} lines", source=path,
                                      field=key)
                header[key] = values
                if key == "DATA":
                    break
        if header["DATA"] != ["binary"]:
            raise ConfigError(f"PCD DATA is {' '.join(header['DATA'])}, not binary", source=path)
        for key in ("FIELDS", "SIZE", "TYPE", "POINTS"):
            if key not in header:
                raise ConfigError(f"PCD header has no {key} line", source=path, field=key)
        names, types, sizes = header["FIELDS"], header["TYPE"], header["SIZE"]
        if not names or len(types) != len(names) or len(sizes) != len(names):
            raise ConfigError(f"PCD header has {len(names)} FIELDS, {len(types)} TYPE and "
                              f"{len(sizes)} SIZE entries", source=path, field="FIELDS")
        if len(set(names)) != len(names):
            raise ConfigError("PCD header names a field twice", source=path, field="FIELDS")
        if header.get("COUNT", ["1"] * len(names)) != ["1"] * len(names):
            raise ConfigError("PCD fields with COUNT other than 1 are not supported",
                              source=path, field="COUNT")
        kinds = {"F": "f", "I": "i", "U": "u"}
        allowed = {"f": ("4", "8"), "i": ("1", "2", "4", "8"), "u": ("1", "2", "4", "8")}
        for name, kind, width in zip(names, types, sizes):
            if kind not in kinds or width not in allowed[kinds[kind]]:
                raise ConfigError(f"PCD field '{name}' has TYPE {kind} SIZE {width}, not one "
                                  "of F 4/8, I or U 1/2/4/8", source=path, field=name)
        dtype = np.dtype([(name, f"<{kinds[t]}{s}") for name, t, s in zip(names, types, sizes)])
        if len(header["POINTS"]) != 1:
            raise ConfigError("PCD POINTS line does not hold one count", source=path,
                              field="POINTS")
        count = check_record_count(header["POINTS"][0], dtype.itemsize, size - stream.tell(),
                                   source=path, what="points", field="POINTS")
        data = np.frombuffer(stream.read(count * dtype.itemsize), dtype=dtype)
        if len(data) != count:
            raise ConfigError(f"PCD file is truncated: {len(data)} of {count} points",
                              source=path)
        back = {pcd: column for column, pcd in PCD_NAMES.items()}
        columns = {}
        for name in dtype.names or ():
            column = back.get(name, name)
            columns[column] = cast_column(data[name], POINT_FIELDS.get(column,
                                                                        data[name].dtype),
                                          source=path, field=name)
    return columns, metadata_from_lines(comments, _METADATA_PREFIX, source=path,
                                        field="# lidarsim-frame")


def read_pcd(path: str | Path) -> "PointCloud":
    """Read a binary PCD written by :class:`PcdExporter` back into a point cloud.

    Raises
    ------
    ConfigError
        If the file is not a binary PCD with lidarsim frame metadata.
    """
    from .columns import cloud_from_columns

    return cloud_from_columns(*read_pcd_columns(path), source=path,
                              no_metadata="PCD file lacks the lidarsim-frame comment")


@hookimpl
def lidarsim_register_exporters(register: Any) -> None:
    """Register the PCD exporter."""
    register(PcdExporter)
