"""``lidarsim view PATH``: look at any cloud lidarsim wrote, or a run directory, with pyvista.

PATH is a point-cloud file (``.ply``, ``.pcd``, ``.las``, ``.laz``, ``.npz``, ``.csv``, read by
:func:`lidarsim_core.read`) or a run directory: its clouds of one frame (``--frame``, default
the lowest), plus, when the directory holds its ``scenario.yaml``, the target meshes at the
frame's ground-truth pose. A dataset made from one scenario (``lidarsim dataset``), or one
sequence folder of a dataset, is a run directory too: its clouds are in ``frames/``. The first
cloud is coloured by ``--color-by``, any other cloud of the frame (the run without errors)
in one solid colour named in a legend. Everything is drawn in the sensor frame (the sensor is
the red dot at the origin, the axes in the corner); the view frames the targets and their
points, with a scale bar under them. Without ``--screenshot`` an interactive window opens;
with it the view is rendered off-screen to a PNG (extra ``viz``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

import typer

from ..base.terminal import terminal_safe

from .app import app
from .errors import run_guarded


@app.command()
def view(path: Path = typer.Argument(..., help="A cloud file lidarsim wrote, or a run "
                                               "directory."),
         color_by: str = typer.Option("part", "--color-by",
                                      help="part, range, intensity, time or any numeric "
                                           "column."),
         screenshot: Optional[Path] = typer.Option(None, "--screenshot",
                                                   help="Render off-screen to this PNG "
                                                        "instead of opening a window."),
         frame: Optional[int] = typer.Option(None, help="Frame to show from a run directory."),
         overwrite: bool = typer.Option(False, help="Replace an existing screenshot."),
         ) -> None:
    """Show a point cloud (or a run directory with its target meshes) in 3-D."""
    run_guarded(lambda: _view(path, color_by, screenshot, frame, overwrite))


def _cloud_folder(directory: Path) -> Path:
    """Where a run directory keeps its clouds: itself, or ``frames/`` of a dataset made from
    one scenario (``lidarsim dataset``)."""
    frames = directory / "frames"
    return frames if frames.is_dir() and not _has_clouds(directory) else directory


def _has_clouds(directory: Path) -> bool:
    from ..io.reader import READ_SUFFIXES

    return any(p.suffix.lower() in READ_SUFFIXES and p.is_file() for p in directory.iterdir())


def _clouds_of_run(directory: Path, frame: int | None) -> list[tuple[Path, Any]]:
    from ..base.errors import ConfigError
    from ..io.reader import READ_SUFFIXES, read
    from ..io.sidecar import frame_is_complete

    folder = _cloud_folder(directory)
    if (directory / "sequences").is_dir() and folder == directory and not _has_clouds(folder):
        raise ConfigError("a dataset of several sequences: view one of them, "
                          f"e.g. {directory / 'sequences' / '<name>'}", source=directory)
    files = sorted(p for p in folder.iterdir()
                   if p.suffix.lower() in READ_SUFFIXES and frame_is_complete(p) is not None)
    if not files:
        raise ConfigError("no point cloud written by lidarsim (a file with its .json sidecar) "
                          "in the directory", source=directory)
    clouds = [(p, read(p)) for p in files]
    frames = sorted({c.frame.frame for _, c in clouds})
    chosen = frames[0] if frame is None else frame
    if chosen not in frames:
        raise ConfigError(f"no cloud of frame {chosen}; frames present: {frames}",
                          source=directory, field="--frame")
    # one cloud per file content: the same frame may be there in several formats
    seen: set[tuple[str, str]] = set()
    out = []
    for p, c in clouds:
        key = (c.metadata_json(), str(len(c)))
        if c.frame.frame == chosen and key not in seen:
            seen.add(key)
            out.append((p, c))
    return out


def _meshes(directory: Path, cloud: Any) -> list[Any]:
    """Target meshes posed in the sensor frame at frame start (from the run's scenario)."""
    from ..pipeline.simulation import Simulation
    from ..records.groundtruth import frame_record, pose_from_record
    from ..report.run import SCENARIO_NAMES
    from ..report.scene import mesh_polydata
    from ..scenario.load import load_scenario

    scenario = next((directory / n for n in SCENARIO_NAMES if (directory / n).is_file()), None)
    if scenario is None:
        return []
    sim = Simulation(load_scenario(scenario))
    record = frame_record(cloud.frame)
    return [mesh_polydata(target.mesh, pose_from_record(rec), target.part_offset)
            for target, rec in zip(sim.targets, record["targets"])]


def _view(path: Path, color_by: str, screenshot: Path | None, frame: int | None,
          overwrite: bool) -> None:
    from ..base.errors import OutputError
    from ..io.reader import read
    from ..report.colouring import point_colours

    if screenshot is not None:
        if screenshot.suffix.lower() != ".png":
            raise OutputError("the screenshot must be a .png file", source=screenshot)
        from ..base.outputs import check_file

        check_file(screenshot, overwrite=overwrite)  # a missing folder is created below
    from .progress import status

    status(f"reading {path}")
    if path.is_dir():
        clouds = _clouds_of_run(path, frame)
        meshes = _meshes(path, clouds[0][1])
    else:
        clouds, meshes = [(path, read(path))], []
    colours = [point_colours(c, color_by) for _, c in clouds]  # bad --color-by: fail early
    if screenshot is not None:
        from ..report.render import new_plotter, rendering_backend

        rendering_backend()
        plotter = new_plotter(window_size=(1200, 800))
    else:
        import pyvista as pv

        plotter = pv.Plotter(window_size=[1200, 800])
        plotter.set_background("white")
    status("rendering" if screenshot is not None else "opening the viewer window")
    _draw(plotter, clouds, colours, meshes)
    title = path.name if not path.is_dir() else \
        f"{path.name}: frame {clouds[0][1].frame.frame}, {', '.join(p.name for p, _ in clouds)}"
    plotter.add_text(title, font_size=10, color="black")
    if screenshot is None:
        plotter.show()
        return
    from ..base.outputs import make_parent
    from ..report.render import save_plotter

    make_parent(screenshot)
    save_plotter(plotter, screenshot)
    n = sum(len(c) for _, c in clouds)
    typer.echo(terminal_safe(f"wrote {screenshot} ({n:,} points coloured by {color_by}"
                             f"{f', {len(meshes)} target mesh(es)' if meshes else ''})"))


#: Solid colours of the clouds after the first in one view (the first is coloured by
#: ``--color-by``), so that two clouds of a run (with and without errors) stay apart.
OTHER_CLOUD_COLOURS = ("magenta", "black", "darkorange", "teal")


def _draw(plotter: Any, clouds: list[tuple[Path, Any]], colours: list[Any],
          meshes: list[Any]) -> None:
    """The meshes, the first cloud coloured by ``colours[0]``, the others each in one solid
    colour with a legend, the sensor (red dot), axes and a scale bar; the camera frames the
    targets and their points, not the sensor."""
    import numpy as np

    from ..report.plotting import add_coloured_points, add_points, look, oblique_view
    from ..report.scene import MESH_COLOUR, SENSOR_COLOUR

    for poly in meshes:
        plotter.add_mesh(poly, color=MESH_COLOUR, opacity=0.35, show_edges=False)
    points = [c.xyz for _, c in clouds]
    size = 4.0
    if points:
        add_coloured_points(plotter, points[0], colours[0], size)
    legend = []
    for (path, _), xyz, colour in zip(clouds[1:], points[1:], OTHER_CLOUD_COLOURS * 8):
        add_points(plotter, xyz, size * 0.6, color=colour)
        legend.append([path.name, colour])
    if legend:  # upper left, under the title, wide enough for the names (VTK shrinks text)
        width = min(0.6, 0.03 + 0.0095 * max(len(name) for name, _ in legend))
        height = 0.035 * len(legend)
        box = plotter.add_legend(legend, bcolor="white", loc="upper left", face="circle",
                                 size=(width, height))
        box.SetPosition(0.01, 0.93 - height)
    add_points(plotter, np.zeros((1, 3)), 12.0, color=SENSOR_COLOUR)
    low, high = _extent(points, meshes)
    low = low - np.array([0.0, 0.0, 0.1 * float(np.max(high - low))])  # room for the bar
    centre = (low + high) / 2
    bounds = tuple(np.ravel(np.column_stack([low, high])))
    look(plotter, centre, oblique_view(centre), (0.0, 0.0, 1.0), zoom=1.25, bounds=bounds)
    plotter.add_axes(xlabel="X", ylabel="Y", zlabel="Z", line_width=3)  # the sensor frame
    _scale_bar(plotter, low, high)


def _extent(points: list[Any], meshes: list[Any]) -> tuple[Any, Any]:
    """Lower and upper corners of the clouds and meshes (the sensor's origin when empty)."""
    import numpy as np

    corners = [p for p in points if len(p)]
    corners += [np.array(m.bounds).reshape(3, 2).T for m in meshes]
    if not corners:
        return np.full(3, -1.0), np.full(3, 1.0)
    stacked = np.vstack([np.vstack([c.min(axis=0), c.max(axis=0)]) for c in corners])
    return stacked.min(axis=0), stacked.max(axis=0)


def _scale_bar(plotter: Any, low: Any, high: Any) -> None:
    """A bar of a round length (1, 2 or 5 × 10^k m, about a third of the scene's width) under
    the scene, with its length written beside it."""
    import math

    import numpy as np
    import pyvista as pv

    width = float(np.max(high - low)) or 1.0
    exponent = math.floor(math.log10(width / 3))
    length = min((m * 10 ** exponent for m in (1, 2, 5, 10)), key=lambda v: abs(v - width / 3))
    start = np.array([low[0], low[1], low[2]])
    end = start + np.array([0.0, length, 0.0])
    plotter.add_mesh(pv.Line(start, end), color="black", line_width=4)
    plotter.add_point_labels(np.array([(start + end) / 2]), [f"{length:g} m"], font_size=14,
                             text_color="black", shape=None, show_points=False,
                             always_visible=True)
