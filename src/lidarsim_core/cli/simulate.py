"""``lidarsim simulate SCENARIO --out FILE``: one frame or a sequence into point-cloud files."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Optional

import typer
from .output import markup_safe as escape

from .app import app
from .errors import check_seed_option, run_guarded
from .output import console as make_console
from .progress import warm_kernels

#: Bytes of points ``lidarsim simulate`` holds in memory per frame before spilling them to a
#: temporary file (the frame is then streamed to its output file).
SPOOL_MEMORY_BYTES = 64 * 2 ** 20


# ---- simulate ----------------------------------------------------------------------------
@app.command()
def simulate(scenario: Path = typer.Argument(..., help="Scenario file (YAML, TOML or JSON)."),
             out: Path = typer.Option(..., "--out", "-o",
                                      help="Output file; the suffix picks the format: .ply, "
                                           ".pcd, .las, .laz, .npz, .csv, or .mcap (one ROS 2 "
                                           "bag of every frame). With several frames, put "
                                           "'{frame}' in the name, e.g. cloud_{frame:04d}.ply."),
             frame: Optional[int] = typer.Option(None, help="Only this frame (default: all)."),
             fmt: Optional[str] = typer.Option(None, "--format", help="Exporter name."),
             overwrite: bool = typer.Option(False, "--overwrite",
                                            help="Replace existing output files."),
             backend: Optional[str] = typer.Option(None, help="Override the scenario's backend."),
             seed: Optional[int] = typer.Option(None, help="Override the scenario's seed."),
             livox: bool = typer.Option(False, "--livox", help="With a .mcap bag: also write "
                                        "livox_ros_driver2/msg/CustomMsg on /livox/lidar."),
             range_image: bool = typer.Option(False, "--range-image", help="Also write each "
                                              "frame's organised range image: <name>.range.npz"
                                              " and a 16-bit <name>.range.png."),
             dialect: Optional[str] = typer.Option(
                 None, "--dialect", help="PLY and CSV column names: 'standard' (default) or "
                                         "'cloudcompare' (scalar_<column>: every column a "
                                         "named scalar field in CloudCompare)."),
             ) -> None:
    """Simulate a scenario file and write the point cloud(s), or one ROS 2 bag (.mcap)."""
    run_guarded(lambda: _simulate(scenario, out, frame, fmt, overwrite, backend, seed, livox,
                                  range_image, dialect))


def _simulate(path: Path, out: Path, frame: int | None, fmt: str | None, overwrite: bool,
              backend: str | None, seed: int | None, livox: bool = False,
              range_image: bool = False, dialect: str | None = None) -> None:
    from ..base.errors import ConfigError, OutputError
    from ..base.outputs import check_file, make_parent
    from ..io.paths import frame_paths, has_frame_field
    from ..io.points import PointSpool
    from ..io.write import write_points_file
    from ..pipeline.simulation import Simulation
    from ..plugins.resolve import exporter_for
    from ..scenario.load import load_scenario
    from .output import RayProgress

    check_seed_option(seed)
    scenario = load_scenario(path)
    changes: dict[str, Any] = {}
    if backend is not None:
        changes["backend"] = {"name": backend}
    if seed is not None:
        changes["seed"] = seed
    if changes:
        scenario = scenario.with_updates(**changes)
    n_frames = scenario.scan.frames
    if frame is not None and not 0 <= frame < n_frames:
        raise ConfigError(f"--frame {frame} is outside 0..{n_frames - 1}", source=path,
                          field="scan.frames")
    frames = [frame] if frame is not None else list(range(n_frames))
    if dialect is not None and not (fmt in ("ply", "csv") or
                                    (fmt is None and out.suffix.lower() in (".ply", ".csv"))):
        raise OutputError("--dialect applies to PLY and CSV output (--out cloud.ply or "
                          "cloud.csv)", source=out)
    if out.suffix.lower() == ".mcap" or fmt == "mcap":  # every frame into one ROS 2 bag
        from .bag import simulate_to_bag

        return simulate_to_bag(scenario, frames, out, overwrite=overwrite, livox=livox,
                               range_image=range_image, source=path)
    if livox:
        raise OutputError("--livox applies to a ROS 2 bag (--out run.mcap)", source=out)
    templated = has_frame_field(out)
    if len(frames) > 1 and not templated:
        raise OutputError(f"the scenario has {len(frames)} frames: put '{{frame}}' in --out "
                          "(e.g. cloud_{frame:04d}.ply) or choose one with --frame", source=out)
    targets = frame_paths(out, frames) if templated else [out]
    try:  # unknown format or option: fail before simulating
        exporter = exporter_for(targets[0], fmt,
                                options={"dialect": dialect} if dialect is not None else None)
    except OutputError as exc:
        if fmt:
            raise
        raise OutputError(f"{exc.message}; or .mcap for one ROS 2 bag of every frame",
                          source=exc.source, field=exc.field) from None
    for target in targets:  # every output is checked before any work (lidarsim_core.base.outputs)
        check_file(target, overwrite=overwrite)
    if range_image:  # the cloud and its range image are one group: all checked, then written
        from ..base.outputs import check_group
        from ..io.rangeimage import range_image_files

        check_group([f for target in targets for f in range_image_files(target)],
                    overwrite=overwrite)
    sim = Simulation(scenario)  # guards third-party components itself
    warm_kernels()  # a bar while a first run on this machine compiles them
    from ..base.outputs import check_not_input

    for target in targets:  # the meshes and keyframes the simulation has just read too
        check_not_input(target)
    if range_image:  # the images' layout, checked before anything is simulated
        from ..io.rangeimage import check_layout

        try:
            check_layout(sim.pattern, [(i.t_start, i.t_end) for i in sim.frame_infos(frames)])
        except ConfigError as exc:  # name the scenario file the field is in
            raise ConfigError(exc.message, source=exc.source or path, field=exc.field) from None
    console = make_console()
    for f, target in zip(frames, targets):
        t0 = time.perf_counter()
        info = sim.frame_info(f)
        # stream the frame through a spool (memory, then a temporary file): any size fits
        with PointSpool(info, memory_limit=SPOOL_MEMORY_BYTES) as spool:
            with RayProgress(info.rays_emitted, f"frame {f}") as progress:
                spool.extend(_counted_chunks(sim, f, progress))
            make_parent(target)
            write_points_file(spool, target, exporter=exporter, overwrite=overwrite)
            points = len(spool)
            if range_image:
                from ..io.rangeimage import save_range_image

                save_range_image(spool.to_cloud(), sim.pattern, target, overwrite=overwrite)
        console.print(f"frame {f}: {points:,} points from {info.rays_emitted:,} rays "
                      f"in {time.perf_counter() - t0:.2f} s → {escape(str(target))}")
        if points == 0:
            console.print(f"note: frame {f} is empty: no point was detected within "
                          f"{sim.sensor.range_min_m:g}–{sim.sensor.range_max_m:g} m (targets "
                          "out of range, outside the field of view, behind the sensor or too "
                          "faint)")


def _counted_chunks(sim: Any, frame: int, progress: Any) -> Any:
    """The chunks of ``frame``, advancing ``progress`` by the pulses of each (every chunk but
    the last holds the scenario's ``chunk_rays`` pulses)."""
    k0, k1 = sim.frame_rays(frame)
    step = sim.scenario.chunk_rays
    done = k0
    for chunk in sim.iter_chunks(frame):
        pulses = min(step, k1 - done)
        done += pulses
        progress.advance(pulses)
        yield chunk
