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
    memory_stream = True

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

    Before anything is inflated, every member's declared size is checked: the archive as a
    whole inflates to no more than the ``data_bytes`` limit (a zip bomb is refused by its
    directory), and each member's NPY header (shape × item size) agrees with the member's
    size. Object arrays (pickles) are refused, and the columns are checked by
    :func:`~lidarsim_core.io.columns.cloud_from_columns` (1-D, numbers, one length).

    Raises
    ------
    ConfigError
        Naming the file and the defect, if it is not an NPZ archive lidarsim can read.
    """
    from ..base.limits import LIMITS, limit
    from .columns import check_input, reader_errors

    path = Path(path)
    check_input(path, "NPZ file")
    bound = limit("data_bytes")
    columns: dict[str, np.ndarray] = {}
    meta = None
    with reader_errors(path, "NPZ file"), zipfile.ZipFile(path) as archive:
        members = archive.infolist()
        inflated = sum(info.file_size for info in members)
        if inflated > bound:
            raise ConfigError(f"NPZ archive inflates to {inflated:,} bytes, over the limit of "
                              f"{bound:,.0f} (set {LIMITS['data_bytes'].env} to raise it)",
                              source=path)
        for info in members:
            if not info.filename.endswith(".npy") or info.is_dir():
                raise ConfigError(f"NPZ member '{info.filename}' is not an .npy array",
                                  source=path, field=info.filename)
            name = info.filename[:-len(".npy")]
            with archive.open(info) as member:
                array = _read_member(member, info.file_size, path, name)
            if name == "frame_json":
                if array.ndim != 0 or array.dtype.kind != "U":
                    raise ConfigError("frame_json is not one string", source=path,
                                      field="frame_json")
                try:
                    meta = json.loads(str(array))
                except ValueError as exc:
                    raise ConfigError(f"frame_json is not JSON ({exc})", source=path,
                                      field="frame_json") from None
            elif name not in ("part_names", "target_names"):
                columns[name] = array
    return columns, meta


def _read_member(member: IO[bytes], size: int, path: Path, name: str) -> np.ndarray:
    """One ``.npy`` member, its header checked against its declared size before the data
    is read (no pickles)."""
    fmt = np.lib.format
    version = fmt.read_magic(member)
    if version == (1, 0):
        shape, fortran, dtype = fmt.read_array_header_1_0(member)
    elif version in ((2, 0), (3, 0)):
        shape, fortran, dtype = fmt.read_array_header_2_0(member)
    else:
        raise ConfigError(f"NPY format version {version} is not supported", source=path,
                          field=name)
    if dtype.hasobject:
        raise ConfigError("array holds Python objects (a pickle), which lidarsim never loads "
                          "(allow_pickle=False)", source=path, field=name)
    needed = int(np.prod(shape, dtype=object)) * dtype.itemsize
    header = member.tell()
    if needed != size - header:
        raise ConfigError(f"NPY header declares shape {shape} of {dtype} ({needed:,} bytes) "
                          f"but the member holds {size - header:,} bytes", source=path,
                          field=name)
    data = bytearray(needed)  # one writable buffer, filled in place
    got = member.readinto(data) if needed else 0
    if got != needed:
        raise ConfigError(f"array is truncated: {got:,} of {needed:,} bytes",
                          source=path, field=name)
    array = np.frombuffer(data, dtype=dtype)
    return array.reshape(shape, order="F" if fortran else "C")


def read_npz(path: str | Path) -> "PointCloud":
    """Load a cloud written by :class:`NpzExporter` (no pickles are read)."""
    from .columns import cloud_from_columns

    return cloud_from_columns(*read_npz_columns(path), source=path)


@hookimpl
def lidarsim_register_exporters(register: Any) -> None:
    """Register the NPZ exporter."""
    register(NpzExporter)
