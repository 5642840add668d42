"""Base class of exporter plugins, and the streaming write every exporter goes through.

Exporters implement :meth:`Exporter.write_points` (stream from a
:class:`~lidarsim_core.io.points.PointSource` in chunks: memory stays bounded) or, for simple
formats, :meth:`Exporter.write` (a whole in-memory cloud); each has a default in terms of the
other. :func:`write_points_file` writes atomically (:func:`lidarsim_core.base.atomic.atomic_output`)
and adds the sidecar JSON (:mod:`lidarsim_core.io.sidecar`) that holds the frame metadata for every format.
"""

from __future__ import annotations

from typing import IO, TYPE_CHECKING, ClassVar

from ..base.components import Component

if TYPE_CHECKING:
    from ..records.pointcloud import PointCloud
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
    #: Whether :meth:`write_points` writes the same bytes to an in-memory buffer as to a file
    #: (it needs no file descriptor or file name): :func:`~lidarsim_core.io.write.write_points_file`
    #: then encodes a frame in memory, hashes those bytes and writes them with one call.
    memory_stream: ClassVar[bool] = False

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
