"""Base class of exporter plugins and the atomic write every exporter goes through.

Exporters implement :meth:`Exporter.write_points` (stream from a
:class:`~lidarsim_core.io.points.PointSource` in chunks: memory stays bounded) or, for simple
formats, :meth:`Exporter.write` (a whole in-memory cloud); each has a default in terms of the
other. :func:`write_points_file` and :func:`write_cloud` write atomically and add the sidecar
JSON (:mod:`lidarsim_core.io.sidecar`) that holds the frame metadata for every format.
"""

from __future__ import annotations

import os
import secrets
from contextlib import contextmanager
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, ClassVar, Iterator

from ..components import Component
from ..errors import OutputError, UserInputError

if TYPE_CHECKING:
    from ..pointcloud import PointCloud
    from .points import PointSource


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

    The temporary file is hidden (``.NAME.RANDOM.part``) and never the target. It is removed
    whatever stops the body: an exception, Ctrl-C, or SIGTERM under the CLI (its name is
    chosen before the file is created, so even an interrupt arriving while it is being
    created cannot strand it). Only SIGKILL or a crash can leave one behind; ``lidarsim
    dataset`` removes such leftovers when it resumes.
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise OutputError("output path is a directory", source=path)
    if not parent.is_dir():
        raise OutputError(f"output directory does not exist: {parent}", source=path)
    if os.path.lexists(path) and not overwrite:  # a symbolic link, even a looping one, too
        raise OutputError("output file exists (use --overwrite to replace it)", source=path)
    tmp: Path | None = parent / f".{path.name}.{secrets.token_hex(6)}.part"
    try:
        try:
            # O_EXCL: a name that exists is never ours (and is then left alone); the mode is
            # reduced by the umask as for any new file
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0),
                         0o666)
        except PermissionError:
            tmp = None
            raise OutputError(f"output directory is not writable: {parent}",
                              source=path) from None
        except OSError as exc:
            tmp = None
            raise OutputError(f"cannot write here: {exc.strerror}", source=path) from None
        with os.fdopen(fd, "wb") as stream:
            yield stream
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except FileNotFoundError:
                pass
        if isinstance(exc, UserInputError) and exc.source is None:
            # an exporter's complaint (a column that does not fit the format) names the file
            raise type(exc)(exc.message, source=path, field=exc.field) from None
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            # ENOSPC, EDQUOT, EIO...: one line naming the file, nothing left behind
            from ..guard import describe_os_error

            raise OutputError(f"cannot write: {describe_os_error(exc)}", source=path) from exc
        raise


def write_text_atomic(path: str | Path, text: str, *, overwrite: bool = True) -> Path:
    """Write UTF-8 ``text`` to ``path`` through :func:`atomic_output`; returns the path."""
    with atomic_output(path, overwrite=overwrite) as stream:
        stream.write(text.encode("utf-8"))
    return Path(path)


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
    from ..guard import guard_exporter
    from .sidecar import sidecar_record, write_sidecar

    # a third-party exporter that fails is reported by name (and leaves no file)
    exporter = guard_exporter(exporter or exporter_for(path, format))
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
