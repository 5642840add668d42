"""Columns read from a file, and its frame metadata, made into a point cloud: the one step that
every reader ends with (PLY, PCD, LAS/LAZ, NPZ, CSV; :func:`lidarsim_core.io.reader.read`)."""

from __future__ import annotations

import struct
import zipfile
import zlib
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any, Iterator

import numpy as np

from ..base.config_io import check_input_file
from ..base.errors import ConfigError
from ..records.pointcloud import POINT_FIELDS, FrameInfo, PointCloud


def cloud_from_columns(columns: dict[str, np.ndarray], metadata: dict[str, Any] | None, *,
                       source: str | Path,
                       no_metadata: str = "the file holds no lidarsim frame metadata"
                       ) -> PointCloud:
    """The point cloud of ``columns`` read from ``source`` with frame ``metadata``.

    Every point-record column gets its record dtype (an integer column a format stores as
    double, such as PLY's ``ray_index``, is rounded back); further columns are kept as read.

    Raises
    ------
    ConfigError
        Naming ``source``: no metadata (``no_metadata``), metadata that is not lidarsim's, or
        point-record columns missing.
    """
    if metadata is None:
        raise ConfigError(no_metadata, source=source)
    if not isinstance(metadata, dict):
        raise ConfigError(f"frame metadata is a JSON {type(metadata).__name__}, not an object",
                          source=source)
    try:
        frame = FrameInfo.from_dict(metadata)
    except (TypeError, KeyError, ValueError, AttributeError, IndexError) as exc:
        raise ConfigError(f"frame metadata is not lidarsim's ({exc})", source=source) from None
    check_columns(columns, source=source)
    missing = [name for name in POINT_FIELDS if name not in columns]
    if missing:
        raise ConfigError(f"file lacks point-record columns {', '.join(missing)}",
                          source=source, field=missing[0])
    out = {}
    for name, values in columns.items():
        dtype = np.dtype(POINT_FIELDS.get(name, values.dtype))
        if dtype.kind in "iu" and values.dtype.kind == "f":
            values = np.round(values)  # integer columns stored as double (PLY's ray_index)
        out[name] = np.ascontiguousarray(cast_column(values, dtype, source=source, field=name))
    return PointCloud(out, frame)


def cast_column(values: np.ndarray, dtype: np.dtype | str, *, source: str | Path,
                field: str) -> np.ndarray:
    """``values`` as ``dtype``, refused when a value does not fit: NaN, infinities or
    fractions into an integer column, integers beyond its range (NumPy would wrap them or
    cast NaN to an arbitrary integer, silently).

    Raises
    ------
    ConfigError
        Naming ``source`` and the column.
    """
    dtype = np.dtype(dtype)
    if dtype.kind in "iu" and values.dtype.kind in "fiub" and len(values):
        info = np.iinfo(dtype)
        if values.dtype.kind == "f":
            if not np.all(np.isfinite(values)):
                raise ConfigError("integer column holds a value that is not finite",
                                  source=source, field=field)
            if not np.all(values == np.round(values)):
                raise ConfigError("integer column holds a fraction", source=source,
                                  field=field)
        low, high = values.min(), values.max()
        if low < info.min or high > info.max:
            raise ConfigError(f"values {low}..{high} do not fit the column's type {dtype}",
                              source=source, field=field)
    try:
        with np.errstate(all="raise"):  # any other lossy cast (NaN into bool, 1e300 into
            return values.astype(dtype, copy=False)  # float32) is refused, not warned about
    except FloatingPointError:
        raise ConfigError(f"values of type {values.dtype} do not fit the column's type "
                          f"{dtype} (NaN, infinite or too large)", source=source,
                          field=field) from None


#: Exceptions a parser raises on malformed bytes (NumPy, zipfile, json, struct, laspy...);
#: :func:`reader_errors` turns them into one :class:`ConfigError` naming the file.
MALFORMED = (ValueError, KeyError, IndexError, TypeError, EOFError, OverflowError,
             UnicodeDecodeError, LookupError, AttributeError, zipfile.BadZipFile,
             zipfile.LargeZipFile, struct.error, RecursionError, zlib.error,
             NotImplementedError,  # a zip member of an unsupported compression method
             RuntimeError)  # an encrypted zip member


@contextmanager
def reader_errors(path: str | Path, what: str) -> Iterator[None]:
    """Turn a parser's raw exception while reading ``path`` into a :class:`ConfigError`
    naming the file, ``what`` it should be, and the parser's own words (escaped).

    The readers check what they know first (counts against the file's length, column shapes)
    and say so precisely; this is the net under them, so that no malformed byte ever becomes a
    bare ``ValueError`` or ``KeyError``.
    """
    try:
        yield
    except ConfigError:
        raise
    except MALFORMED as exc:
        words = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise ConfigError(f"cannot read {what}: {type(exc).__name__}: {words}",
                          source=path) from None


def check_input(path: str | Path, what: str) -> int:
    """The size of ``path`` after the bounded reader's checks (a regular file, not a FIFO,
    device, directory or dangling link, under the ``data_bytes`` limit)."""
    return check_input_file(path, what, limit_name="data_bytes")


#: Longest text header (PLY, PCD) lidarsim reads; its own are a few KB.
MAX_HEADER_BYTES = 1 << 20


def header_lines(stream: IO[bytes], path: str | Path, what: str, end: str) -> Iterator[str]:
    """The lines of a text header (PLY, PCD) read from ``stream``, decoded, each read with a
    bound; the caller stops at its ``end`` line.

    Raises
    ------
    ConfigError
        At the end of the file before the ``end`` line, or past :data:`MAX_HEADER_BYTES`.
    """
    while True:
        raw = stream.readline(MAX_HEADER_BYTES)
        if not raw:
            raise ConfigError(f"{what} header has no {end} line", source=path)
        if stream.tell() > MAX_HEADER_BYTES:
            raise ConfigError(f"{what} header is longer than {MAX_HEADER_BYTES:,} bytes",
                              source=path)
        yield raw.decode("utf-8", errors="replace").rstrip("\r\n")


def check_record_count(count: object, record_bytes: int, available: int, *,
                       source: str | Path, what: str, field: str) -> int:
    """``count`` records of ``record_bytes`` bytes each, as declared by a header field,
    checked against the ``available`` bytes the file really holds before anything is
    allocated.

    Raises
    ------
    ConfigError
        Naming ``source`` and ``field`` when the count is not a non-negative integer, or
        when the records it declares need more bytes than the file holds.
    """
    text = str(count).strip()
    if not (text.isascii() and text.isdigit()):
        raise ConfigError(f"{what} count {text[:40]!r} is not a non-negative integer",
                          source=source, field=field)
    number = int(text)
    needed = number * record_bytes
    if needed > available:
        raise ConfigError(f"declares {number:,} {what} of {record_bytes} bytes "
                          f"({needed:,} bytes), but the file holds only {available:,} bytes "
                          "of data (truncated, or a false count)", source=source, field=field)
    return number


def check_columns(columns: dict[str, np.ndarray], *, source: str | Path) -> None:
    """Every column one-dimensional, numeric (or boolean), and all of one length.

    Raises
    ------
    ConfigError
        Naming ``source`` and the first offending column.
    """
    length = None
    for name, values in columns.items():
        if values.ndim != 1:
            raise ConfigError(f"column has shape {values.shape}, not one value per point",
                              source=source, field=name)
        if values.dtype.kind not in "biuf":
            raise ConfigError(f"column has type {values.dtype}, not a number type",
                              source=source, field=name)
        if length is None:
            length = len(values)
        elif len(values) != length:
            raise ConfigError(f"column has {len(values):,} values where the others have "
                              f"{length:,}", source=source, field=name)
