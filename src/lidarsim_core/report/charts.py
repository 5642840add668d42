"""2-D report figures drawn with matplotlib: the scan pattern on a plane (paper Fig. 5), the
error histograms with their normal fits (Figs. 6 and 9) and the FOV coverage map.

Pictures of the sensor's view are drawn as seen from behind the sensor looking along the
boresight: +Z up and +Y to the *left* (the horizontal axis is flipped accordingly).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..patterns.base import ScanPattern
from ..patterns.geometry import (
    az_el_from_directions,
    directions_from_az_el,
    directions_from_off_axis,
    off_axis_angle,
)
from .render import save_figure
from .stats import NormalFit

#: Rays drawn per segment of the pattern figure when the pattern has no turn period.
SEGMENT_RAYS = 4000
_SEGMENT_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e")


def new_figure(width_in: float, height_in: float) -> Any:
    """A matplotlib Figure with an Agg canvas, outside pyplot's global state."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def pattern_segment_s(pattern: ScanPattern) -> float:
    """Length of one segment of the pattern figure (s).

    One turn of a rose; a third of a revolution of a spinning head; one period of the slower
    axis of a Lissajous scanner; else :data:`SEGMENT_RAYS` pulses.
    """
    options = pattern.options
    turn = getattr(options, "turn_period_s", None)
    if turn:
        return float(turn)
    rotation = getattr(options, "rotation_hz", None)
    if rotation:
        return 1.0 / (3.0 * float(rotation))
    axes = [getattr(options, f"{axis}_hz", None) for axis in ("azimuth", "elevation")]
    if all(axes):
        return 1.0 / min(float(a) for a in axes)
    return SEGMENT_RAYS / pattern.rate_hz


def plane_points(directions: np.ndarray, distance_m: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Where rays from the sensor origin meet the plane ``x = distance_m``.

    Returns
    -------
    (points, mask)
        (M, 2) ``(y, z)`` of the rays going forward (``x > 0``), and the (N,) mask of those rays.
    """
    forward = directions[:, 0] > 1e-9
    d = directions[forward]
    return distance_m * d[:, 1:] / d[:, :1], forward


def pattern_figure(pattern: ScanPattern, path: str | Path, *, segments: int = 3,
                   segment_s: float | None = None, t_start_s: float = 0.0,
                   distance_m: float = 1.0) -> Path:
    """Consecutive segments of a pattern's rays on a plane in front of the sensor (Fig. 5).

    Panoramic sensors are drawn in azimuth and elevation instead (the unrolled cylinder).

    Parameters
    ----------
    pattern
        A scan pattern bound to its sensor.
    path
        PNG to write.
    segments
        How many consecutive segments to draw, each in its own colour (paper: 3 rosettes).
    segment_s
        Length of a segment (s); default :func:`pattern_segment_s` (one turn of a rose).
    t_start_s
        Time of the first ray drawn (s from scan start).
    distance_m
        Distance of the plane from the sensor along the boresight (paper: 1 m).
    """
    seg = segment_s or pattern_segment_s(pattern)
    batch = pattern.rays(t_start_s, t_start_s + segments * seg)
    panoramic = pattern.sensor.fov_type == "panoramic"
    if panoramic:  # a plane ahead would show a sliver: unroll the cylinder instead
        az, el = az_el_from_directions(batch.direction)
        pts, keep = np.degrees(np.column_stack([az, el])), np.ones(len(batch), dtype=bool)
    else:
        pts, keep = plane_points(batch.direction, distance_m)
    which = np.minimum(((batch.t[keep] - t_start_s) / seg).astype(int), segments - 1)
    fig = new_figure(10.0, 5.6) if panoramic else new_figure(7.0, 7.4)
    ax = fig.add_subplot()
    label = "rosette" if getattr(pattern.options, "turn_period_s", None) else "segment"
    size = float(np.clip(6000.0 / max(len(pts), 1), 0.3, 4.0))
    colours = np.array([_SEGMENT_COLOURS[i % len(_SEGMENT_COLOURS)] for i in range(segments)])
    # drawn in a shuffled order, so that no segment hides the ones drawn before it
    order = np.random.default_rng(0).permutation(len(pts))
    ax.scatter(pts[order, 0], pts[order, 1], s=size, linewidths=0, c=colours[which[order]])
    for i in range(segments):  # legend entries
        t0, t1 = t_start_s + i * seg, t_start_s + (i + 1) * seg
        ax.scatter([], [], s=size, color=colours[i],
                   label=f"{label} {i + 1}: {1e3 * t0:.1f}–{1e3 * t1:.1f} ms "
                         f"({int((which == i).sum()):,} rays)")
    if panoramic:
        sheet = pattern.sensor
        half = math.degrees(sheet.half_fov_v_rad)
        ax.set_xlim(180, -180)  # +Y (azimuth > 0) to the left, as seen from the sensor
        ax.set_ylim(sheet.fov_v_center_deg - 1.15 * half, sheet.fov_v_center_deg + 1.15 * half)
        ax.set_xlabel("azimuth (deg)   ← +Y left")
        ax.set_ylabel("elevation (deg)   +Z up")
        where = "in azimuth and elevation (panoramic FOV)"
    else:
        _draw_fov_outline(ax, pattern, distance_m)
        extent = 1.08 * distance_m * math.tan(min(pattern.max_off_axis_rad(),
                                                  math.radians(60.0)))
        ax.set_xlim(extent, -extent)  # +Y is to the left, seen from behind the sensor
        ax.set_ylim(-extent, extent)
        ax.set_aspect("equal")
        ax.set_xlabel("y (m)   ← +Y left")
        ax.set_ylabel("z (m)   +Z up")
        where = f"on a plane {distance_m:g} m in front of the sensor"
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=1, fontsize=8,
              markerscale=6 / max(size, 0.5), frameon=False)
    ax.set_title(f"{pattern.sensor.name} ({pattern.name} pattern): {segments} consecutive "
                 f"{label}s\n{where} (cf. paper Fig. 5)", fontsize=10)
    return save_figure(fig, path)


def _draw_fov_outline(ax: Any, pattern: ScanPattern, distance_m: float) -> None:
    """The datasheet FOV's edge where it meets the plane (circular and rectangular FOVs)."""
    sheet = pattern.sensor
    if sheet.fov_type == "circular" and sheet.half_fov_h_rad < math.radians(80):
        phi = np.linspace(0, 2 * np.pi, 361)
        edge = directions_from_off_axis(np.full_like(phi, sheet.half_fov_h_rad), phi)
    elif sheet.fov_type == "rectangular":
        h, v, c = sheet.half_fov_h_rad, sheet.half_fov_v_rad, math.radians(sheet.fov_v_center_deg)
        s = np.linspace(-1, 1, 100)
        az = np.concatenate([s * h, np.full_like(s, h), -s * h, np.full_like(s, -h)])
        el = c + np.concatenate([np.full_like(s, -v), s * v, np.full_like(s, v), -s * v])
        edge = directions_from_az_el(az, el)
    else:
        return
    pts, _ = plane_points(edge, distance_m)
    ax.plot(pts[:, 0], pts[:, 1], color="0.3", lw=0.8, ls="--", label="datasheet FOV")


def error_histogram_figure(sample: np.ndarray, fit: NormalFit, datasheet_sigma: float,
                           path: str | Path, *, title: str, xlabel: str, unit: str,
                           sample_label: str | None = None) -> Path:
    """Histogram of an error sample with its fitted normal curve and the datasheet's (Figs. 6, 9).

    ``sample``, ``fit`` and ``datasheet_sigma`` are in the display unit ``unit``;
    ``sample_label`` describes the sample in the legend (default: its size).
    """
    fig = new_figure(7.0, 4.6)
    ax = fig.add_subplot()
    spread = max(fit.sigma, datasheet_sigma, 1e-12)
    lo, hi = fit.mean - 4.5 * spread, fit.mean + 4.5 * spread
    heights = ax.hist(sample, bins=np.linspace(lo, hi, 71), density=True, color="#9ecae1",
                      edgecolor="#3182bd", linewidth=0.4,
                      label=f"injected errors ({sample_label or f'n = {fit.n:,}'})")[0]
    x = np.linspace(lo, hi, 400)
    ax.plot(x, fit.pdf(x), color="#d62728", lw=2,
            label=f"fitted normal: μ = {fit.mean:+.3g} {unit}, σ = {fit.sigma:.3g} {unit}")
    if datasheet_sigma > 0:
        sheet = NormalFit(fit.n, 0.0, datasheet_sigma)
        ax.plot(x, sheet.pdf(x), color="black", lw=1.2, ls="--",
                label=f"datasheet 1σ = {datasheet_sigma:.3g} {unit}")
    lo95, hi95 = fit.sigma_ci95
    ax.text(0.02, 0.97, f"σ 95 % interval\n[{lo95:.3g}, {hi95:.3g}] {unit}",
            transform=ax.transAxes, va="top", fontsize=8)
    ax.set_xlim(lo, hi)
    ax.set_ylim(0, 1.35 * max(float(heights.max()), float(fit.pdf(np.array([fit.mean]))[0])))
    ax.set_xlabel(xlabel)
    ax.set_ylabel(f"probability density (1/{unit})")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8, loc="upper right")
    ax.grid(True, lw=0.3, alpha=0.5)
    return save_figure(fig, path)


@dataclass(frozen=True)
class CoverageMap:
    """Rays per cell over the FOV in one integration time (see :func:`coverage_map`).

    Attributes
    ----------
    counts
        (nu, nv) rays per cell.
    in_fov
        (nu, nv) whether the cell centre lies in the datasheet FOV.
    u_edges_deg, v_edges_deg
        Cell edges (deg) along the horizontal (+Y, or azimuth) and vertical (+Z, or elevation)
        axes of the projection.
    projection
        ``"azimuthal-equidistant"`` (circular, rectangular FOVs) or ``"equirectangular"``.
    """

    counts: np.ndarray
    in_fov: np.ndarray
    u_edges_deg: np.ndarray
    v_edges_deg: np.ndarray
    projection: str

    @property
    def coverage(self) -> float:
        """Fraction of FOV cells hit at least once."""
        n = int(self.in_fov.sum())
        return float((self.counts[self.in_fov] > 0).sum() / n) if n else 0.0


def coverage_map(pattern: ScanPattern, duration_s: float, cell_deg: float = 0.5, *,
                 t_start_s: float = 0.0, chunk_rays: int = 1 << 20) -> CoverageMap:
    """Count the rays emitted in ``[t_start_s, t_start_s + duration_s)`` per FOV cell.

    Circular and rectangular FOVs use the azimuthal-equidistant projection about the boresight
    (``u = θ cos φ`` toward +Y, ``v = θ sin φ`` toward +Z, with θ the off-axis angle and φ the
    roll from +Y toward +Z), so distances from the centre are true angles; panoramic FOVs use
    azimuth and elevation. A cell is in the FOV when its centre is.
    """
    sheet = pattern.sensor
    cell = math.radians(cell_deg)
    if sheet.fov_type == "panoramic":
        projection = "equirectangular"
        centre = math.radians(sheet.fov_v_center_deg)
        u_edges = np.linspace(-math.pi, math.pi, max(1, round(2 * math.pi / cell)) + 1)
        # rows centred on the FOV's lower edge: rings at round elevations fall mid-cell
        nv = math.floor(2 * sheet.half_fov_v_rad / cell + 1e-9) + 1
        v_edges = centre - sheet.half_fov_v_rad - cell / 2 + cell * np.arange(nv + 1)
        if sheet.fov_h_deg < 360:
            u_edges = u_edges[np.abs(u_edges) <= sheet.half_fov_h_rad + cell]
    else:
        projection = "azimuthal-equidistant"
        reach = min(pattern.max_off_axis_rad(), math.pi * 0.95) + cell
        n = math.ceil(reach / cell)
        u_edges = v_edges = cell * np.arange(-n, n + 1)
    uc, vc = np.meshgrid((u_edges[:-1] + u_edges[1:]) / 2, (v_edges[:-1] + v_edges[1:]) / 2,
                         indexing="ij")
    if projection == "equirectangular":
        centres = directions_from_az_el(uc.ravel(), vc.ravel())
    else:
        theta = np.hypot(uc.ravel(), vc.ravel())
        centres = directions_from_off_axis(theta, np.arctan2(vc.ravel(), uc.ravel()))
    in_fov = pattern.inside_fov(centres).reshape(uc.shape)
    counts = np.zeros(uc.shape, dtype=np.int64)
    k0, k1 = pattern.index_range(t_start_s, t_start_s + duration_s)
    for start in range(k0, k1, chunk_rays):
        d = pattern.rays_for_indices(np.arange(start, min(start + chunk_rays, k1))).direction
        if projection == "equirectangular":
            u, v = az_el_from_directions(d)
        else:
            theta = off_axis_angle(d)
            phi = np.arctan2(d[:, 2], d[:, 1])
            u, v = theta * np.cos(phi), theta * np.sin(phi)
        counts += np.histogram2d(u, v, bins=(u_edges, v_edges))[0].astype(np.int64)
    return CoverageMap(counts, in_fov, np.degrees(u_edges), np.degrees(v_edges), projection)


def coverage_figure(cmap: CoverageMap, path: str | Path, *, sensor: str, duration_s: float,
                    coverage: float | None = None) -> Path:
    """Draw a :class:`CoverageMap`: rays per cell, unhit FOV cells in red, FOV edge dashed.

    ``coverage`` is the fraction quoted in the title (default: the map's own).
    """
    from matplotlib.colors import ListedColormap, LogNorm

    coverage = cmap.coverage if coverage is None else coverage
    wide = cmap.projection == "equirectangular"
    fig = new_figure(10.0 if wide else 7.0, 4.6 if wide else 6.6)
    ax = fig.add_subplot()
    u, v = cmap.u_edges_deg, cmap.v_edges_deg
    hits = np.ma.masked_where(~cmap.in_fov | (cmap.counts == 0), cmap.counts)
    missed = np.ma.masked_where(~(cmap.in_fov & (cmap.counts == 0)), np.ones(cmap.counts.shape))
    ax.pcolormesh(u, v, missed.T, cmap=ListedColormap(["#fcbba1"]), rasterized=True)
    mesh = ax.pcolormesh(u, v, hits.T, cmap="viridis", rasterized=True,
                         norm=LogNorm(vmin=1, vmax=max(int(cmap.counts.max()), 2)))
    fig.colorbar(mesh, ax=ax, label="rays per cell", shrink=0.85)
    ax.contour((u[:-1] + u[1:]) / 2, (v[:-1] + v[1:]) / 2, cmap.in_fov.T.astype(float),
               levels=[0.5], colors="0.3", linewidths=0.8, linestyles="--")
    cell = abs(u[1] - u[0])
    if wide:
        ax.set_xlim(u[-1], u[0])
        ax.set_xlabel("azimuth (deg)   ← +Y left")
        ax.set_ylabel("elevation (deg)")
    else:
        ax.set_xlim(u[-1], u[0])  # +Y to the left, seen from behind the sensor
        ax.set_ylim(v[0], v[-1])
        ax.set_aspect("equal")
        ax.set_xlabel("θ·cos φ (deg)   ← +Y left")
        ax.set_ylabel("θ·sin φ (deg)   +Z up")
    ax.set_title(f"{sensor}: FOV coverage in {duration_s:g} s = {100 * coverage:.1f} % of the "
                 f"{cell:g}° cells\n(red: FOV cells no ray reached; dashed: datasheet FOV)",
                 fontsize=10)
    return save_figure(fig, path)
