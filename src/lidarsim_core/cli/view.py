"""``lidarsim view PATH``: look at any cloud lidarsim wrote, or a run directory, with pyvista.

PATH is a point-cloud file (``.ply``, ``.pcd``, ``.las``, ``.laz``, ``.npz``, ``.csv``, read by
:func:`lidarsim_core.read`) or a run directory: its clouds of one frame (``--frame``, default
the lowest), plus, when the directory holds its ``scenario.yaml``, the target meshes at the
frame's ground-truth pose. Everything is drawn in the sensor frame (the sensor is the red
dot at the origin). Without ``--screenshot`` an interactive window opens; with it the view is
rendered off-screen to a PNG (extra ``viz``).
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


def _clouds_of_run(directory: Path, frame: int | None) -> list[tuple[Path, Any]]:
    from ..base.errors import ConfigError
    from ..io.reader import READ_SUFFIXES, read
    from ..io.sidecar import frame_is_complete

    files = sorted(p for p in directory.iterdir()
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
        if screenshot.exists() and not overwrite:
            raise OutputError("output file exists (use --overwrite to replace it)",
                              source=screenshot)
        parent = screenshot.parent if str(screenshot.parent) else Path(".")
        if not parent.is_dir():
            raise OutputError(f"output directory does not exist: {parent}", source=screenshot)
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
    _draw(plotter, clouds, colours, meshes)
    title = path.name if not path.is_dir() else \
        f"{path.name}: frame {clouds[0][1].frame.frame}, {', '.join(p.name for p, _ in clouds)}"
    plotter.add_text(title, font_size=10, color="black")
    if screenshot is None:
        plotter.show()
        return
    from ..report.render import save_plotter

    save_plotter(plotter, screenshot)
    n = sum(len(c) for _, c in clouds)
    typer.echo(terminal_safe(f"wrote {screenshot} ({n:,} points coloured by {color_by}"
                             f"{f', {len(meshes)} target mesh(es)' if meshes else ''})"))


def _draw(plotter: Any, clouds: list[tuple[Path, Any]], colours: list[Any],
          meshes: list[Any]) -> None:
    import numpy as np

    from ..report.plotting import add_coloured_points, add_points, look, oblique_view
    from ..report.scene import MESH_COLOUR, SENSOR_COLOUR

    for poly in meshes:
        plotter.add_mesh(poly, color=MESH_COLOUR, opacity=0.35, show_edges=False)
    points = [c.xyz for _, c in clouds]
    size = 4.0
    for xyz, colour in zip(points, colours):
        add_coloured_points(plotter, xyz, colour, size)
    add_points(plotter, np.zeros((1, 3)), 12.0, color=SENSOR_COLOUR)
    everything = np.concatenate([p for p in points if len(p)] or [np.zeros((1, 3))])
    centre = everything.mean(axis=0)
    look(plotter, centre, oblique_view(centre), (0.0, 0.0, 1.0))
