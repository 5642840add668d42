"""Reading scan-pattern tables: Livox scan-mode CSV files and generic CSV/NPY tables.

Formats
-------
``livox``
    CSV with the header ``Time/s,Azimuth/deg,Zenith/deg`` as in Livox's published scan-mode
    files. Zenith is the polar angle from +Z (so elevation = 90° − zenith), azimuth is measured
    from +X toward +Y; both in degrees.
``generic`` (CSV)
    A header naming the columns ``t_s`` (or ``time_s``), ``azimuth_deg``, ``elevation_deg`` and
    optionally ``channel``, in any order; one ray per line.
``generic`` (NPY)
    A structured array with those field names, or a 2-D numeric array whose columns are
    ``t_s, azimuth_deg, elevation_deg[, channel]``.

Times are taken relative to the first row and must not decrease. Every problem (wrong columns,
non-numeric or non-finite values, no rows, angles out of range, times going backwards) raises a
:class:`~lidarsim_core.base.errors.PatternFileError` naming the file, the column and the line.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from ..base.errors import PatternFileError

LIVOX_COLUMNS = ("Time/s", "Azimuth/deg", "Zenith/deg")
GENERIC_COLUMNS = ("t_s", "azimuth_deg", "elevation_deg", "channel")
_TIME_ALIASES = ("t_s", "time_s")
_EXPECTED = ("expected the Livox header 'Time/s,Azimuth/deg,Zenith/deg' or the columns "
             "t_s, azimuth_deg, elevation_deg[, channel]")

TableFormat = Literal["auto", "livox", "generic"]


@dataclass(frozen=True)
class PatternTable:
    """A scan pattern read from a file (angles in radians, times in seconds from row 0)."""

    t: np.ndarray
    azimuth: np.ndarray
    elevation: np.ndarray
    channel: np.ndarray

    def __len__(self) -> int:
        return len(self.t)


def resolve_table_path(text: str) -> Path:
    """A file path, or ``pkg:MODULE/relative/path`` for a file shipped inside a Python package.

    ``MODULE`` is located without being imported (a configuration file never runs code): it
    must be a top-level package, or a module already imported (e.g. a loaded plugin).
    """
    if text.startswith("pkg:"):
        module, _, rel = text[4:].partition("/")
        if not module or not rel:
            raise PatternFileError("a 'pkg:' path needs the form pkg:MODULE/relative/path",
                                   source=text)
        return _package_dir(module, rel, text) / rel
    return Path(text).expanduser()


def _package_dir(module: str, rel: str, text: str) -> Path:
    import importlib.util
    import sys

    loaded = sys.modules.get(module)
    spec = getattr(loaded, "__spec__", None)
    if spec is None:
        if "." in module:  # finding a submodule would import (run) its parent packages
            raise PatternFileError(f"'{module}' is not imported: a 'pkg:' path names a "
                                   "top-level package or a loaded plugin module", source=text)
        try:
            spec = importlib.util.find_spec(module)  # locates a top-level module, runs nothing
        except (ImportError, ValueError):
            spec = None
    if spec is None:
        raise PatternFileError(f"package '{module}' is not installed", source=text)
    places = [Path(p) for p in (spec.submodule_search_locations or [])]
    if not places and spec.origin:
        places = [Path(spec.origin).parent]
    if not places:
        raise PatternFileError(f"package '{module}' has no files on disk", source=text)
    return next((p for p in places if (p / rel).exists()), places[0])


def read_pattern_table(path: str | Path, fmt: TableFormat = "auto") -> PatternTable:
    """Read and validate a scan-pattern table.

    Parameters
    ----------
    path
        The file (``.csv``/``.txt`` or ``.npy``).
    fmt
        ``"livox"``, ``"generic"`` or ``"auto"`` (by suffix and header).

    Raises
    ------
    PatternFileError
        Naming the file, the column and the line of the first problem.
    """
    from ..base.config_io import check_input_file

    path = Path(path)
    # the bounded reader's checks: missing, devices, FIFOs, link loops, directories, size
    check_input_file(path, "pattern file", error=PatternFileError,
                     limit_name="data_bytes" if path.suffix.lower() == ".npy" else
                     "config_bytes")
    if path.suffix.lower() == ".npy":
        if fmt == "livox":
            raise PatternFileError("Livox scan-mode files are CSV, not NPY", source=path)
        return _from_npy(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise PatternFileError(f"cannot read the file: {exc}", source=path) from None
    return _from_csv(path, text, fmt)


def _from_csv(path: Path, text: str, fmt: TableFormat) -> PatternTable:
    rows = [(n, r) for n, r in enumerate(csv.reader(io.StringIO(text)), start=1)
            if r and any(c.strip() for c in r)]
    if not rows:
        raise PatternFileError("the file is empty", source=path)
    header_line, header = rows[0]
    names = [h.strip() for h in header]
    is_livox = [n.lower() for n in names] == [c.lower() for c in LIVOX_COLUMNS]
    if fmt == "livox" and not is_livox:
        raise PatternFileError(f"line {header_line}: header is {','.join(names)!r}; "
                               f"expected 'Time/s,Azimuth/deg,Zenith/deg'", source=path)
    data = rows[1:]
    if not data:
        raise PatternFileError("no data rows after the header", source=path)
    if is_livox and fmt != "generic":
        cols = _numeric_columns(path, data, list(LIVOX_COLUMNS))
        _check_range(path, cols["Zenith/deg"], 0.0, 180.0, "Zenith/deg", data)
        _check_range(path, cols["Azimuth/deg"], -360.0, 360.0, "Azimuth/deg", data)
        return _table(path, cols["Time/s"], cols["Azimuth/deg"], 90.0 - cols["Zenith/deg"],
                      None, lines=[n for n, _ in data])
    index = _generic_index(path, names)
    cols = _numeric_columns(path, data, names)
    chan = cols[names[index["channel"]]] if "channel" in index else None
    return _table(path, cols[names[index["t_s"]]], cols[names[index["azimuth_deg"]]],
                  cols[names[index["elevation_deg"]]], chan, lines=[n for n, _ in data])


def _generic_index(path: Path, names: list[str]) -> dict[str, int]:
    lowered = [n.lower() for n in names]
    index: dict[str, int] = {}
    for i, name in enumerate(lowered):
        key = "t_s" if name in _TIME_ALIASES else name
        if key not in GENERIC_COLUMNS:
            raise PatternFileError(f"unknown column {names[i]!r}; {_EXPECTED}", source=path)
        if key in index:
            raise PatternFileError(f"column {names[i]!r} appears twice", source=path)
        index[key] = i
    missing = [c for c in GENERIC_COLUMNS[:3] if c not in index]
    if missing:
        raise PatternFileError(f"missing column(s) {', '.join(missing)}; {_EXPECTED}",
                               source=path)
    return index


def _numeric_columns(path: Path, data: list[tuple[int, list[str]]],
                     names: list[str]) -> dict[str, np.ndarray]:
    width = len(names)
    for line, row in data:
        if len(row) != width:
            raise PatternFileError(f"line {line} has {len(row)} fields, expected {width}",
                                   source=path)
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(names):
        raw = [row[j].strip() for _, row in data]
        try:
            values = np.array(raw, dtype=np.float64)
        except ValueError:
            for (line, _), cell in zip(data, raw):
                try:
                    float(cell)
                except ValueError:
                    raise PatternFileError(f"line {line}: {cell!r} is not a number",
                                           source=path, field=name) from None
            raise
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            raise PatternFileError(f"line {data[bad[0]][0]}: value {raw[bad[0]]!r} is not "
                                   "finite", source=path, field=name)
        out[name] = values
    return out


def _check_range(path: Path, values: np.ndarray, lo: float, hi: float, name: str,
                 data: list[tuple[int, list[str]]] | None = None) -> None:
    bad = np.flatnonzero((values < lo) | (values > hi))
    if len(bad):
        where = f"line {data[bad[0]][0]}" if data is not None else f"row {bad[0]}"
        raise PatternFileError(f"{where}: {values[bad[0]]:g} is outside [{lo:g}, {hi:g}]",
                               source=path, field=name)


def _check_npy_size(path: Path) -> None:
    """Refuse an NPY file whose header declares more data than the file holds (a shape of
    2^36 rows in a 1 KB file), before NumPy allocates it."""
    fmt = np.lib.format
    with path.open("rb") as stream:
        version = fmt.read_magic(stream)
        if version == (1, 0):
            shape, _, dtype = fmt.read_array_header_1_0(stream)
        else:
            shape, _, dtype = fmt.read_array_header_2_0(stream)
        header = stream.tell()
    if dtype.hasobject:  # its size says nothing: np.load refuses it below, by name
        return
    needed = int(np.prod(shape, dtype=object)) * dtype.itemsize
    size = path.stat().st_size
    if needed != size - header:
        raise PatternFileError(f"the NPY header declares shape {shape} of {dtype} "
                               f"({needed:,} bytes) but the file holds {size - header:,} "
                               "bytes of data", source=path)


def _from_npy(path: Path) -> PatternTable:
    try:
        with path.open("rb") as stream:
            magic = stream.read(len(np.lib.format.MAGIC_PREFIX))
        if magic != np.lib.format.MAGIC_PREFIX:
            raise PatternFileError("not a .npy file (no NumPy array header)", source=path)
        _check_npy_size(path)  # the shape its header declares, against the file's length
        # never unpickle: a pattern table is numbers, and a pickle could run code
        arr = np.load(path, allow_pickle=False)
    except OSError as exc:
        raise PatternFileError(f"cannot read the file: {exc.strerror}", source=path) from None
    except ValueError as exc:
        reason = "it holds Python objects (pickles are never loaded)" \
            if "allow_pickle" in str(exc) else " ".join(str(exc).split())
        raise PatternFileError(f"not a readable .npy array: {reason}", source=path) from None
    if arr.dtype.names:
        index = _generic_index(path, list(arr.dtype.names))
        names = list(arr.dtype.names)

        def col(key: str) -> np.ndarray:
            return _npy_numeric(path, arr[names[index[key]]], names[index[key]])

        chan = col("channel") if "channel" in index else None
        if arr.ndim != 1 or len(arr) == 0:
            raise PatternFileError("the array has no rows", source=path)
        return _table(path, col("t_s"), col("azimuth_deg"), col("elevation_deg"), chan)
    if arr.ndim != 2 or arr.shape[1] not in (3, 4):
        raise PatternFileError(f"array of shape {arr.shape}: expected (N, 3) or (N, 4) columns "
                               "t_s, azimuth_deg, elevation_deg[, channel]", source=path)
    if arr.shape[0] == 0:
        raise PatternFileError("the array has no rows", source=path)
    cols = [_npy_numeric(path, arr[:, j], GENERIC_COLUMNS[j]) for j in range(arr.shape[1])]
    return _table(path, cols[0], cols[1], cols[2], cols[3] if len(cols) == 4 else None)


def _npy_numeric(path: Path, values: np.ndarray, name: str) -> np.ndarray:
    if not (np.issubdtype(values.dtype, np.number) or values.dtype == np.bool_):
        raise PatternFileError(f"column of dtype {values.dtype} is not numeric", source=path,
                               field=name)
    values = values.astype(np.float64)
    bad = np.flatnonzero(~np.isfinite(values))
    if len(bad):
        raise PatternFileError(f"row {bad[0]}: value is not finite", source=path, field=name)
    return values


def _table(path: Path, t: np.ndarray, az_deg: np.ndarray, el_deg: np.ndarray,
           channel: np.ndarray | None, lines: list[int] | None = None) -> PatternTable:
    data = [(n, []) for n in lines] if lines is not None else None
    _check_range(path, az_deg, -360.0, 360.0, "azimuth_deg", data)
    _check_range(path, el_deg, -90.0, 90.0, "elevation_deg", data)
    back = np.flatnonzero(np.diff(t) < 0)
    if len(back):
        row = back[0] + 1
        where = f"line {lines[row]}" if lines is not None else f"row {row}"
        raise PatternFileError(f"{where}: time {t[row]:g} s is before the previous row's "
                               f"{t[row - 1]:g} s (times must not decrease)", source=path,
                               field="time")
    if channel is None:
        chan = np.zeros(len(t), dtype=np.int16)
    else:
        bad = np.flatnonzero((channel != np.round(channel)) | (channel < 0) | (channel > 32767))
        if len(bad):
            where = f"line {lines[bad[0]]}" if lines is not None else f"row {bad[0]}"
            raise PatternFileError(f"{where}: channel {channel[bad[0]]:g} is not an integer "
                                   "in 0..32767", source=path, field="channel")
        chan = channel.astype(np.int16)
    return PatternTable(t - t[0], np.radians(az_deg), np.radians(el_deg), chan)
