"""Built-in plugin: binary little-endian PLY with every point-record column as a property.

Property types are the ones every common PLY reader takes: Open3D's tensor reader (which
skips ``char``, ``short``, ``ushort`` and ``uint`` properties as "unsupported datatype"), its
legacy reader and CloudCompare (both RPly), plyfile and trimesh all accept ``uchar``, ``int``,
``float`` and ``double``:

=======================  =========  ===================================================
record dtype             PLY type   columns
=======================  =========  ===================================================
float64                  double     x, y, z, x_true..., range, timestamp, ...
float32                  float      intensity
uint8 / bool             uchar      return_number, number_of_returns, detected
int8, int16, uint16,     int        channel, target, part; and face_index (int64 in the
int32                               record; a triangle index beyond int32 is an error
                                    that suggests ``.npz``)
uint32, int64, uint64    double     ray_index (and any other 64-bit integer column):
                                    exact for integers below 2**53
=======================  =========  ===================================================

The frame metadata is in the header as ``comment lidarsim-frame <piece>`` lines of under 200
characters (:mod:`lidarsim_core.io.headermeta`; RPly aborts the process on a header line over
~1 KB), and the exact part and target names as ``comment lidarsim-part <index> "<name>"`` /
``comment lidarsim-target <index> "<name>"`` lines (the name as an ASCII JSON string: plyfile
decodes headers as ASCII), so that ``part`` and ``target`` can be labelled with nothing but a
PLY reader. The sidecar JSON holds the metadata too.

Option ``dialect: cloudcompare`` (CLI ``--dialect cloudcompare``) names every property but
x, y, z ``scalar_<column>``, so that CloudCompare loads each as a scalar field (it keeps only
x, y, z and ``intensity`` of the standard names; :mod:`lidarsim_core.io.dialects`);
:func:`read_ply_columns` maps the names back.
Written chunk by chunk from NumPy structured arrays: the format is a header plus raw bytes.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from pydantic import Field

from ..base.errors import ConfigError, OutputError
from ..hookspecs import hookimpl
from .base import Exporter
from .columns import check_input, check_record_count, header_lines, reader_errors
from .dialects import Dialect, DialectOptions, column_name, record_names
from .headermeta import metadata_from_lines, metadata_lines
from .points import DEFAULT_CHUNK_POINTS

if TYPE_CHECKING:
    from .points import PointSource

#: Prefix of the header comments holding the frame metadata.
METADATA_PREFIX = "lidarsim-frame "
#: Integer columns written as ``double`` hold exact integers up to this magnitude.
_EXACT_DOUBLE = 2 ** 53
#: Columns whose PLY type is fixed whatever their record dtype (triangle indices fit int32).
_FIXED_TYPES: dict[str, tuple[str, str]] = {"face_index": ("int", "<i4")}
#: ``(PLY type, little-endian dtype)`` of every PLY type a file may hold.
PLY_TYPES: dict[str, str] = {"char": "i1", "uchar": "u1", "short": "<i2", "ushort": "<u2",
                             "int": "<i4", "uint": "<u4", "float": "<f4", "double": "<f8",
                             "int8": "i1", "uint8": "u1", "int16": "<i2", "uint16": "<u2",
                             "int32": "<i4", "uint32": "<u4", "float32": "<f4",
                             "float64": "<f8"}


def ply_type(dtype: np.dtype | str) -> tuple[str, str]:
    """``(PLY type, written dtype)`` for a column of NumPy ``dtype`` (see the module table)."""
    dtype = np.dtype(dtype)
    if dtype.kind == "f":
        return ("float", "<f4") if dtype.itemsize <= 4 else ("double", "<f8")
    if dtype.kind == "b" or (dtype.kind == "u" and dtype.itemsize == 1):
        return "uchar", "u1"
    if dtype.kind in "iu" and (dtype.itemsize < 4 or (dtype.kind == "i" and dtype.itemsize == 4)):
        return "int", "<i4"
    if dtype.kind in "iu":
        return "double", "<f8"
    raise OutputError(f"a column of type {dtype} has no PLY type; use .npz")


def ply_layout(fields: dict[str, np.dtype] | None = None) -> list[tuple[str, str, str]]:
    """``(column, PLY type, written dtype)`` for every column (default: the point record)."""
    if fields is None:
        from ..records.pointcloud import POINT_FIELDS

        fields = {k: np.dtype(v) for k, v in POINT_FIELDS.items()}
    return [(name, *_FIXED_TYPES.get(name, ply_type(dtype))) for name, dtype in fields.items()]


def _check_fits(column: str, values: np.ndarray, ply: str, out: str) -> None:
    if not len(values) or values.dtype.kind not in "iu":
        return
    lo, hi = int(values.min()), int(values.max())
    if ply == "double":
        if max(abs(lo), abs(hi)) >= _EXACT_DOUBLE:
            raise OutputError(f"column '{column}' has integers beyond 2**53, which PLY's "
                              "double cannot hold exactly; use .npz", field=column)
        return
    info = np.iinfo(out)
    if lo < info.min or hi > info.max:
        raise OutputError(f"column '{column}' does not fit PLY type {ply}; use .npz",
                          field=column)


def _names_comments(kind: str, names: list[str]) -> list[str]:
    return list(_names_lines(kind, tuple(names)))


@functools.lru_cache(maxsize=64)
def _names_lines(kind: str, names: tuple[str, ...]) -> tuple[str, ...]:
    # the same names in every frame of a sequence: made once
    lines = []
    for i, name in enumerate(names):
        text = json.dumps(name, ensure_ascii=True)
        if len(text) > 400:
            raise OutputError(f"{kind} name {name[:40]!r}... is too long for a PLY header line",
                              field=f"{kind}_names")
        lines.append(f"comment lidarsim-{kind} {i} {text}")
    return tuple(lines)


class PlyOptions(DialectOptions):
    """Options of the PLY exporter."""

    dialect: Dialect = Field(
        "standard", description="Property names: 'standard' (the point-record names) or "
                                "'cloudcompare' (each column but x, y, z prefixed 'scalar_', "
                                "loaded by CloudCompare as scalar fields).")


class PlyExporter(Exporter):
    """Binary PLY with every column as a vertex property and metadata in short comments."""

    name = "ply"
    suffixes = (".ply",)
    memory_stream = True
    Options = PlyOptions
    options: PlyOptions

    def write_points(self, points: "PointSource", stream: IO[bytes]) -> None:
        layout, dtype, properties, checked = _plan(tuple(points.fields.items()),
                                                   self.options.dialect)
        frame = points.frame
        header = ["ply", "format binary_little_endian 1.0", "comment generated by lidarsim"]
        header += ["comment " + line
                   for line in metadata_lines(frame.to_dict(), METADATA_PREFIX)]
        header += _names_comments("part", frame.part_names)
        header += _names_comments("target", frame.target_names)
        header.append(f"element vertex {len(points)}")
        header += properties
        header.append("end_header")
        stream.write(("\n".join(header) + "\n").encode("ascii"))
        records = points.records()
        if records is not None:  # one conversion a chunk: the same bytes as column by column
            for column, ply, out in checked:
                _check_fits(column, records[column], ply, out)
            for start in range(0, len(records), DEFAULT_CHUNK_POINTS):
                stream.write(records[start:start + DEFAULT_CHUNK_POINTS].astype(dtype).data)
            return
        for chunk in points.iter_chunks([n for n, _, _ in layout]):
            data = np.empty(len(chunk["x"]), dtype=dtype)
            for column, ply, out in layout:
                _check_fits(column, chunk[column], ply, out)
                data[column] = chunk[column]
            stream.write(data.tobytes())


@functools.lru_cache(maxsize=64)
def _plan(fields: tuple[tuple[str, np.dtype], ...], dialect: str
          ) -> tuple[list[tuple[str, str, str]], np.dtype, tuple[str, ...],
                     tuple[tuple[str, str, str], ...]]:
    """What a layout of columns needs, made once: ``(column, PLY type, written dtype)`` of
    each, the written record dtype, the header's property lines, and the columns whose
    values must be checked against their PLY type (integers that may not fit it)."""
    layout = ply_layout(dict(fields))
    dtype = np.dtype([(n, out) for n, _, out in layout])
    properties = tuple(f"property {ply} {column_name(name, dialect)}"
                       for name, ply, _ in layout)
    kinds = dict(fields)
    checked = tuple((name, ply, out) for name, ply, out in layout
                    if kinds[name].kind in "iu" and not (
                        np.dtype(out).kind in "iu" and np.can_cast(kinds[name], out, "safe")))
    return layout, dtype, properties, checked


def read_ply_columns(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, Any] | None]:
    """The vertex properties of a binary little-endian PLY point cloud and its lidarsim
    frame metadata (``None`` when the header has none).

    Properties of the ``cloudcompare`` dialect (``scalar_<column>``) come back under the
    point-record names.

    Raises
    ------
    ConfigError
        If the file is not a binary little-endian PLY with one vertex element of scalars.
    """

    path = Path(path)
    size = check_input(path, "PLY file")
    with open(path, "rb") as stream, reader_errors(path, "PLY file"):
        comments, props, count, fmt = _ply_header(stream, path)
        if fmt != ["binary_little_endian"]:
            raise ConfigError(f"PLY format {' '.join(fmt or ['(none)'])} is not "
                              "binary_little_endian", source=path)
        if count is None:
            raise ConfigError("PLY file has no vertex element", source=path)
        if not props:
            raise ConfigError("PLY vertex element has no properties", source=path,
                              field="element vertex")
        dtype = np.dtype(props)
        number = check_record_count(count, dtype.itemsize, size - stream.tell(), source=path,
                                    what="vertices", field="element vertex")
        data = np.frombuffer(stream.read(number * dtype.itemsize), dtype=dtype)
        if len(data) != number:  # the file shrank while it was read
            raise ConfigError(f"PLY file is truncated: {len(data)} of {number} vertices",
                              source=path)
        from ..records.pointcloud import POINT_FIELDS

        names = list(dtype.names or ())
        columns = {new: np.array(data[name])
                   for name, new in zip(names, record_names(names, POINT_FIELDS))}
    return columns, metadata_from_lines(comments, METADATA_PREFIX, source=path,
                                        field="comment lidarsim-frame")


def _ply_header(stream: IO[bytes], path: Path
                ) -> tuple[list[str], list[tuple[str, str]], str | None, list[str] | None]:
    """Comments, vertex properties, the vertex count as written, and the format words of a
    PLY header, every defect named."""
    comments: list[str] = []
    props: list[tuple[str, str]] = []
    count: str | None = None
    fmt: list[str] | None = None
    element = None
    if stream.readline(64).strip() != b"ply":
        raise ConfigError("not a PLY file (no 'ply' magic line)", source=path)
    for line in header_lines(stream, path, "PLY", "end_header"):
        words = line.split()
        if not words:
            continue
        if words[0] == "end_header":
            break
        if words[0] == "comment":
            comments.append(line[len("comment "):])
        elif words[0] == "format":
            fmt = words[1:2]
        elif words[0] == "element":
            if len(words) != 3:
                raise ConfigError(f"PLY line {line[:60]!r} is not 'element NAME COUNT'",
                                  source=path, field="element")
            element = words[1]
            if element == "vertex":
                if count is not None:
                    raise ConfigError("PLY header has two vertex elements", source=path,
                                      field="element vertex")
                count = words[2]
                check_record_count(count, 0, 0, source=path, what="vertices",
                                   field="element vertex")
            elif words[2] != "0":
                raise ConfigError(f"PLY element '{element}' is not supported (only a "
                                  "vertex element)", source=path)
        elif words[0] == "property" and element == "vertex":
            if len(words) != 3 or words[1] not in PLY_TYPES:
                raise ConfigError(f"PLY property '{' '.join(words[1:])}' is not a scalar "
                                  "of a known type", source=path, field=words[-1])
            if any(name == words[2] for name, _ in props):
                raise ConfigError(f"PLY property '{words[2]}' is declared twice",
                                  source=path, field=words[2])
            props.append((words[2], PLY_TYPES[words[1]]))
    return comments, props, count, fmt


@hookimpl
def lidarsim_register_exporters(register: Any) -> None:
    """Register the PLY exporter."""
    register(PlyExporter)
