"""One reader for every point-cloud format lidarsim writes: :func:`read`.

``ls.read("cloud.ply")`` gives back a :class:`~lidarsim_core.records.pointcloud.PointCloud` with its
frame metadata, whatever the exporter: PLY, PCD, LAS/LAZ and NPZ carry the metadata inside the
file, CSV only in the sidecar JSON (``<file name>.json``), which is used whenever the file has
none of its own. Columns come back with the point record's dtypes (:data:`POINT_FIELDS`);
what a format stores with less precision comes back at that precision (float32 x, y, z in PCD,
``scale_m`` steps in LAS), see ``docs/outputs.md``.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..base.errors import ConfigError
from .dialects import CLOUDCOMPARE_HEADER, record_names
from ..records.pointcloud import POINT_FIELDS, PointCloud
from .columns import cloud_from_columns

#: Suffixes :func:`read` knows (those of the built-in exporters).
READ_SUFFIXES = (".ply", ".pcd", ".las", ".laz", ".npz", ".csv")


def _ply(path: Path) -> tuple[dict[str, np.ndarray], dict[str, Any] | None]:
    from .ply import read_ply_columns

    return read_ply_columns(path)


def _pcd(path: Path) -> tuple[dict[str, np.ndarray], dict[str, Any] | None]:
    from .pcd import read_pcd_columns

    return read_pcd_columns(path)


def _las(path: Path) -> tuple[dict[str, np.ndarray], dict[str, Any] | None]:
    from .las import read_las_columns

    return read_las_columns(path)


def _npz(path: Path) -> tuple[dict[str, np.ndarray], dict[str, Any] | None]:
    from .npz import read_npz_columns

    return read_npz_columns(path)


def _csv(path: Path) -> tuple[dict[str, np.ndarray], dict[str, Any] | None]:
    from .columns import check_input

    check_input(path, "CSV file")
    with open(path, encoding="ascii", errors="strict", newline="") as stream:
        try:
            rows = list(csv.reader(stream))
        except (UnicodeDecodeError, csv.Error) as exc:
            raise ConfigError(f"cannot read CSV: {exc}", source=path) from None
    if not rows:
        raise ConfigError("CSV file is empty (no header row)", source=path)
    names, body = list(rows[0]), rows[1:]
    if names and names[0].startswith(CLOUDCOMPARE_HEADER):  # the cloudcompare dialect
        names[0] = names[0][len(CLOUDCOMPARE_HEADER):]
    names = record_names(names, POINT_FIELDS)
    if any(len(row) != len(names) for row in body):
        raise ConfigError("CSV rows differ in length from the header row", source=path)
    columns: dict[str, np.ndarray] = {}
    for i, name in enumerate(names):
        text = [row[i] for row in body]
        kind = np.dtype(POINT_FIELDS.get(name, "f8")).kind
        try:
            # floats were written in shortest round-trip form: float() gives the same bits
            columns[name] = (np.array([float(v) for v in text], dtype=np.float64) if kind == "f"
                             else np.array([int(v) for v in text], dtype=np.int64))
        except ValueError as exc:
            raise ConfigError(f"CSV value is not a number ({exc})", source=path,
                              field=name) from None
    return columns, None


_READERS: dict[str, Callable[[Path], tuple[dict[str, np.ndarray], dict[str, Any] | None]]] = {
    ".ply": _ply, ".pcd": _pcd, ".las": _las, ".laz": _las, ".npz": _npz, ".csv": _csv}


def read(path: str | Path) -> PointCloud:
    """Read a point cloud written by any lidarsim exporter, with its frame metadata.

    Parameters
    ----------
    path
        A ``.ply``, ``.pcd``, ``.las``, ``.laz``, ``.npz`` or ``.csv`` file written by lidarsim
        (``cloud.save``, ``lidarsim simulate``, ``lidarsim dataset``).

    Returns
    -------
    PointCloud
        Every point-record column with its record dtype (plus any further column the file
        holds), and the frame metadata from the file or, failing that, its sidecar JSON.

    Raises
    ------
    ConfigError
        If the file is missing, of an unknown suffix, unreadable, not a regular file, larger
        than the ``data_bytes`` limit, malformed in any way (counts the file cannot hold,
        truncated records, a column of another shape, length or type, metadata that is not
        JSON), has no frame metadata in it or beside it, or lacks point-record columns. The
        message names the file and the defect.

    Examples
    --------
    >>> import lidarsim_core as ls
    >>> cloud = ls.read("demo-out/envisat_mid70_with_errors.ply")  # doctest: +SKIP
    >>> cloud.frame.targets_in_sensor[0]["translation_m"]           # doctest: +SKIP
    """
    from .sidecar import read_sidecar, sidecar_path

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in _READERS:
        raise ConfigError(f"cannot read suffix '{suffix or '(none)'}'; lidarsim reads "
                          f"{', '.join(READ_SUFFIXES)}", source=path)
    from .columns import check_input, reader_errors

    check_input(path, "point-cloud file")  # a directory, FIFO, device or missing file, named
    with reader_errors(path, f"{suffix[1:].upper()} file"):
        columns, metadata = _READERS[suffix](path)
    if metadata is None:
        if not sidecar_path(path).is_file():
            raise ConfigError("the file holds no lidarsim frame metadata and has no sidecar "
                              f"{sidecar_path(path).name}", source=path)
        metadata = read_sidecar(path)["frame"]
    return cloud_from_columns(columns, metadata, source=path)
