"""``PointCloud.save()`` and ``PointCloud.range_image()``: shortcuts attached to the record
class from here, the lowest layer that may resolve exporters and scan patterns by name.

The point record (:mod:`lidarsim_core.records.pointcloud`) is a data type and imports no I/O
and no registry; these two methods are set on it when :mod:`lidarsim_core.plugins` is
imported, which everything that hands clouds to users does (:class:`Simulation`,
``ls.read``, ``ls.PointCloud``, the CLI, datasets).
"""

from __future__ import annotations

from pathlib import Path

from ..base.outputs import API_HINT, check_file, make_parent
from ..io.points import CloudPoints
from ..io.rangeimage import RangeImage, range_image
from ..io.sidecar import sidecar_path
from ..io.write import write_points_file
from ..patterns.base import ScanPattern
from ..records.pointcloud import PointCloud
from .resolve import exporter_for, pattern_for_cloud


def write_cloud(cloud: PointCloud, path: str | Path, *, format: str | None = None,
                overwrite: bool = True, sidecar: bool = True) -> Path:
    """Write ``cloud`` to ``path`` atomically with the exporter ``format`` names or the
    path's suffix selects; returns the path.

    With ``sidecar`` (the default) the frame metadata also goes to ``<file name>.json``.
    """
    write_points_file(CloudPoints(cloud), path, exporter_for(path, format), overwrite=overwrite,
                      sidecar=sidecar)
    return Path(path)


def save(self: PointCloud, path: str | Path, *, format: str | None = None,
         overwrite: bool = False) -> Path:
    """Write the cloud with the exporter chosen by ``format`` or the path's suffix.

    The file and its sidecar ``<file name>.json`` are written atomically (temporary
    file, then rename); a missing folder is created. As on the command line, an existing
    file is replaced only with ``overwrite=True`` (:mod:`lidarsim_core.base.outputs`).

    Raises
    ------
    OutputError
        If the file (or its sidecar) exists and ``overwrite`` is False, or the place
        cannot be written.
    """
    check_file(path, overwrite=overwrite, hint=API_HINT)
    check_file(sidecar_path(path), overwrite=overwrite, hint=API_HINT)
    make_parent(path)
    return write_cloud(self, path, format=format, overwrite=overwrite)


def cloud_range_image(self: PointCloud, pattern: ScanPattern | None = None) -> RangeImage:
    """The organised range image of this frame (spinning, flash and raster sensors).

    Parameters
    ----------
    pattern
        The scan pattern that made the cloud (``Simulation(scenario).pattern``); default:
        the catalogue sensor's pattern with its datasheet options.

    Returns
    -------
    lidarsim_core.io.rangeimage.RangeImage
        ``range``, ``intensity``, ``part`` and ``point_index`` arrays (NaN / -1 where
        there is no return); ``.save(path)`` writes NPZ and a 16-bit PNG.
    """
    return range_image(self, pattern if pattern is not None else pattern_for_cloud(self))


def attach() -> None:
    """Set :func:`save` and :func:`cloud_range_image` as ``PointCloud.save`` and
    ``PointCloud.range_image``."""
    cloud_range_image.__name__ = "range_image"
    PointCloud.save = save  # type: ignore[attr-defined]
    PointCloud.range_image = cloud_range_image  # type: ignore[attr-defined]


attach()

__all__: list[str] = ["attach", "cloud_range_image", "save", "write_cloud"]
