"""Built-in plugins: LAS 1.4 and LAZ (compressed LAS) through laspy (extra ``las``).

Point data record format 6 (LAS 1.4, with GPS time). The point record maps to it as follows:

====================  =================================================================
LAS field             from
====================  =================================================================
X, Y, Z               x, y, z (sensor frame), integers of ``scale_m`` (default 0.1 mm),
                      offset 0: rounded to the nearest step, so |error| <= scale_m / 2
gps_time              timestamp: seconds from the scenario epoch (not GPS time; global
                      encoding says "GPS week time", the field's neutral setting)
intensity             the ``intensity`` column when there is one: a float column (apparent
                      reflectivity, unbounded: glints and retro-reflectors exceed 1) as
                      ``round(intensity / s)`` with the file's scale
                      ``s = max(1, brightest intensity) / 65535``, so nothing clips and the
                      brightest return reads 65535 (s = 1/65535, "65535 is reflectivity 1",
                      when no return exceeds 1); ``s`` is in VLR ``lidarsim``/4. An integer
                      column is clipped to 0..65535. Without the column, 0
return_number,        the same columns (LAS holds 1..15; larger values are an error)
number_of_returns
classification        64 + part (ASPRS classes 64..255 are user-definable), named in a
                      standard Classification Lookup VLR; a scene with more than 192 parts
                      writes class 1 (unclassified) and keeps ``part`` as extra bytes
extra bytes           every other column under its own name and exact type (x_true, range,
                      ray_index as int64, ...), described in the standard Extra Bytes VLR,
                      and ``reflectivity``: the exact float32 ``intensity`` (the standard
                      field holds it to half a step of ``s``)
====================  =================================================================

The frame metadata (poses, sensor, seed, configuration hash...) is JSON in a VLR with user ID
``lidarsim``, record ID 1 (an EVLR when it exceeds a VLR's 65,535 bytes). The lookup VLR
holds 15 ASCII characters per class (and laspy's parser drops every character but letters,
digits and spaces when it reads one: ``panel_right`` comes back as ``panelright``), so the
exact part names are also in VLR ``lidarsim``/2 and the target names in ``lidarsim``/3, as
UTF-8 text with one name per line (part *i* on line *i*, class 64 + *i*). VLR ``lidarsim``/4
holds the intensity scale as JSON, ``{"intensity_scale": s}``: ``Intensity × s`` is the
apparent reflectivity within ``s / 2`` (1/131070 of the file's brightest return). The project
GUID is derived from the configuration hash and the frame index; system identifier and
generating software name lidarsim. The file creation day and year are written as 0 ("unknown"): a
regenerated frame is identical to the bit.

laspy (and lazrs for LAZ) are imported only when a file is written.
"""

from __future__ import annotations

import json
import uuid
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, ClassVar

import numpy as np
from pydantic import Field

from .._version import __version__
from ..base.components import ComponentOptions
from ..base.errors import ConfigError, OutputError
from ..base.optional import require
from ..hookspecs import hookimpl
from .base import Exporter
from .columns import cast_column, check_input, check_record_count

if TYPE_CHECKING:
    from ..records.pointcloud import PointCloud
    from .points import PointSource

#: Standard fields of point format 6 filled from the point record (besides x, y, z, part).
_STANDARD = ("timestamp", "return_number", "number_of_returns", "intensity")
#: VLR holding the frame metadata.
METADATA_USER_ID = "lidarsim"
METADATA_RECORD_ID = 1
#: VLRs holding the exact part and target names, one per line.
PART_NAMES_RECORD_ID = 2
TARGET_NAMES_RECORD_ID = 3
#: VLR holding the scale of the standard intensity field (JSON ``{"intensity_scale": s}``).
INTENSITY_SCALE_RECORD_ID = 4
#: Intensity scale when no return is brighter than reflectivity 1: 65535 is reflectivity 1.
UNIT_INTENSITY_SCALE = 1.0 / 65535.0
#: Extra-bytes column holding the exact float ``intensity``.
EXACT_INTENSITY = "reflectivity"
#: Classification of part 0; ASPRS reserves 0..63.
CLASS_OFFSET = 64
_MAX_VLR_BYTES = 65535
_CREATION_DATE_OFFSET = 90  # File Creation Day of Year (u16) and Year (u16) in the header
_GUID_NAMESPACE = uuid.UUID("5d1f1f7e-5a53-4a8e-9d6e-6c1d4f3b2a10")
_CHUNK_POINTS = 262144


class LasOptions(ComponentOptions):
    """Options of the LAS/LAZ exporters."""

    scale_m: float = Field(1e-4, gt=0, le=0.01,
                           description="Coordinate resolution (m): X, Y, Z are integers of it.")


def _laspy() -> Any:
    return require("laspy", extra="las", what="writing LAS/LAZ", error=OutputError)


def classes_fit(part_names: list[str]) -> bool:
    """Whether every part gets its own user-definable LAS class (at most 192 parts)."""
    return len(part_names) <= 256 - CLASS_OFFSET


def extra_columns(fields: dict[str, np.dtype], part_names: list[str]) -> list[str]:
    """Columns stored as LAS extra bytes: everything not held by a standard field."""
    standard = {"x", "y", "z", *_STANDARD}
    if classes_fit(part_names):
        standard.add("part")
    return [name for name in fields if name not in standard]


def _class_label(name: str) -> str:
    # the lookup VLR holds 15 ASCII characters; the full names are in the metadata VLR
    short = name.rsplit("/", 1)[-1].encode("ascii", "replace").decode("ascii")
    return short[:15]


def intensity_scale(brightest: float) -> float:
    """The scale ``s`` of LAS's 16-bit intensity for a file whose brightest float intensity is
    ``brightest``: ``max(1, brightest) / 65535``, so that no return clips and the brightest
    reads 65535 (65535 is reflectivity 1 when no return is brighter)."""
    if not np.isfinite(brightest) or brightest <= 1.0:
        return UNIT_INTENSITY_SCALE
    return float(brightest) / 65535.0


def _intensity_u16(values: np.ndarray, scale: float) -> np.ndarray:
    if values.dtype.kind == "f":
        counts = np.round(np.nan_to_num(values.astype(np.float64), nan=0.0) / scale)
        return np.clip(counts, 0.0, 65535.0).astype(np.uint16)
    return np.clip(values, 0, 65535).astype(np.uint16)


def _brightest(points: "PointSource") -> float:
    brightest = 0.0
    for chunk in points.iter_chunks(["intensity"], size=_CHUNK_POINTS):
        values = chunk["intensity"][np.isfinite(chunk["intensity"])]
        if len(values):
            brightest = max(brightest, float(values.max()))
    return brightest


def _float_intensity(fields: dict[str, np.dtype]) -> bool:
    # a float intensity is scaled into the standard u16 field (scale in VLR lidarsim/4)
    return "intensity" in fields and np.dtype(fields["intensity"]).kind == "f"


def _exact_intensity(fields: dict[str, np.dtype]) -> bool:
    # a float intensity loses precision in the standard u16 field: kept exact in extra bytes
    return _float_intensity(fields) and EXACT_INTENSITY not in fields


class LasExporter(Exporter):
    """LAS 1.4 point format 6: gps time, returns, class per part, the rest as extra bytes."""

    name = "las"
    suffixes = (".las",)
    memory_stream = True
    Options = LasOptions
    options: LasOptions
    requires = ("laspy", "lazrs")
    #: Whether to compress (LAZ).
    compress: ClassVar[bool] = False

    def _header(self, laspy: Any, points: "PointSource", scale: float
                ) -> tuple[Any, list[str]]:
        frame = points.frame
        header = laspy.LasHeader(point_format=6, version="1.4")
        header.scales = np.full(3, self.options.scale_m)
        header.offsets = np.zeros(3)
        header.system_identifier = "lidarsim simulation"
        header.generating_software = f"lidarsim-core {__version__}"[:32]
        header.uuid = uuid.uuid5(_GUID_NAMESPACE, f"{frame.config_hash}/{frame.frame}")
        header.global_encoding.wkt = True  # required for point formats 6..10
        extras = extra_columns(points.fields, frame.part_names)
        params = [laspy.ExtraBytesParams(name, points.fields[name], description=name[:32])
                  for name in extras]
        if _exact_intensity(points.fields):
            params.append(laspy.ExtraBytesParams(EXACT_INTENSITY, np.float32,
                                                 description="exact intensity"))
        header.add_extra_dims(params)
        if classes_fit(frame.part_names):
            lookup = laspy.vlrs.known.ClassificationLookupVlr()
            for i, part in enumerate(frame.part_names):
                lookup[CLASS_OFFSET + i] = _class_label(part)
            header.vlrs.append(lookup)
        blob = points.metadata_json().encode("utf-8")
        vlr = laspy.VLR(user_id=METADATA_USER_ID, record_id=METADATA_RECORD_ID,
                        description="lidarsim frame metadata", record_data=blob)
        (header.vlrs if len(blob) <= _MAX_VLR_BYTES else header.evlrs).append(vlr)
        if _float_intensity(points.fields):
            header.vlrs.append(laspy.VLR(
                user_id=METADATA_USER_ID, record_id=INTENSITY_SCALE_RECORD_ID,
                description="lidarsim intensity scale",
                record_data=json.dumps({"intensity_scale": scale}).encode("ascii")))
        for record_id, kind, names in ((PART_NAMES_RECORD_ID, "part", frame.part_names),
                                       (TARGET_NAMES_RECORD_ID, "target", frame.target_names)):
            if any("\n" in name for name in names):
                raise OutputError(f"a {kind} name holds a line break, which LAS's name VLR "
                                  "cannot hold", field=f"{kind}_names")
            blob = "\n".join(names).encode("utf-8")
            (header.vlrs if len(blob) <= _MAX_VLR_BYTES else header.evlrs).append(
                laspy.VLR(user_id=METADATA_USER_ID, record_id=record_id,
                          description=f"lidarsim {kind} names", record_data=blob))
        return header, extras

    def write_points(self, points: "PointSource", stream: IO[bytes]) -> None:
        laspy = _laspy()
        scale = (intensity_scale(_brightest(points)) if _float_intensity(points.fields)
                 else UNIT_INTENSITY_SCALE)
        header, extras = self._header(laspy, points, scale)
        fields = points.fields
        with_part = classes_fit(points.frame.part_names)
        xyz_scale = self.options.scale_m
        columns = ["x", "y", "z", "timestamp", "return_number", "number_of_returns",
                   *(["part"] if with_part else []),
                   *(["intensity"] if "intensity" in fields else []), *extras]
        backend = laspy.LazBackend.Lazrs if self.compress else None
        start = stream.tell()
        with laspy.open(stream, mode="w", header=header, do_compress=self.compress,
                        laz_backend=backend, closefd=False) as writer:
            for chunk in points.iter_chunks(columns, size=_CHUNK_POINTS):
                n = len(chunk["x"])
                record = laspy.ScaleAwarePointRecord.zeros(n, header=header)
                for axis in "xyz":
                    record[axis.upper()] = self._scaled(axis, chunk[axis], xyz_scale)
                record["gps_time"] = chunk["timestamp"]
                for column in ("return_number", "number_of_returns"):
                    values = chunk[column]
                    if n and (values.min() < 0 or values.max() > 15):
                        raise OutputError(f"column '{column}' exceeds LAS's 0..15; use .npz",
                                          field=column)
                    record[column] = values
                record["classification"] = (chunk["part"].astype(np.int64) + CLASS_OFFSET
                                            if with_part else np.ones(n, dtype=np.uint8))
                if "intensity" in chunk:
                    record["intensity"] = _intensity_u16(chunk["intensity"], scale)
                    if _exact_intensity(fields):
                        record[EXACT_INTENSITY] = chunk["intensity"]
                for name in extras:
                    record[name] = chunk[name]
                writer.write_points(record)
        end = stream.seek(0, 2)
        stream.seek(start + _CREATION_DATE_OFFSET)
        stream.write(bytes(4))  # creation day and year 0: "unknown", so reruns are identical
        stream.seek(end)

    @staticmethod
    def _scaled(axis: str, values: np.ndarray, scale: float) -> np.ndarray:
        ints = np.round(values / scale)
        if len(ints) and (np.abs(ints).max() > np.iinfo(np.int32).max or
                          not np.all(np.isfinite(ints))):
            raise OutputError(f"coordinate '{axis}' beyond LAS's int32 range at scale "
                              f"{scale:g} m; raise scale_m or use .npz", field=axis)
        return ints.astype(np.int32)


class LazExporter(LasExporter):
    """LAZ (LASzip-compressed LAS 1.4, via lazrs): the same content as ``las``, smaller."""

    name = "laz"
    suffixes = (".laz",)
    compress = True


def read_las_columns(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, Any] | None]:
    """The point-record columns of a LAS/LAZ file written by :class:`LasExporter`, and its
    frame metadata (``None`` without lidarsim's metadata VLR).

    x, y, z come back at the file's resolution (``scale_m``); ``part`` from the classification
    (or the extra bytes), ``timestamp`` from the GPS time, ``intensity`` from the exact
    ``reflectivity`` extra bytes when there are some, the rest from the extra bytes.
    """
    from ..records.pointcloud import POINT_FIELDS

    path = Path(path)
    size = check_input(path, "LAS/LAZ file")
    laspy = _laspy()
    _check_las_header(laspy, path, size)
    try:
        data = laspy.read(str(path))
    except Exception as exc:  # laspy raises its own and many other types on bad files
        raise ConfigError(f"cannot read LAS/LAZ: {type(exc).__name__}: "
                          f"{' '.join(str(exc).split())[:200]}", source=path) from None
    blob, scale = None, UNIT_INTENSITY_SCALE
    for vlr in [*data.header.vlrs, *data.header.evlrs]:
        user, record = getattr(vlr, "user_id", None), getattr(vlr, "record_id", None)
        if user == METADATA_USER_ID and record == METADATA_RECORD_ID:
            blob = getattr(vlr, "record_data", b"")
        if user == METADATA_USER_ID and record == INTENSITY_SCALE_RECORD_ID:
            scale = read_intensity_scale(bytes(getattr(vlr, "record_data", b"")), path)
    metadata = None
    if blob is not None:
        try:
            metadata = json.loads(bytes(blob).decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError) as exc:
            raise ConfigError(f"lidarsim's metadata VLR is not UTF-8 JSON ({exc})",
                              source=path, field="VLR lidarsim/1") from None
    columns: dict[str, np.ndarray] = {
        "x": np.asarray(data.x, dtype=np.float64), "y": np.asarray(data.y, dtype=np.float64),
        "z": np.asarray(data.z, dtype=np.float64),
        "timestamp": np.asarray(data.gps_time, dtype=np.float64),
        "return_number": np.asarray(data.return_number, dtype=np.uint8),
        "number_of_returns": np.asarray(data.number_of_returns, dtype=np.uint8)}
    extras = list(data.point_format.extra_dimension_names)
    for name in extras:
        if name != EXACT_INTENSITY or "intensity" not in POINT_FIELDS:
            columns[name] = np.asarray(data[name])
    if "intensity" in POINT_FIELDS:
        if EXACT_INTENSITY in extras:
            columns["intensity"] = np.asarray(data[EXACT_INTENSITY])
        else:
            raw = np.asarray(data.intensity)
            kind = np.dtype(POINT_FIELDS["intensity"]).kind
            columns["intensity"] = raw * scale if kind == "f" else raw
    if "part" not in columns:
        columns["part"] = (np.asarray(data.classification, dtype=np.int64)
                           - CLASS_OFFSET).astype(np.int16)
    columns = {k: cast_column(v, POINT_FIELDS.get(k, v.dtype), source=path, field=k)
               for k, v in columns.items()}
    return columns, metadata


def read_intensity_scale(record: bytes, source: str | Path) -> float:
    """The intensity scale ``s`` held by VLR ``lidarsim``/4 (``Intensity × s`` is the apparent
    reflectivity).

    Raises
    ------
    ConfigError
        If the record is not ``{"intensity_scale": <positive number>}``.
    """
    try:
        scale = float(json.loads(record.decode("ascii"))["intensity_scale"])
    except (ValueError, KeyError, TypeError, UnicodeDecodeError):
        scale = float("nan")
    if not (np.isfinite(scale) and scale > 0):
        raise ConfigError("VLR lidarsim/4 is not {\"intensity_scale\": <positive number>}",
                          source=source, field="intensity_scale")
    return scale


def _check_las_header(laspy: Any, path: Path, size: int) -> None:
    """Refuse a LAS/LAZ whose header declares more points than the file can hold, before
    laspy allocates them: an uncompressed LAS holds ``count × record length`` bytes after its
    offset to point data; a LAZ is held to the ``rays_per_frame`` limit (a point per ray) and
    to the ``data_bytes`` limit once decompressed."""
    from ..base.limits import LIMITS, limit

    _check_las_layout(path, size)  # counts laspy would loop over, before it does
    try:
        with laspy.open(str(path)) as reader:
            header = reader.header
            count = int(header.point_count)
            record = int(header.point_format.size)
            offset = int(header.offset_to_point_data)
            compressed = bool(header.are_points_compressed)
    except Exception as exc:  # laspy raises its own and many other types on bad headers
        raise ConfigError(f"cannot read LAS/LAZ header: {type(exc).__name__}: "
                          f"{' '.join(str(exc).split())[:200]}", source=path) from None
    if compressed:
        bound = limit("data_bytes")
        if count * record > bound:
            raise ConfigError(f"declares {count:,} points of {record} bytes, over the limit "
                              f"of {bound:,.0f} bytes once decompressed (set "
                              f"{LIMITS['data_bytes'].env} to raise it)", source=path,
                              field="point count")
        return
    check_record_count(count, record, max(size - offset, 0), source=path, what="points",
                       field="point count")


#: Sizes of a VLR header and an EVLR header (LAS 1.4 specification).
_VLR_HEADER = 54
_EVLR_HEADER = 60


def _check_las_layout(path: Path, size: int) -> None:
    """The LAS header's own counts against the file: the VLRs must fit between the header
    and the point data, the EVLRs after their start offset (laspy would otherwise create
    millions of empty records for a count with one flipped byte, for minutes)."""
    import struct

    with open(path, "rb") as stream:
        head = stream.read(375)
    if len(head) < 227 or head[:4] != b"LASF":
        raise ConfigError("not a LAS/LAZ file (no LASF signature or a header shorter than "
                          "227 bytes)", source=path)
    header_size, offset, vlrs = struct.unpack_from("<HII", head, 94)
    if not header_size <= offset <= size:
        raise ConfigError(f"offset to point data {offset:,} is outside the file ({size:,} "
                          f"bytes, header {header_size} bytes)", source=path,
                          field="offset to point data")
    if vlrs * _VLR_HEADER > offset - header_size:
        raise ConfigError(f"declares {vlrs:,} VLRs ({vlrs * _VLR_HEADER:,} bytes of their "
                          f"headers at least) in the {offset - header_size:,} bytes between "
                          "the header and the points", source=path, field="number of VLRs")
    if head[24:26] >= b"\x01\x04" and len(head) >= 255:
        start, evlrs = struct.unpack_from("<QI", head, 243)
        if evlrs and (start > size or evlrs * _EVLR_HEADER > size - start):
            raise ConfigError(f"declares {evlrs:,} extended VLRs from byte {start:,}, which "
                              f"the file ({size:,} bytes) cannot hold", source=path,
                              field="number of EVLRs")


def read_las(path: str | Path) -> "PointCloud":
    """Read a LAS/LAZ file written by :class:`LasExporter` back into a point cloud
    (see :func:`read_las_columns`).

    Raises
    ------
    ConfigError
        If the file lacks lidarsim's metadata VLR.
    """
    from .columns import cloud_from_columns

    return cloud_from_columns(*read_las_columns(path), source=path,
                              no_metadata="LAS file lacks lidarsim's metadata VLR")


@hookimpl
def lidarsim_register_exporters(register: Any) -> None:
    """Register the LAS and LAZ exporters (laspy is imported only when writing)."""
    register(LasExporter)
    register(LazExporter)
