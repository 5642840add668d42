"""Built-in plugin: NumPy ``.npz`` with one array per column and the metadata as JSON.

Read back with ``numpy.load(path)``: every point-record column under its name, ``frame_json``
(a 0-d string array holding the frame metadata), and ``part_names`` / ``target_names``.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from ..base.errors import ConfigError
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


def read_npz_columns(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, Any] | None]:
    """The columns and frame metadata of an NPZ cloud (no pickles are read).

    Raises
    ------
    ConfigError
        If the file is not a readable NPZ archive.
    """
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["frame_json"])) if "frame_json" in data.files else None
            columns = {name: data[name] for name in data.files
                       if name not in ("frame_json", "part_names", "target_names")}
    except (OSError, ValueError) as exc:
        raise ConfigError(f"cannot read NPZ: {exc}", source=path) from None
    return columns, meta


def read_npz(path: str | Path) -> "PointCloud":
    """Load a cloud written by :class:`NpzExporter` (no pickles are read)."""
    from .columns import cloud_from_columns

    return cloud_from_columns(*read_npz_columns(path), source=path)


@hookimpl
def lidarsim_register_exporters(register: Any) -> None:
    """Register the NPZ exporter."""
    register(NpzExporter)
