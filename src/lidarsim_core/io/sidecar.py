"""The sidecar JSON written beside every exported point-cloud file.

Whatever room a format has for metadata, ``<file name>.json`` (e.g. ``frame_000000.las.json``)
always holds the frame metadata (poses, sensor, seed, configuration hash...), what the file
contains and its checksum::

    {"format": "lidarsim-frame", "version": 1, "file": "frame_000000.las", "exporter": "las",
     "points": 51234, "columns": [["x", "float64"], ...], "bytes": 6012345,
     "sha256": "…", "frame": {… FrameInfo …}}

The content depends only on the file and its frame (no dates, no host names), so regenerating
a frame regenerates its sidecar bit for bit. Datasets use a present, readable sidecar whose
file has the recorded size as the mark of a finished frame: it is written, atomically, only
after its data file.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..base.atomic import write_text_atomic
from ..base.config_io import read_json_file
from ..base.errors import ConfigError
from ..base.jsontext import indented_json

if TYPE_CHECKING:
    import numpy as np

    from .base import Exporter
    from .points import PointSource

SIDECAR_FORMAT = "lidarsim-frame"
SIDECAR_VERSION = 1
_READ_BLOCK = 4 * 2 ** 20


def sidecar_path(path: str | Path) -> Path:
    """The sidecar of ``path``: the same name with ``.json`` appended."""
    path = Path(path)
    return path.with_name(path.name + ".json")


def sha256_file(path: str | Path) -> str:
    """Hex SHA-256 of a file, read in blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        while block := stream.read(_READ_BLOCK):
            digest.update(block)
    return digest.hexdigest()


def sidecar_record(path: str | Path, points: "PointSource", exporter: "Exporter", *,
                   size: int | None = None, sha256: str | None = None) -> dict[str, Any]:
    """The sidecar content for the finished file ``path`` holding ``points``; its ``size``
    and ``sha256`` are read from the file unless given (from the bytes just written)."""
    path = Path(path)
    return {"format": SIDECAR_FORMAT, "version": SIDECAR_VERSION, "file": path.name,
            "exporter": exporter.name, "points": len(points),
            "columns": [list(pair) for pair in _column_names(tuple(points.fields.items()))],
            "bytes": path.stat().st_size if size is None else size,
            "sha256": sha256_file(path) if sha256 is None else sha256,
            "frame": points.frame.to_dict()}


@functools.lru_cache(maxsize=64)
def _column_names(fields: tuple[tuple[str, "np.dtype"], ...]) -> tuple[tuple[str, str], ...]:
    # NumPy builds a dtype's name anew each time (~1.5 µs a column): once per layout
    return tuple((name, dtype.name) for name, dtype in fields)


def sidecar_text(record: dict[str, Any]) -> str:
    """The sidecar file's text: ``json.dumps(record, indent=1, sort_keys=True)`` and a line
    end (:func:`~lidarsim_core.base.jsontext.indented_json`, the same text faster)."""
    # the parts that are the same in every frame of a sequence (the columns; the part,
    # target and noise names) as tuples: each is encoded once (the same text)
    columns = record.get("columns")
    if isinstance(columns, list) and all(isinstance(c, list) for c in columns):
        record = {**record, "columns": tuple(tuple(c) for c in columns)}
    frame = record.get("frame")
    if isinstance(frame, dict):
        record = {**record, "frame": {key: _names(value) for key, value in frame.items()}}
    return indented_json(record) + "\n"


def _names(value: Any) -> Any:
    """``value`` as a tuple if it is a list of strings, else as it is."""
    if type(value) is list and all(type(item) is str for item in value):
        return tuple(value)
    return value


def write_sidecar(path: str | Path, record: dict[str, Any]) -> Path:
    """Write ``record`` atomically to the sidecar of ``path``; returns the sidecar's path."""
    return write_text_atomic(sidecar_path(path), sidecar_text(record))


def read_sidecar(path: str | Path) -> dict[str, Any]:
    """Read the sidecar of the point-cloud file ``path`` (or a sidecar path itself).

    Raises
    ------
    ConfigError
        If it is missing, not JSON, or not a lidarsim sidecar.
    """
    path = Path(path)
    target = path if path.name.endswith(".json") else sidecar_path(path)
    data = read_json_file(target, "sidecar file")
    if not isinstance(data, dict) or data.get("format") != SIDECAR_FORMAT:
        raise ConfigError(f"not a {SIDECAR_FORMAT} sidecar", source=target, field="format")
    return data


def frame_is_complete(path: str | Path, *, verify: bool = False) -> dict[str, Any] | None:
    """The sidecar record if ``path`` is a finished export, else ``None``.

    Finished means: the sidecar reads, names this file, and the file has the recorded size
    (and, with ``verify``, the recorded SHA-256).
    """
    path = Path(path)
    try:
        record = read_sidecar(path)
        size = path.stat().st_size
    except (ConfigError, OSError):
        return None
    if record.get("file") != path.name or record.get("bytes") != size:
        return None
    if verify and record.get("sha256") != sha256_file(path):
        return None
    return record
