"""Built-in plugin: NumPy ``.npz`` with one array per column and the metadata as JSON.

Read back with ``numpy.load(path)``: every point-record column under its name, ``frame_json``
(a 0-d string array holding the frame metadata), and ``part_names`` / ``target_names``.
"""

from __future__ import annotations

from typing import IO, TYPE_CHECKING, Any

import numpy as np

from ..hookspecs import hookimpl
from .base import Exporter

if TYPE_CHECKING:
    from ..pointcloud import PointCloud


class NpzExporter(Exporter):
    """Compressed NumPy archive with every column at full precision and the frame metadata."""

    name = "npz"
    suffixes = (".npz",)

    def write(self, cloud: "PointCloud", stream: IO[bytes]) -> None:
        np.savez_compressed(
            stream, **cloud.columns, frame_json=np.array(cloud.metadata_json()),
            part_names=np.array(cloud.frame.part_names, dtype=str),
            target_names=np.array(cloud.frame.target_names, dtype=str))


def read_npz(path: Any) -> "PointCloud":
    """Load a cloud written by :class:`NpzExporter` (no pickles are read)."""
    import json

    from ..pointcloud import POINT_FIELDS, FrameInfo, PointCloud

    with np.load(path, allow_pickle=False) as data:
        columns = {k: data[k] for k in POINT_FIELDS}
        frame = FrameInfo.from_dict(json.loads(str(data["frame_json"])))
    return PointCloud(columns, frame)


@hookimpl
def lidarsim_register_exporters(register: Any) -> None:
    """Register the NPZ exporter."""
    register(NpzExporter)
