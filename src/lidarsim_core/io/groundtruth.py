"""Ground-truth pose files for a sequence of frames (one JSON or CSV file per sequence).
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

from ..base.config_io import read_json_file
from ..base.errors import ConfigError, OutputError

if TYPE_CHECKING:  # pragma: no cover
    from ..records.pointcloud import FrameInfo
from ..records.groundtruth import FORMAT_NAME, QUATERNION_FIELDS, ground_truth


def _csv_columns() -> list[str]:
    cols = ["frame", "t_start_s", "t_end_s", "cloud", "target"]
    for end in ("", "_end"):
        for q in QUATERNION_FIELDS:
            cols += [f"{q}{end}_{a}" for a in "xyzw"]
            r = "r" + q[1:]
            cols += [f"{r}{end}_{a}_m" for a in "xyz"]
    return cols


def _csv_text(data: dict[str, Any]) -> str:
    buffer = io.StringIO(newline="")
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(_csv_columns())
    for fr in data["frames"]:
        for tg in fr["targets"]:
            row: list[Any] = [fr["frame"], repr(fr["t_start_s"]), repr(fr["t_end_s"]),
                              fr["cloud"] or "", tg["name"]]
            for end in ("", "_end"):
                for q in QUATERNION_FIELDS:
                    source = fr if q.startswith("q_sensor") else tg
                    row += [repr(v) for v in source[f"{q}{end}"]]
                    row += [repr(v) for v in source[f"r{q[1:]}{end}_m"]]
            writer.writerow(row)
    return buffer.getvalue()


def _json_text(data: dict[str, Any]) -> str:
    """Indented header, one compact line per frame (readable and diff-friendly)."""
    header = {k: v for k, v in data.items() if k != "frames"}
    head = json.dumps(header, indent=1)[:-2]
    frames = ",\n".join("  " + json.dumps(fr) for fr in data["frames"])
    return f'{head},\n "frames": [\n{frames}\n ]\n}}\n'


def write_ground_truth(path: str | Path, infos: Sequence["FrameInfo"], *,
                       clouds: Sequence[str | None] | None = None,
                       overwrite: bool = True) -> Path:
    """Write the poses of a sequence to ``path`` (``.json`` or ``.csv``), atomically.

    Raises
    ------
    OutputError
        Unknown suffix, existing file without ``overwrite``, or an unwritable place.
    """
    from ..base.atomic import write_text_atomic

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".json", ".csv"):
        raise OutputError(f"unknown pose-file format '{suffix or '(none)'}'; use .json or .csv",
                          source=path)
    data = ground_truth(infos, clouds)
    text = _csv_text(data) if suffix == ".csv" else _json_text(data)
    write_text_atomic(path, text, overwrite=overwrite)
    return path


def read_ground_truth(path: str | Path) -> dict[str, Any]:
    """Read a JSON pose file written by :func:`write_ground_truth`.

    Raises
    ------
    ConfigError
        If the file is missing, not JSON, or not a lidarsim pose file.
    """
    path = Path(path)
    data = read_json_file(path, "pose file")
    if not isinstance(data, dict) or data.get("format") != FORMAT_NAME:
        raise ConfigError(f"not a {FORMAT_NAME} JSON file", source=path, field="format")
    return data
