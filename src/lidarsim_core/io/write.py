"""Writing a cloud's file: the points streamed atomically through an exporter, then the sidecar
JSON with the frame metadata and the file's checksum."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..base.atomic import atomic_output
from .base import Exporter
from .points import PointSource
from .sidecar import sidecar_record, write_sidecar


def write_points_file(points: PointSource, path: str | Path, exporter: Exporter, *,
                      overwrite: bool = True, sidecar: bool = True) -> dict[str, Any]:
    """Stream ``points`` to ``path`` atomically, then write its sidecar JSON.

    Parameters
    ----------
    points
        The points and frame metadata.
    path
        Output file.
    exporter
        The exporter (with its options); :func:`lidarsim_core.plugins.resolve.exporter_for`
        chooses it by name or suffix.
    overwrite
        Replace an existing file (otherwise :class:`OutputError`).
    sidecar
        Also write ``<file name>.json`` with the frame metadata and the file's checksum.

    Returns
    -------
    dict
        The sidecar record (file name, exporter, point count, columns, size, SHA-256, frame).
    """
    with atomic_output(path, overwrite=overwrite) as stream:
        exporter.write_points(points, stream)
    record = sidecar_record(path, points, exporter)
    if sidecar:
        write_sidecar(path, record)
    return record
