"""Plotting primitives shared by the report's 3-D figures and ``lidarsim view``: the camera,
points (one colour, or coloured by a column) and a legend of named parts."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .colouring import PointColours, part_colour


def look(plotter: Any, focus: np.ndarray, view_from: np.ndarray, up: np.ndarray,
          zoom: float = 1.0, bounds: tuple[float, ...] | None = None) -> None:
    """Aim the active camera at ``focus`` from direction ``view_from``, then fit the scene
    (or only ``bounds``, ``(xmin, xmax, ymin, ymax, zmin, zmax)``: what must fill the view)."""
    view_from = np.asarray(view_from, dtype=float) / np.linalg.norm(view_from)
    plotter.camera.focal_point = tuple(focus)
    plotter.camera.position = tuple(np.asarray(focus) + view_from)
    plotter.camera.up = tuple(up)
    if bounds is None:
        plotter.reset_camera()
    else:
        plotter.reset_camera(bounds=bounds)
    plotter.camera.zoom(zoom)
    fit_in_view(plotter, bounds)


def fit_in_view(plotter: Any, bounds: tuple[float, ...] | None = None,
                margin: float = 0.97) -> None:
    """Zoom the active camera out, if needed, until every corner of ``bounds`` (default: the
    visible actors' box) is in the view: a long target seen broadside is not cut at the edges
    (fitting a bounding sphere to the view's height leaves a wide one cut in a narrow
    panel)."""
    renderer = plotter.renderer
    if bounds is None:
        bounds = tuple(renderer.ComputeVisiblePropBounds())
    if not np.all(np.isfinite(bounds)) or bounds[0] > bounds[1]:
        return
    camera = plotter.camera
    matrix = camera.GetCompositeProjectionTransformMatrix(renderer.GetTiledAspectRatio(), -1, 1)
    m = np.array([[matrix.GetElement(i, j) for j in range(4)] for i in range(4)])
    corners = np.array([[x, y, z, 1.0] for x in bounds[0:2] for y in bounds[2:4]
                        for z in bounds[4:6]])
    projected = corners @ m.T
    w = projected[:, 3:4]
    if np.any(w <= 0):
        return
    extent = float(np.abs(projected[:, :2] / w).max())
    if extent > margin:
        camera.zoom(margin / extent)


def oblique_view(centre: np.ndarray) -> np.ndarray:
    """A viewing direction (from ``centre`` toward the eye) beside and above the sensor."""
    back = -centre / max(np.linalg.norm(centre), 1e-9)
    return back + np.array([0.0, -0.3, 0.3])


def add_points(plotter: Any, points: np.ndarray, size: float, **kwargs: Any) -> None:
    import pyvista as pv

    if len(points):
        plotter.add_mesh(pv.PolyData(np.ascontiguousarray(points)), point_size=size,
                         render_points_as_spheres=True, **kwargs)


def add_coloured_points(plotter: Any, points: np.ndarray, colours: PointColours, size: float,
                         clim: tuple[float, float] | None = None, bar_below: bool = False
                         ) -> None:
    """Points coloured by ``colours``: a part legend, or a colour bar (right, or below)."""
    import pyvista as pv

    if not len(points):
        return
    if colours.categorical:
        present = np.unique(colours.values.astype(int))
        for idx in present:
            sel = colours.values == idx
            add_points(plotter, points[sel], size, color=part_colour(int(idx)))
        add_legend(plotter, [colours.names[int(i)] for i in present], present, "circle")
        return
    cloud = pv.PolyData(np.ascontiguousarray(points))
    cloud.point_data[colours.label] = colours.values
    if clim is None:
        finite = colours.values[np.isfinite(colours.values)]
        clim = (float(finite.min()), float(finite.max())) if len(finite) else (0.0, 1.0)
    lo, hi, labels, fmt = nice_ticks(*clim)
    place = {"vertical": False, "position_x": 0.3, "position_y": 0.03, "width": 0.4,
             "height": 0.08} if bar_below else \
        {"vertical": True, "position_x": 0.88, "position_y": 0.15, "height": 0.6, "width": 0.06}
    new_bar = colours.label not in plotter.scalar_bars  # linked subplots share one bar
    plotter.add_mesh(cloud, scalars=colours.label, cmap="turbo", point_size=size,
                     render_points_as_spheres=True, clim=(lo, hi),
                     scalar_bar_args={"title": colours.label, "color": "black", "fmt": fmt,
                                      "n_labels": labels, "title_font_size": 14,
                                      "label_font_size": 12, **place})
    if new_bar:  # VTK writes a bar's title over its end tick labels: put it clear of them
        plotter.scalar_bars[colours.label].SetTitle("")
        if bar_below:  # left of the bar, a gap before its first label
            plotter.add_text(colours.label, position=(0.25, 0.045), viewport=True, font_size=9,
                             color="black").GetTextProperty().SetJustificationToRight()
        else:  # above the bar, a gap over its top label
            plotter.add_text(colours.label, position=(0.86, 0.15 + 0.6 + 0.05), viewport=True,
                             font_size=9, color="black")


def add_legend(plotter: Any, names: list[str], indices: Any, face: str) -> None:
    """A legend of part colours in the lower-right corner, wide enough for the longest name
    (VTK scales the text to the box: a box too narrow cuts the names)."""
    rows = len(names)
    longest = max((len(n) for n in names), default=4)
    height = min(0.028 * rows + 0.01, 0.5)
    width = min(0.45, max(0.16, 0.02 + 0.01 * longest))  # VTK shrinks the text to fit
    legend = plotter.add_legend([[name, part_colour(int(i))] for name, i in zip(names, indices)],
                                bcolor="white", size=(width, height), loc="lower right",
                                face=face, background_opacity=0.8)
    # pyvista places a right-hand legend by its height, not its width: put it inside
    legend.SetPosition(1.0 - width - 0.02, 0.05)


def nice_ticks(lo: float, hi: float, max_ticks: int = 6) -> tuple[float, float, int, str]:
    """A colour-bar range widened to round numbers: ``(lo, hi, labels, printf format)``, the
    labels at a step of 1, 2 or 5 times a power of ten with as many decimals as it needs."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return lo, hi if hi > lo else lo + 1.0, 2, "%.4g"
    raw = (hi - lo) / (max_ticks - 1)
    power = 10 ** math.floor(math.log10(raw))
    step = next(m * power for m in (1, 2, 5, 10) if m * power >= raw)
    start, stop = math.floor(lo / step) * step, math.ceil(hi / step) * step
    labels = int(round((stop - start) / step)) + 1
    decimals = max(0, -math.floor(math.log10(step) + 1e-9))
    return start, stop, labels, f"%.{decimals}f"
