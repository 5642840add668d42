"""Base class of exporter plugins and the atomic write every exporter goes through."""

from __future__ import annotations

import os
import tempfile
from abc import abstractmethod
from contextlib import contextmanager
from pathlib import Path
from typing import IO, TYPE_CHECKING, ClassVar, Iterator

from ..components import Component
from ..errors import OutputError

if TYPE_CHECKING:
    from ..pointcloud import PointCloud


class Exporter(Component):
    """Writes a :class:`~lidarsim_core.pointcloud.PointCloud` to a binary stream.

    Subclasses set :attr:`suffixes` and implement :meth:`write`.
    """

    #: File suffixes (lower case, with the dot) that select this exporter.
    suffixes: ClassVar[tuple[str, ...]] = ()

    @abstractmethod
    def write(self, cloud: "PointCloud", stream: IO[bytes]) -> None:
        """Write ``cloud`` to the open binary ``stream``."""


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
    except OSError as exc:
        raise OutputError(f"cannot write here: {exc.strerror}", source=path) from None
    try:
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


def write_cloud(cloud: "PointCloud", path: str | Path, *, format: str | None = None,
                overwrite: bool = True) -> Path:
    """Write ``cloud`` to ``path`` atomically with the chosen exporter; returns the path."""
    exporter = exporter_for(path, format)
    with atomic_output(path, overwrite=overwrite) as stream:
        exporter.write(cloud, stream)
    return Path(path)
