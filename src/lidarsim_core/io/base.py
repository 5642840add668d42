"""Base class of exporter plugins and the atomic write every exporter goes through.

Exporters implement :meth:`Exporter.write_points` (stream from a
:class:`~lidarsim_core.io.points.PointSource` in chunks: memory stays bounded) or, for simple
formats, :meth:`Exporter.write` (a whole in-memory cloud); each has a default in terms of the
other. :func:`write_points_file` and :func:`write_cloud` write atomically and add the sidecar
JSON (:mod:`lidarsim_core.io.sidecar`) that holds the frame metadata for every format.
"""

from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, ClassVar, Iterator

from ..components import Component
from ..errors import OutputError

if TYPE_CHECKING:
    from ..pointcloud import PointCloud
    from .points import PointSource


def _read_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


_UMASK = _read_umask()


class Exporter(Component):
    """Writes point clouds to a binary stream.

    Subclasses set :attr:`suffixes` and implement :meth:`write_points` (streaming, preferred)
    or :meth:`write` (whole cloud in memory); the other one then works too.
    """

    #: File suffixes (lower case, with the dot) that select this exporter.
    suffixes: ClassVar[tuple[str, ...]] = ()
    #: Python distributions whose versions can change the bytes written (recorded in dataset
    #: manifests), e.g. ``("laspy", "lazrs")``.
    requires: ClassVar[tuple[str, ...]] = ()

    def write(self, cloud: "PointCloud", stream: IO[bytes]) -> None:
        """Write ``cloud`` to the open binary ``stream``."""
        if type(self).write_points is Exporter.write_points:
            raise NotImplementedError(f"exporter '{self.name}' implements neither write() nor "
                                      "write_points()")
        from .points import CloudPoints

        self.write_points(CloudPoints(cloud), stream)

    def write_points(self, points: "PointSource", stream: IO[bytes]) -> None:
        """Write the points of ``points`` to the open binary ``stream``, chunk by chunk.

        The default gathers every point in memory and calls :meth:`write`; streaming
        exporters override it.
        """
        if type(self).write is Exporter.write:
            raise NotImplementedError(f"exporter '{self.name}' implements neither write() nor "
                                      "write_points()")
        self.write(points.to_cloud(), stream)


@contextmanager
def atomic_output(path: str | Path, *, overwrite: bool = True) -> Iterator[IO[bytes]]:
    """Open a temporary file beside ``path``; rename it onto ``path`` only on success.

    Nothing is left on disk if the body raises (or the process is interrupted before the
    rename, apart from a hidden ``.part`` file that a signal can strand; it is never the target).
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise OutputError("output path is a directory", source=path)
    if not parent.is_dir():
        raise OutputError(f"output directory does not exist: {parent}", source=path)
    if path.exists() and not overwrite:
        raise OutputError("output file exists (use --overwrite to replace it)", source=path)
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=parent)
    except PermissionError:
        raise OutputError(f"output directory is not writable: {parent}", source=path) from None
    except OSError as exc:
        raise OutputError(f"cannot write here: {exc.strerror}", source=path) from None
    try:
        if hasattr(os, "fchmod"):  # mkstemp makes 0600; give the file the usual permissions
            os.fchmod(fd, 0o666 & ~_UMASK)
        with os.fdopen(fd, "wb") as stream:
            yield stream
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(tmp_name, path)
    except BaseException:
        try:
            os.unlink(tmp_name)
        except FileNotFoundError:
            pass
        raise


def exporter_for(path: str | Path, format: str | None = None) -> Exporter:
    """The exporter selected by ``format`` (a registered name) or by the suffix of ``path``."""
    from ..plugins import get_registry

    registry = get_registry()
    if format:
        return registry.get("exporter", format, field="format")()
    suffix = Path(path).suffix.lower()
    for entry in registry.iter("exporter"):
        if suffix in entry.obj.suffixes:
            return entry.obj()
    known = sorted(s for e in registry.iter("exporter") for s in e.obj.suffixes)
    raise OutputError(f"no exporter for suffix '{suffix or '(none)'}'; known: {', '.join(known)}",
                      source=path)


def write_points_file(points: "PointSource", path: str | Path, *, format: str | None = None,
                      exporter: Exporter | None = None, overwrite: bool = True,
                      sidecar: bool = True) -> dict[str, Any]:
    """Stream ``points`` to ``path`` atomically, then write its sidecar JSON.

    Parameters
    ----------
    points
        The points and frame metadata.
    path
        Output file; its suffix chooses the exporter unless ``format`` or ``exporter`` is given.
    format
        A registered exporter name.
    exporter
        An exporter instance (with its options), instead of ``format``.
    overwrite
        Replace an existing file (otherwise :class:`OutputError`).
    sidecar
        Also write ``<file name>.json`` with the frame metadata and the file's checksum.

    Returns
    -------
    dict
        The sidecar record (file name, exporter, point count, columns, size, SHA-256, frame).
    """
    from .sidecar import sidecar_record, write_sidecar

    exporter = exporter or exporter_for(path, format)
    with atomic_output(path, overwrite=overwrite) as stream:
        exporter.write_points(points, stream)
    record = sidecar_record(path, points, exporter)
    if sidecar:
        write_sidecar(path, record)
    return record


def write_cloud(cloud: "PointCloud", path: str | Path, *, format: str | None = None,
                overwrite: bool = True, sidecar: bool = True) -> Path:
    """Write ``cloud`` to ``path`` atomically with the chosen exporter; returns the path.

    With ``sidecar`` (the default) the frame metadata also goes to ``<file name>.json``.
    """
    from .points import CloudPoints

    write_points_file(CloudPoints(cloud), path, format=format, overwrite=overwrite,
                      sidecar=sidecar)
    return Path(path)
