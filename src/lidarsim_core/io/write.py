"""Writing a cloud's file: the points streamed atomically through an exporter, then the sidecar
JSON with the frame metadata and the file's checksum.

A frame whose points are in memory (up to :data:`BUFFER_LIMIT` bytes of records) is encoded
into an in-memory buffer when its exporter allows it (:attr:`Exporter.memory_stream
<lidarsim_core.io.base.Exporter.memory_stream>`): its checksum and size come from those bytes
and the file and its sidecar are written together
(:func:`~lidarsim_core.io.filegroup.write_files_atomic`: one compiled call where it can be),
instead of streaming to the file and reading it back to hash it. The bytes are the same
either way.
"""

from __future__ import annotations

import hashlib
import io
from pathlib import Path
from typing import Any

from ..base.atomic import atomic_output
from ..base.errors import UserInputError
from .base import Exporter
from .points import PointSource
from .filegroup import write_files_atomic
from .sidecar import sidecar_path, sidecar_record, sidecar_text, write_sidecar

#: Largest frame (bytes of its point records) encoded in memory before it is written; larger
#: ones stream to their file chunk by chunk, as before.
BUFFER_LIMIT = 16 * 2 ** 20


def _buffered(points: PointSource, exporter: Exporter) -> bool:
    if not getattr(exporter, "memory_stream", False):
        return False
    row = sum(dtype.itemsize for dtype in points.fields.values())
    return len(points) * row <= BUFFER_LIMIT


def encode_points(points: PointSource, exporter: Exporter, path: str | Path) -> memoryview:
    """The bytes ``exporter`` writes for ``points``, encoded in memory (an exporter's
    complaint names ``path``, as a write to the file would)."""
    buffer = io.BytesIO()
    try:
        exporter.write_points(points, buffer)
    except UserInputError as exc:
        if exc.source is None:
            raise type(exc)(exc.message, source=Path(path), field=exc.field) from None
        raise
    return buffer.getbuffer()


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
    if not _buffered(points, exporter):
        with atomic_output(path, overwrite=overwrite) as stream:
            exporter.write_points(points, stream)
        record = sidecar_record(path, points, exporter)
        if sidecar:
            write_sidecar(path, record)
        return record
    data = encode_points(points, exporter, path)
    try:
        record = sidecar_record(path, points, exporter, size=len(data),
                                sha256=hashlib.sha256(data).hexdigest())
        files = [(path, data)]
        if sidecar:
            files.append((sidecar_path(path), sidecar_text(record).encode("utf-8")))
        # in one compiled call where it can be (io.filegroup): the file, then its sidecar
        write_files_atomic(files, overwrite=(overwrite, True)[:len(files)])
    finally:
        data.release()
    return record
