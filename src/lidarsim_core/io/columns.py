"""Columns read from a file, and its frame metadata, made into a point cloud: the one step that
every reader ends with (PLY, PCD, LAS/LAZ, NPZ, CSV; :func:`lidarsim_core.io.reader.read`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

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
    try:
        frame = FrameInfo.from_dict(metadata)
    except TypeError as exc:
        raise ConfigError(f"frame metadata is not lidarsim's ({exc})", source=source) from None
    missing = [name for name in POINT_FIELDS if name not in columns]
    if missing:
        raise ConfigError(f"file lacks point-record columns {', '.join(missing)}",
                          source=source, field=missing[0])
    out = {}
    for name, values in columns.items():
        dtype = np.dtype(POINT_FIELDS.get(name, values.dtype))
        if dtype.kind in "iu" and values.dtype.kind == "f":
            values = np.round(values)  # integer columns stored as double (PLY's ray_index)
        out[name] = np.ascontiguousarray(values, dtype=dtype)
    return PointCloud(out, frame)
