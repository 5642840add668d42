"""How well a scan pattern fills its field of view: FOV coverage and point density.

Cells
-----
The FOV is cut into square cells of ``cell_deg × cell_deg`` in a projection chosen by FOV type:

* ``circular`` and ``rectangular`` FOVs use the azimuthal-equidistant projection about the
  boresight: a direction at off-axis angle θ and roll φ maps to ``(θ cos φ, θ sin φ)`` degrees,
  so radial distance is the true angle from the boresight (equal-angle cells; a cell at θ
  subtends ``sin θ / θ`` of the solid angle of a cell on the boresight: 0.94 at 35°);
* ``panoramic`` FOVs (spinning heads) use the equirectangular (azimuth, elevation) grid: a whole
  number of columns round 360° (the width rounded so they divide it evenly) and rows centred on
  the FOV's lower edge, so rings at round elevations fall mid-cell, not on cell borders.

A cell belongs to the FOV when its centre is inside the datasheet's FOV. The *coverage* is the
fraction of FOV cells hit by at least one ray emitted in ``[t_start, t_start + duration)``.
The density profile bins rays by off-axis angle and divides by the solid angle of the FOV cells
whose centres fall in each bin.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from .base import ScanPattern
from .geometry import (
    az_el_from_directions,
    directions_from_az_el,
    directions_from_off_axis,
    off_axis_angle,
)

#: Rays generated per step when scanning a pattern (bounds memory).
CHUNK_RAYS = 1 << 20
_SR_TO_DEG2 = (180.0 / math.pi) ** 2


@dataclass
class DensityBin:
    """Point density in one off-axis annulus ``[off_axis_lo_deg, off_axis_hi_deg)``."""

    off_axis_lo_deg: float
    off_axis_hi_deg: float
    points: int
    solid_angle_deg2: float
    points_per_deg2: float
    points_per_deg2_per_s: float


@dataclass
class CoverageReport:
    """FOV coverage of a pattern over one integration time (see module docstring)."""

    sensor: str
    pattern: str
    t_start_s: float
    duration_s: float
    cell_deg: float
    projection: str
    rays: int
    rays_in_fov_cells: int
    cells_in_fov: int
    cells_hit: int
    coverage: float
    density: list[DensityBin] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready mapping (``coverage`` is the fraction of FOV cells hit)."""
        return asdict(self)


class _Grid:
    """The cell grid of a FOV: cell index of a direction, and which cells are inside the FOV."""

    def __init__(self, pattern: ScanPattern, cell_deg: float) -> None:
        sheet = pattern.sensor
        self.cell = math.radians(cell_deg)
        self.panoramic = sheet.fov_type == "panoramic"
        if self.panoramic:
            # whole cells round the circle; rows centred on the FOV's lower edge, so rings at
            # round elevations fall in the middle of cells rather than on their borders
            self.projection = "equirectangular (azimuth, elevation)"
            self.nu = max(1, round(2 * math.pi / self.cell))
            self.cell_u = 2 * math.pi / self.nu
            lower = math.radians(sheet.fov_v_center_deg) - sheet.half_fov_v_rad
            self.u0, self.v0 = -math.pi - self.cell_u / 2, lower - self.cell / 2
            self.nv = math.floor(2 * sheet.half_fov_v_rad / self.cell + 1e-9) + 1
        else:
            self.projection = "azimuthal-equidistant about the boresight"
            if sheet.fov_type == "circular":
                reach = sheet.half_fov_h_rad
            else:  # bounds the corner's angle from the boresight
                reach = math.hypot(sheet.half_fov_h_rad,
                                   abs(math.radians(sheet.fov_v_center_deg)) + sheet.half_fov_v_rad)
            r = min(reach, math.pi) + self.cell
            self.cell_u = self.cell
            self.u0, self.v0 = -r, -r
            self.nu = self.nv = max(1, math.ceil(2 * r / self.cell - 1e-9))
        iu, iv = np.meshgrid(np.arange(self.nu), np.arange(self.nv), indexing="ij")
        uc = self.u0 + (iu.ravel() + 0.5) * self.cell_u
        vc = self.v0 + (iv.ravel() + 0.5) * self.cell
        centres, solid = self._centres(uc, vc)
        self.in_fov = pattern.inside_fov(centres, 1e-9) & np.isfinite(solid)
        self.centre_off_axis = off_axis_angle(centres)
        self.solid_angle = np.where(self.in_fov, solid, 0.0)

    def _centres(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit directions of cell centres and each cell's solid angle (sr)."""
        c2 = self.cell_u * self.cell
        if self.panoramic:
            return directions_from_az_el(u, v), c2 * np.abs(np.cos(v))
        theta = np.hypot(u, v)
        ok = theta <= math.pi
        sinc = np.where(theta > 0, np.sin(theta) / np.where(theta > 0, theta, 1.0), 1.0)
        return directions_from_off_axis(np.minimum(theta, math.pi), np.arctan2(v, u)), \
            np.where(ok, c2 * sinc, np.nan)

    def cell_of(self, directions: np.ndarray) -> np.ndarray:
        """Flat cell index of each direction (-1 when outside the grid)."""
        if self.panoramic:
            u, v = az_el_from_directions(directions)
        else:
            theta = off_axis_angle(directions)
            phi = np.arctan2(directions[:, 2], directions[:, 1])
            u, v = theta * np.cos(phi), theta * np.sin(phi)
        iu = np.floor((u - self.u0) / self.cell_u).astype(np.int64)
        iv = np.floor((v - self.v0) / self.cell).astype(np.int64)
        if self.panoramic:
            iu %= self.nu  # azimuth wraps round
        ok = (iu >= 0) & (iu < self.nu) & (iv >= 0) & (iv < self.nv)
        return np.where(ok, iu * self.nv + iv, -1)


def fov_coverage(pattern: ScanPattern, duration_s: float, cell_deg: float = 0.5, *,
                 t_start_s: float = 0.0, bin_deg: float = 1.0) -> CoverageReport:
    """Fraction of the FOV hit by a pattern in an integration time, and density by off-axis angle.

    Parameters
    ----------
    pattern
        A scan pattern bound to its sensor.
    duration_s
        Integration time (s), > 0.
    cell_deg
        Cell size (deg), > 0.
    t_start_s
        Start of the integration window (s from scan start).
    bin_deg
        Width of the off-axis bins of the density profile (deg).

    Returns
    -------
    CoverageReport
        ``coverage`` = hit FOV cells / FOV cells; ``density`` per off-axis bin.

    Examples
    --------
    >>> from lidarsim_core import get_sensor
    >>> from lidarsim_core.patterns.fov import pattern_for
    >>> report = fov_coverage(pattern_for(get_sensor("livox-mid70")), 0.1, 0.5)
    >>> 0.0 < report.coverage < 1.0
    True
    """
    if not duration_s > 0:
        raise ValueError("duration_s must be > 0")
    if not cell_deg > 0 or not bin_deg > 0:
        raise ValueError("cell_deg and bin_deg must be > 0")
    if not (cell_deg <= 360 and bin_deg <= 180):  # larger cells overflow the grid's size
        raise ValueError("cell_deg must be at most 360 and bin_deg at most 180")
    # the resource budget, before the grid and the bins are allocated
    from ..base.limits import check, check_pattern_window
    from .fov import coverage_cells

    check("profile_bins", 180.0 / bin_deg, what=f"bin_deg {bin_deg:g}", field="bin_deg")
    check("coverage_cells", coverage_cells(pattern.sensor, cell_deg), field="cell_deg",
          what=f"cell_deg {cell_deg:g} over a {pattern.sensor.fov_h_deg:g}° field of view")
    check_pattern_window(pattern.rate_hz, t_start_s, duration_s, budget="rays_per_frame",
                         duration_field="duration_s", start_field="t_start_s")
    grid = _Grid(pattern, cell_deg)
    hit = np.zeros(grid.nu * grid.nv, dtype=bool)
    edges = np.arange(0.0, 180.0 + bin_deg, bin_deg)
    counts = np.zeros(len(edges) - 1, dtype=np.int64)
    k0, k1 = pattern.index_range(t_start_s, t_start_s + duration_s)
    in_cells = 0
    for start in range(k0, k1, CHUNK_RAYS):
        batch = pattern.rays_for_indices(np.arange(start, min(start + CHUNK_RAYS, k1)))
        cells = grid.cell_of(batch.direction)
        valid = cells >= 0
        valid[valid] = grid.in_fov[cells[valid]]
        hit[cells[valid]] = True
        in_cells += int(valid.sum())
        counts += np.histogram(np.degrees(off_axis_angle(batch.direction)), bins=edges)[0]
    n_fov = int(grid.in_fov.sum())
    solid = np.histogram(np.degrees(grid.centre_off_axis), bins=edges,
                         weights=grid.solid_angle)[0] * _SR_TO_DEG2
    density = []
    for i in np.flatnonzero((solid > 0) | (counts > 0)):
        per = counts[i] / solid[i] if solid[i] > 0 else float("nan")
        density.append(DensityBin(float(edges[i]), float(edges[i + 1]), int(counts[i]),
                                  float(solid[i]), float(per), float(per / duration_s)))
    return CoverageReport(
        sensor=pattern.sensor.name, pattern=pattern.name, t_start_s=t_start_s,
        duration_s=duration_s, cell_deg=cell_deg, projection=grid.projection, rays=k1 - k0,
        rays_in_fov_cells=in_cells, cells_in_fov=n_fov, cells_hit=int(hit[grid.in_fov].sum()),
        coverage=float(hit[grid.in_fov].sum() / n_fov) if n_fov else 0.0, density=density)


# ---- scan-pattern commands -----------------------------------------------------------------
def coverage_cells(sheet: Any, cell_deg: float) -> float:
    """Cells of the coverage grid of datasheet ``sheet`` with cells of ``cell_deg`` (the
    shape :func:`lidarsim_core.patterns.fov.fov_coverage` builds), computed without
    building it."""
    if not (math.isfinite(cell_deg) and 0 < cell_deg <= 360):
        return math.inf
    if sheet.fov_type == "panoramic":
        return max(1.0, float(round(360.0 / cell_deg))) * \
            float(math.floor(sheet.fov_v_deg / cell_deg) + 1)
    if sheet.fov_type == "circular":
        reach = sheet.fov_h_deg / 2
    else:
        reach = math.hypot(sheet.fov_h_deg / 2, abs(sheet.fov_v_center_deg) + sheet.fov_v_deg / 2)
    side = max(1.0, float(math.ceil(2 * (min(reach, 180.0) + cell_deg) / cell_deg)))
    return side * side
