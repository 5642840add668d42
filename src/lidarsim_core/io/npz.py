"""Built-in plugin: NumPy ``.npz`` with one array per column and the metadata as JSON.

Read back with ``numpy.load(path)``: every point-record column under its name, ``frame_json``
(a 0-d string array holding the frame metadata), and ``part_names`` / ``target_names``.
"""

from __future__ import annotations

import zipfile
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from ..hookspecs import hookimpl
from .base import Exporter

if TYPE_CHECKING:
    from ..records.pointcloud import PointCloud
    from .points import PointSource


class NpzExporter(Exporter):
    """Compressed NumPy archive with every column at full precision and the frame metadata."""

    name = "npz"
    suffixes = (".npz",)

    def write_points(self, points: "PointSource", stream: IO[bytes]) -> None:
        # the layout of numpy.savez_compressed, written one column at a time in chunks
        with zipfile.ZipFile(stream, mode="w", compression=zipfile.ZIP_DEFLATED,
                             allowZip64=True) as archive:
            for name, dtype in points.fields.items():
                with archive.open(f"{name}.npy", mode="w", force_zip64=True) as member:
                    np.lib.format.write_array_header_1_0(member, {
                        "descr": np.lib.format.dtype_to_descr(dtype), "fortran_order": False,
                        "shape": (len(points),)})
                    for chunk in points.iter_chunks([name]):
                        member.write(chunk[name].tobytes())
            extras = {"frame_json": np.array(points.metadata_json()),
                      "part_names": np.array(points.frame.part_names, dtype=str),
                      "target_names": np.array(points.frame.target_names, dtype=str)}
            for name, array in extras.items():
                with archive.open(f"{name}.npy", mode="w", force_zip64=True) as member:
                    np.lib.format.write_array(member, array, allow_pickle=False)


def read_npz(path: Any) -> "PointCloud":
    """Load a cloud written by :class:`NpzExporter` (no pickles are read)."""
    import json

    from ..records.pointcloud import POINT_FIELDS, FrameInfo, PointCloud

    with np.load(path, allow_pickle=False) as data:
        columns = {k: data[k] for k in POINT_FIELDS}
        frame = FrameInfo.from_dict(json.loads(str(data["frame_json"])))
    return PointCloud(columns, frame)


@hookimpl
def lidarsim_register_exporters(register: Any) -> None:
    """Register the NPZ exporter."""
    register(NpzExporter)
