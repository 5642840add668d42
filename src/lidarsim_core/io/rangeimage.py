"""Organised range images of sensors with a regular layout.

=========  ===================================================================================
pattern    image
=========  ===================================================================================
spinning   channels × firing cycles of the frame (one column per azimuth step; a frame of one
           revolution, ``duration_s = 1 / rotation_hz``, gives the columns of one revolution);
           rows ordered by elevation, highest first (:attr:`RangeImage.row_channel` gives each
           row's channel), columns in firing order
flash      the detector array, rows × columns, row-major from the top-left pixel (one flash)
raster     lines × samples of one raster frame, in scan order, backward lines of a
           bidirectional raster turned round so every row runs the same way
=========  ===================================================================================

Every pixel holds the first detected return of its ray (lowest ``return_number``): range (m),
intensity and part, NaN / NaN / -1 where there is none, and ``point_index``, the row of the
cloud it came from (-1 for none). The layout comes from the scan pattern; the cloud's nominal
``azimuth`` and ``elevation`` are checked against it, so a pattern other than the one that made
the cloud is refused rather than producing a scrambled image.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..base.errors import ConfigError

if TYPE_CHECKING:
    from ..patterns.base import ScanPattern
    from ..records.pointcloud import PointCloud


#: Largest angle (rad) between a cloud's nominal directions and the pattern's that is accepted.
_DIRECTION_TOLERANCE_RAD = 1e-9


@dataclass
class RangeImage:
    """An organised image of one frame (see the module docstring for the layouts).

    Attributes
    ----------
    range
        (H, W) float64 measured range (m), NaN where there is no return.
    intensity
        (H, W) float32 intensity, NaN where there is no return.
    part
        (H, W) int32 index into ``part_names``, -1 where there is no return.
    point_index
        (H, W) int64 row of the cloud each pixel came from, -1 where there is none.
    layout
        ``"spinning"``, ``"flash"`` or ``"raster"``.
    part_names
        The frame's part names.
    row_channel
        (H,) channel of each row (spinning), else empty.
    """

    range: np.ndarray
    intensity: np.ndarray
    part: np.ndarray
    point_index: np.ndarray
    layout: str
    part_names: list[str] = field(default_factory=list)
    row_channel: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))

    @property
    def shape(self) -> tuple[int, int]:
        """``(height, width)``."""
        return self.range.shape  # type: ignore[return-value]

    def png_scale_m(self) -> float:
        """Metres per PNG unit: 1 mm, or coarser so the farthest return fits 16 bits."""
        far = np.nanmax(self.range) if np.isfinite(self.range).any() else 0.0
        return max(1e-3, float(np.ceil(far / 65535.0 * 1e6)) / 1e6)

    def save(self, path: str | Path, *, overwrite: bool = True) -> tuple[Path, Path]:
        """Write ``<path>.npz`` (every array) and ``<path>.png`` (16-bit range).

        The PNG holds ``round(range / scale)`` with 0 for no return; ``scale`` (m per unit,
        :meth:`png_scale_m`) is in the PNG's ``range_scale_m`` text chunk and in the NPZ.
        Returns the two paths. PNG writing needs Pillow (extra ``viz``).
        """
        from ..base.atomic import atomic_output

        base = Path(path)
        base = base.with_suffix("") if base.suffix.lower() in (".npz", ".png") else base
        npz, png = base.with_name(base.name + ".npz"), base.with_name(base.name + ".png")
        scale = self.png_scale_m()
        with atomic_output(npz, overwrite=overwrite) as stream:
            np.savez_compressed(stream, range=self.range, intensity=self.intensity,
                                part=self.part, point_index=self.point_index,
                                row_channel=self.row_channel, layout=np.array(self.layout),
                                part_names=np.array(self.part_names, dtype=str),
                                range_scale_m=np.array(scale))
        from ..base.errors import OutputError
        from ..base.optional import require

        Image = require("PIL.Image", extra="viz", what="writing the PNG", error=OutputError,
                        source=png)
        PngImagePlugin = require("PIL.PngImagePlugin", extra="viz", what="writing the PNG",
                                 error=OutputError, source=png)
        units = np.where(np.isfinite(self.range), np.round(np.nan_to_num(self.range) / scale), 0)
        image = Image.fromarray(np.clip(units, 0, 65535).astype(np.uint16))
        info = PngImagePlugin.PngInfo()
        info.add_text("range_scale_m", repr(scale))
        info.add_text("lidarsim", json.dumps({"layout": self.layout, "no_return": 0}))
        with atomic_output(png, overwrite=overwrite) as stream:
            image.save(stream, format="PNG", pnginfo=info)
        return npz, png


def has_layout(pattern: "ScanPattern") -> bool:
    """Whether ``pattern`` has a regular layout (spinning, flash, raster)."""
    from ..patterns.flash import FlashPattern
    from ..patterns.raster import RasterPattern
    from ..patterns.spinning import SpinningPattern

    return isinstance(pattern, (SpinningPattern, FlashPattern, RasterPattern))


def _frame_indices(pattern: "ScanPattern", cloud: "PointCloud") -> tuple[int, int]:
    return pattern.index_range(cloud.frame.t_start, cloud.frame.t_end)


def _pixels(pattern: "ScanPattern", cloud: "PointCloud", index: np.ndarray
            ) -> tuple[str, tuple[int, int], np.ndarray, np.ndarray, np.ndarray]:
    """Layout name, image shape, row and column of every ray ``index``, and the rows'
    channels."""
    from ..patterns.flash import FlashPattern
    from ..patterns.raster import RasterPattern
    from ..patterns.spinning import SpinningPattern

    k0, k1 = _frame_indices(pattern, cloud)
    size = pattern.cycle.size if hasattr(pattern, "cycle") else 0
    no_channels = np.empty(0, dtype=np.int64)
    if isinstance(pattern, SpinningPattern):
        elevations = np.asarray(pattern.options.elevations_deg)
        order = np.argsort(-elevations, kind="stable")  # highest elevation on top
        row_of = np.empty(len(order), dtype=np.int64)
        row_of[order] = np.arange(len(order))
        first = k0 // size
        width = (k1 - 1) // size - first + 1 if k1 > k0 else 0
        _check_span(pattern, k0, k1)
        channel = pattern.cycle.channel(index).astype(np.int64)
        return ("spinning", (len(order), width), row_of[channel], index // size - first,
                order.astype(np.int64))
    if isinstance(pattern, FlashPattern):
        _check_span(pattern, k0, k1)
        rows, cols = pattern.options.rows, pattern.options.columns
        pixel = pattern.cycle.slot(index)
        return "flash", (rows, cols), pixel // cols, pixel % cols, no_channels
    if isinstance(pattern, RasterPattern):
        _check_span(pattern, k0, k1)
        rows, cols = pattern.shape
        horizontal = pattern.options.line_axis == "horizontal"
        lines, samples = (rows, cols) if horizontal else (cols, rows)
        slot = pattern.cycle.slot(index)
        line, sample = slot // samples, slot % samples
        if pattern.options.bidirectional:
            sample = np.where(line % 2 == 1, samples - 1 - sample, sample)
        return "raster", (lines, samples), line, sample, no_channels
    raise ConfigError(f"scan pattern '{pattern.name}' has no regular layout: range images "
                      "exist for spinning, flash and raster sensors", field="--range-image")


def range_image(cloud: "PointCloud", pattern: "ScanPattern") -> RangeImage:
    """The organised range image of ``cloud`` made with ``pattern`` (e.g. ``sim.pattern``).

    Raises
    ------
    ConfigError
        If the pattern has no regular layout, the frame spans more than one revolution /
        flash / raster frame, or the cloud's directions are not the pattern's.
    """
    from ..patterns.geometry import directions_from_az_el

    detected = cloud["detected"] == 1
    rows_in_cloud = np.flatnonzero(detected)
    index = cloud["ray_index"][rows_in_cloud]
    layout, shape, row, col, row_channel = _pixels(pattern, cloud, index)
    if len(index):
        nominal = pattern.rays_for_indices(index).direction
        recorded = directions_from_az_el(cloud["azimuth"][rows_in_cloud],
                                         cloud["elevation"][rows_in_cloud])
        # chord length = angle for small angles (arccos of a dot product is too coarse here)
        if np.linalg.norm(nominal - recorded, axis=1).max() > _DIRECTION_TOLERANCE_RAD:
            raise ConfigError("the cloud's ray directions are not this scan pattern's: pass "
                              "the simulation's own pattern (Simulation(scenario).pattern)")
    # first return of each ray wins: sort so that it is written last
    order = np.lexsort((-cloud["return_number"][rows_in_cloud].astype(np.int64),))
    h, w = shape
    point_index = np.full(shape, -1, dtype=np.int64)
    point_index[row[order], col[order]] = rows_in_cloud[order]
    hit = point_index >= 0
    rng = np.full(shape, np.nan)
    intensity = np.full(shape, np.nan, dtype=np.float32)
    part = np.full(shape, -1, dtype=np.int32)
    rng[hit] = cloud["range"][point_index[hit]]
    intensity[hit] = cloud["intensity"][point_index[hit]]
    part[hit] = cloud["part"][point_index[hit]]
    return RangeImage(rng, intensity, part, point_index, layout,
                      list(cloud.frame.part_names), row_channel)


def _check_span(pattern: "ScanPattern", k0: int, k1: int) -> None:
    """Raise :class:`ConfigError` unless the pulses ``k0..k1`` of a frame fit one image: at
    most one revolution, one flash or one raster frame."""
    from ..patterns.flash import FlashPattern
    from ..patterns.raster import RasterPattern
    from ..patterns.spinning import SpinningPattern

    size = pattern.cycle.size
    if isinstance(pattern, SpinningPattern):
        width = (k1 - 1) // size - k0 // size + 1 if k1 > k0 else 0
        revolution = 1.0 / pattern.options.rotation_hz
        if width * pattern.cycle.period_s > revolution * (1 + 1e-9) + pattern.cycle.period_s:
            raise ConfigError(f"the frame spans {width * pattern.cycle.period_s / revolution:.2f}"
                              f" revolutions; a range image needs at most one (scan.duration_s "
                              f"<= {revolution:g} s)", field="scan.duration_s")
    elif isinstance(pattern, FlashPattern):
        if k1 - k0 > size:
            raise ConfigError(f"the frame holds {(k1 - k0) / size:g} flashes; a range image "
                              f"shows one (scan.duration_s <= {pattern.cycle.period_s:g} s, "
                              "one flash)", field="scan.duration_s")
    elif isinstance(pattern, RasterPattern):
        if k1 > k0 and k0 // size != (k1 - 1) // size:
            raise ConfigError("the frame spans more than one raster frame; a range image shows "
                              "one (scan.duration_s = the raster's frame period)",
                              field="scan.duration_s")


def check_layout(pattern: "ScanPattern", spans: "list[tuple[float, float]] | None" = None
                 ) -> None:
    """Raise :class:`ConfigError` unless ``pattern`` has a regular layout and every frame
    ``(t_start, t_end)`` of ``spans`` fits one image (checked before any simulation)."""
    if not has_layout(pattern):
        raise ConfigError(f"scan pattern '{pattern.name}' has no regular layout: range images "
                          "exist for spinning, flash and raster sensors", field="--range-image")
    for t_start, t_end in spans or []:
        _check_span(pattern, *pattern.index_range(t_start, t_end))


def range_image_files(cloud_path: str | Path) -> list[Path]:
    """The two files :func:`save_range_image` writes beside ``cloud_path`` (checked with the
    cloud, as a group, before anything is simulated)."""
    cloud_path = Path(cloud_path)
    base = cloud_path.with_name(cloud_path.stem + ".range")
    return [base.with_name(base.name + ".npz"), base.with_name(base.name + ".png")]


def save_range_image(cloud: "PointCloud", pattern: "ScanPattern", cloud_path: str | Path, *,
                     overwrite: bool = True) -> tuple[Path, Path]:
    """Write the range image of ``cloud`` beside its file: ``cloud_0001.ply`` gives
    ``cloud_0001.range.npz`` and ``cloud_0001.range.png``."""
    cloud_path = Path(cloud_path)
    return range_image(cloud, pattern).save(cloud_path.with_name(cloud_path.stem + ".range"),
                                            overwrite=overwrite)
