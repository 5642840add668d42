"""3-D report figures rendered off-screen with pyvista.

* :func:`scene_figure` — the set-up in the scene frame: target meshes at their poses, the sensor
  (red) with its axes and its field of view (paper Fig. 7);
* :func:`errors_figure` — the cloud without and with the sensor's errors side by side: the whole
  cloud, a face-on close-up of a flat patch (angular error blurs the scan lines) and the same
  patch edge-on with the normal axis stretched (range error thickens the surface) (Fig. 11);
* :func:`cloud_figure` — the mesh coloured by part beside the mesh with the cloud coloured by
  part, range, time or intensity (Fig. 12).

Clouds are drawn in the sensor frame, with the meshes at their pose at frame start. Call
:func:`lidarsim_core.report.render.rendering_backend` before these functions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..geometry.poses import Poses
from ..patterns.geometry import directions_from_az_el, directions_from_off_axis
from ..scenario.datasheet import SensorDatasheet
from ..scene.mesh import Mesh
from .colouring import PointColours, part_colour, point_colours, short_part_names
from .plotting import (
    add_coloured_points,
    add_legend,
    add_points,
    look,
    oblique_view,
)
from .render import new_plotter, save_plotter
from .run import Run

MESH_COLOUR = "#b8bec8"
SENSOR_COLOUR = "#e41a1c"
CLEAN_COLOUR = "#08519c"
NOISY_COLOUR = "#a50f15"


# ---- building blocks ------------------------------------------------------------------
def mesh_polydata(mesh: Mesh, pose: Poses | None = None, part_offset: int = 0) -> Any:
    """A ``pyvista.PolyData`` of ``mesh`` moved by ``pose``, with cell data ``part``."""
    import pyvista as pv

    vertices = mesh.vertices if pose is None else pose.apply(mesh.vertices)
    cells = np.hstack([np.full((len(mesh.faces), 1), 3, dtype=np.int64), mesh.faces]).ravel()
    poly = pv.PolyData(np.ascontiguousarray(vertices), cells)
    poly.cell_data["part"] = mesh.face_part + part_offset
    return poly


def fov_edge_loops(sheet: SensorDatasheet, samples: int = 120) -> list[np.ndarray]:
    """Closed loops of unit directions (sensor frame) tracing the edge of the datasheet FOV.

    One loop for circular and rectangular FOVs; the lower and upper elevation circles for a
    panoramic FOV.
    """
    if sheet.fov_type == "circular":
        phi = np.linspace(0.0, 2 * np.pi, samples + 1)
        return [directions_from_off_axis(np.full_like(phi, sheet.half_fov_h_rad), phi)]
    centre = math.radians(sheet.fov_v_center_deg)
    h, v = sheet.half_fov_h_rad, sheet.half_fov_v_rad
    if sheet.fov_type == "rectangular":
        s = np.linspace(-1.0, 1.0, samples // 4)
        az = np.concatenate([s * h, np.full_like(s, h), -s * h, np.full_like(s, -h)])
        el = centre + np.concatenate([np.full_like(s, -v), s * v, np.full_like(s, v), -s * v])
        return [directions_from_az_el(np.append(az, az[0]), np.append(el, el[0]))]
    az = np.linspace(-min(h, np.pi), min(h, np.pi), samples + 1)
    return [directions_from_az_el(az, np.full_like(az, centre + e)) for e in (-v, v)]


def fov_polydata(sheet: SensorDatasheet, depth_m: float, pose: Poses) -> tuple[Any, Any]:
    """The FOV as translucent cone surfaces and as edge lines, in the scene frame.

    Cones whose edge points forward end on the plane ``depth_m`` ahead along the boresight;
    the others (panoramic FOVs) end on the sphere of radius ``depth_m``.

    Returns
    -------
    (surface, edges)
        Two ``pyvista.PolyData``.
    """
    import pyvista as pv

    apex = pose.position[0]
    surfaces, edges = [], []
    for loop in fov_edge_loops(sheet):
        forward = loop[:, 0].min() > 0.1
        rim = pose.apply(loop * (depth_m / loop[:, :1] if forward else depth_m))
        points = np.vstack([apex, rim])
        n = len(rim)
        tris = np.column_stack([np.full(n - 1, 3), np.zeros(n - 1, dtype=int),
                                np.arange(1, n), np.arange(2, n + 1)]).ravel()
        surfaces.append(pv.PolyData(points, faces=tris))
        edges.append(pv.lines_from_points(rim))
        for k in np.linspace(0, n - 1, 9)[:-1].astype(int):  # a few generatrices
            edges.append(pv.Line(apex, rim[k]))
    return pv.merge(surfaces), pv.merge(edges)












def _meshes_in_sensor_frame(run: Run) -> list[Any]:
    return [mesh_polydata(t.mesh, pose, t.part_offset)
            for t, pose in zip(run.simulation.targets, run.targets_in_sensor())]


def _title(plotter: Any, text: str, size: int = 11) -> None:
    plotter.add_text(text, position="upper_left", font_size=size, color="black")


# ---- Fig. 7: the set-up ---------------------------------------------------------------
def scene_figure(run: Run, path: str | Path, window_size: tuple[int, int] = (1500, 950)) -> Path:
    """The scene at frame start: targets, the sensor (red) with its axes and FOV (Fig. 7)."""
    import pyvista as pv

    plotter = new_plotter(window_size=window_size)
    plotter.enable_depth_peeling()  # the translucent FOV must not hide the targets behind it
    sensor = run.sensor_in_scene()
    origin = sensor.position[0]
    axes = sensor.rotate(np.eye(3))  # rows: boresight (+X), left (+Y), up (+Z) in the scene
    corners, centres = [], []
    for target, pose in zip(run.simulation.targets, run.targets_in_scene()):
        poly = mesh_polydata(target.mesh, pose)
        plotter.add_mesh(poly, color=MESH_COLOUR, specular=0.4, diffuse=0.9, ambient=0.25)
        box = np.array(poly.bounds).reshape(3, 2).T
        corners.append(box)
        centres.append(box.mean(axis=0))
    box = np.vstack(corners)
    far = float(np.max(np.linalg.norm(box - origin, axis=1)))
    depth = 1.08 * float(np.max((box - origin) @ axes[0]))
    surface, edges = fov_polydata(run.sensor, depth if depth > 0 else far, sensor)
    plotter.add_mesh(surface, color=SENSOR_COLOUR, opacity=0.08, show_edges=False)
    plotter.add_mesh(edges, color=SENSOR_COLOUR, line_width=1.5, opacity=0.5)
    size = 0.03 * far
    body = pv.Cube(center=(0.0, 0.0, 0.0), x_length=size, y_length=size, z_length=size)
    body.points = sensor.apply(np.asarray(body.points))
    plotter.add_mesh(body, color=SENSOR_COLOUR)
    for axis, colour, name in ((0, "#d62728", "+X boresight"), (1, "#2ca02c", "+Y"),
                               (2, "#1f77b4", "+Z")):
        length = (0.25 if axis == 0 else 0.12) * far
        plotter.add_mesh(pv.Arrow(start=origin, direction=axes[axis], scale=length,
                                  tip_length=0.2, shaft_radius=0.025, tip_radius=0.07),
                         color=colour)
        plotter.add_point_labels([origin + axes[axis] * length * 1.08], [name], font_size=14,
                                 text_color=colour, shape=None, show_points=False,
                                 always_visible=True)
    plotter.add_point_labels([origin - axes[2] * size * 2.5], [f"LiDAR {run.sensor.name}"],
                             font_size=15, shape=None, text_color=SENSOR_COLOUR,
                             show_points=False, always_visible=True)
    for name, centre in zip(run.noisy.frame.target_names, centres):
        plotter.add_point_labels([centre + axes[2] * 0.5 * float(np.ptp(box[:, 2]) + 1.0)],
                                 [name], font_size=15, shape=None, text_color="#333333",
                                 show_points=False, always_visible=True)
    focus = origin + 0.5 * (depth if depth > 0 else far) * axes[0]
    look(plotter, focus, -0.5 * axes[0] - 1.0 * axes[1] + 0.45 * axes[2], axes[2], zoom=1.45)
    plotter.add_axes(color="black", xlabel="X", ylabel="Y", zlabel="Z")
    targets = ", ".join(f"{name} centre at {np.linalg.norm(c - origin):.1f} m"
                        for name, c in zip(run.noisy.frame.target_names, centres))
    _title(plotter, f"Scene set-up at t = {run.noisy.frame.t_start:g} s, scene frame (cf. paper "
                    f"Fig. 7)\nLiDAR (red) {run.sensor.name}, FOV {_fov_text(run.sensor)}; "
                    f"{targets}")
    return save_plotter(plotter, path)


def _fov_text(sheet: SensorDatasheet) -> str:
    if sheet.fov_type == "circular":
        return f"{sheet.fov_h_deg:g}° circular"
    return f"{sheet.fov_h_deg:g}° × {sheet.fov_v_deg:g}° {sheet.fov_type}"


# ---- Fig. 11: without and with errors ---------------------------------------------------
def plane_keys(cloud: Any, targets: Any) -> np.ndarray:
    """For every point, the plane of the target meshes it hit as a row ``(target, unit
    normal, offset)`` (NaN for false alarms), comparable between clouds of the same targets.

    Faces of one target with the same unit normal and the same offset along it (to 0.1 mm,
    in the body frame, so motion does not matter) lie in one plane, whether or not they
    touch.
    """
    keys = np.full((len(cloud), 5), np.nan)
    target, face = cloud["target"].astype(np.int64), cloud["face_index"].astype(np.int64)
    for t, tgt in enumerate(targets):
        rows = np.flatnonzero((target == t) & (face >= 0))
        if not len(rows):
            continue
        mesh = tgt.mesh
        normals = mesh.face_normals[face[rows]]
        offsets = np.einsum("ij,ij->i", normals, mesh.vertices[mesh.faces[face[rows], 0]])
        keys[rows] = np.column_stack([np.full(len(rows), t), np.round(normals, 4),
                                      np.round(offsets, 4)])
    return keys


def plane_ids(clouds: list[Any], targets: Any) -> list[np.ndarray]:
    """For every point of each cloud, an integer naming the plane it hit (the same plane has
    the same id in every cloud; -1 for false alarms); see :func:`plane_keys`."""
    keys = [plane_keys(c, targets) for c in clouds]
    both = np.vstack(keys) if keys else np.zeros((0, 5))
    ids = np.full(len(both), -1, dtype=np.int64)
    valid = ~np.isnan(both).any(axis=1)
    if valid.any():
        ids[valid] = np.unique(both[valid], axis=0, return_inverse=True)[1].reshape(-1)
    return np.split(ids, np.cumsum([len(k) for k in keys])[:-1])


def flat_patch(points: np.ndarray, planes: np.ndarray, n_points: int = 1500
               ) -> tuple[np.ndarray, np.ndarray, float, int]:
    """A flat patch to zoom on: centre, unit normal (toward the sensor at the origin), radius
    and the plane it lies on.

    Takes the plane with most points (see :func:`plane_ids`), the point nearest its
    median, the ``n_points`` points of that facet nearest to it (the radius reaches the
    farthest), and fits a plane. The patch never straddles an edge: points of other faces are
    not part of it.
    """
    labels, counts = np.unique(planes[planes >= 0], return_counts=True)
    plane = int(labels[np.argmax(counts)])
    mine = points[planes == plane]
    median = np.median(mine, axis=0)
    centre = mine[np.argmin(np.linalg.norm(mine - median, axis=1))]
    dist = np.linalg.norm(mine - centre, axis=1)
    k = min(n_points, len(mine)) - 1
    radius = float(np.partition(dist, k)[k])
    near = mine[dist <= radius]
    mean = near.mean(axis=0)
    normal = np.linalg.svd(near - mean, full_matrices=False)[2][2]
    if normal @ (-mean) < 0:
        normal = -normal
    return mean, normal, max(radius, 1e-3), plane


@dataclass
class PatchView:
    """The flat patch of Fig. 11 in one cloud: the points on it in the patch frame (m; x, y in
    the plane, z along its normal) and their spread off the plane."""

    local: np.ndarray
    spread_mm: float


def patch_views(run: Run, patch_points: int = 1500) -> tuple[dict[str, PatchView], float]:
    """The flat patch of Fig. 11 in the clouds without and with errors (keys ``clean`` and
    ``noisy``), and its radius (m).

    A point belongs to the patch when its pulse hit the patch's planar facet (its
    ``face_index``, so the clean cloud lies exactly on the plane) within the patch radius.
    """
    clean_planes, noisy_planes = plane_ids([run.clean, run.noisy], run.simulation.targets)
    p_centre, normal, radius, plane = flat_patch(run.clean.xyz_true, clean_planes, patch_points)
    frame = _patch_frame(normal)
    views = {}
    for key, cloud, planes in (("clean", run.clean, clean_planes),
                               ("noisy", run.noisy, noisy_planes)):
        local = (cloud.xyz - p_centre) @ frame.T
        keep = (planes == plane) & (np.hypot(local[:, 0], local[:, 1]) < radius)
        spread = 1e3 * float(np.std(local[keep, 2])) if keep.any() else float("nan")
        views[key] = PatchView(local[keep], spread)
    return views, radius


def _patch_frame(normal: np.ndarray) -> np.ndarray:
    """Rows: two in-plane unit axes (the first as horizontal as possible) and the normal."""
    helper = np.array([0.0, 0.0, 1.0]) if abs(normal[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(helper, normal)
    u /= np.linalg.norm(u)
    return np.vstack([u, np.cross(normal, u), normal])


def _nice(value: float) -> float:
    """``value`` rounded down to 1, 2 or 5 times a power of ten (at least 1)."""
    if value <= 1:
        return 1.0
    power = 10 ** math.floor(math.log10(value))
    return max(m * power for m in (1, 2, 5) if m * power <= value)


def errors_figure(run: Run, path: str | Path, *, patch_points: int = 1500,
                  exaggeration: float | None = None,
                  window_size: tuple[int, int] = (1500, 1500)) -> Path:
    """The cloud without (left) and with (right) errors: whole, face-on close-up, edge-on (Fig. 11).

    Parameters
    ----------
    run
        The run.
    path
        PNG to write.
    patch_points
        About how many points the close-up patch holds (its radius follows).
    exaggeration
        Stretch of the surface-normal axis in the edge-on row, so that the range error shows
        (default: the datasheet's 1σ range error becomes 8 % of the patch radius).
    window_size
        Pixels (width, height).
    """
    clean, noisy = run.clean, run.noisy
    plotter = new_plotter(shape=(3, 2), window_size=window_size)
    both = np.vstack([clean.xyz, noisy.xyz]) if len(clean) + len(noisy) else np.zeros((1, 3))
    centre = (both.min(axis=0) + both.max(axis=0)) / 2
    lo, hi = np.percentile(np.concatenate([clean["range"], noisy["range"]]), [1, 99]) \
        if len(both) > 1 else (0.0, 1.0)
    labels = ("a) without errors", "b) with angular and range errors")
    for col, (cloud, label) in enumerate(zip((clean, noisy), labels)):
        plotter.subplot(0, col)
        add_coloured_points(plotter, cloud.xyz, PointColours(cloud["range"], "range (m)"), 3.0,
                             clim=(float(lo), float(hi)), bar_below=True)
        look(plotter, centre, oblique_view(centre), np.array([0.0, 0.0, 1.0]), zoom=1.3)
        _title(plotter, f"{label}: {len(cloud):,} points (cf. paper Fig. 11)", 11)
    if len(clean) < 10:
        return save_plotter(plotter, path)
    views, radius = patch_views(run, patch_points)
    sigma = run.sensor.range_precision_m
    stretch = exaggeration or (_nice(0.08 * radius / sigma) if sigma > 0 else 1.0)
    for col, (key, colour, label) in enumerate(zip(("clean", "noisy"),
                                                   (CLEAN_COLOUR, NOISY_COLOUR), labels)):
        view = views[key]
        plotter.subplot(1, col)
        add_points(plotter, view.local * [1.0, 1.0, 0.0], 5.0, color=colour)
        plotter.enable_parallel_projection()
        look(plotter, np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0]))
        plotter.camera.parallel_scale = 1.05 * radius
        _title(plotter, f"{label[:2]} flat patch face-on, {2 * radius:.2f} m across: "
                        f"{len(view.local):,} points", 10)
        plotter.subplot(2, col)
        add_points(plotter, view.local * [1.0, 1.0, stretch], 4.0, color=colour)
        plotter.enable_parallel_projection()
        look(plotter, np.zeros(3), np.array([0.0, -1.0, 0.0]), np.array([0.0, 0.0, 1.0]))
        plotter.camera.parallel_scale = 0.45 * radius
        _title(plotter, f"{label[:2]} same patch edge-on, normal axis ×{stretch:g}: "
                        f"spread off the plane (1 sigma) = {view.spread_mm:.1f} mm", 10)
    return save_plotter(plotter, path)


# ---- Fig. 12: mesh and cloud -------------------------------------------------------------
def cloud_figure(run: Run, path: str | Path, colour_by: str = "part",
                 window_size: tuple[int, int] = (1800, 900)) -> Path:
    """a) The meshes coloured by part; b) the meshes with the cloud coloured by ``colour_by``.

    ``colour_by``: ``part``, ``range``, ``time``, ``intensity`` (when the cloud has it) or any
    numeric column (see :func:`lidarsim_core.report.colouring.point_colours`).
    """
    cloud = run.noisy
    colours = point_colours(cloud, colour_by)
    meshes = _meshes_in_sensor_frame(run)
    names = short_part_names(run.simulation.part_names)
    corners = np.vstack([np.array(m.bounds).reshape(3, 2).T for m in meshes])
    centre = (corners.min(axis=0) + corners.max(axis=0)) / 2
    view = oblique_view(centre)
    plotter = new_plotter(shape=(1, 2), window_size=window_size)
    plotter.subplot(0, 0)
    present = set()
    for poly in meshes:
        for idx in np.unique(poly.cell_data["part"]):
            plotter.add_mesh(poly.extract_cells(np.flatnonzero(poly.cell_data["part"] == idx)),
                             color=part_colour(int(idx)), specular=0.2)
            present.add(int(idx))
    add_legend(plotter, [names[i] for i in sorted(present)], sorted(present), "rectangle")
    look(plotter, centre, view, np.array([0.0, 0.0, 1.0]), zoom=1.05)
    _title(plotter, "a) target model by part (cf. paper Fig. 12a)")
    plotter.subplot(0, 1)
    for poly in meshes:
        plotter.add_mesh(poly, color=MESH_COLOUR, opacity=0.25)
    add_coloured_points(plotter, cloud.xyz, colours, 3.5, bar_below=True)
    look(plotter, centre, view, np.array([0.0, 0.0, 1.0]), zoom=1.05)
    _title(plotter, f"b) simulated cloud, {len(cloud):,} points, coloured by {colour_by} "
                    "(cf. paper Fig. 12b)")
    plotter.link_views()
    return save_plotter(plotter, path)
