"""The ``lidarsim dataset`` command: many frames, one file each, resumable, serial or on Dask."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from .app import app
from .errors import run_guarded
from .output import console


@app.command()
def dataset(source: Path = typer.Argument(..., help="Scenario file, or a dataset file with a "
                                                    "'sequences:' list (see docs/datasets.md)."),
            out: Path = typer.Option(..., "--out", "-o", help="Dataset directory (new, empty, "
                                     "or one this same command started: it then resumes)."),
            frames: Optional[int] = typer.Option(None, min=1, help="Frames per sequence "
                                                 "(default: the scenario's scan.frames)."),
            fmt: Optional[str] = typer.Option(None, "--format", help="Exporter: ply (default), "
                                              "las, laz, pcd, npz, csv, a plugin's, or mcap "
                                              "(one ROS 2 bag per sequence), or shards "
                                              "(training samples in tar shards)."),
            workers: Optional[int] = typer.Option(None, min=1, help="Run on a local Dask "
                                                  "cluster of this many processes."),
            scheduler: Optional[str] = typer.Option(None, help="Run on the Dask cluster at "
                                                    "this address (e.g. tcp://head:8786)."),
            verify: bool = typer.Option(False, help="Re-hash finished frames before skipping "
                                        "them."),
            quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar, no "
                                       "summary."),
            livox: bool = typer.Option(False, "--livox", help="With --format mcap: also write "
                                       "livox_ros_driver2/msg/CustomMsg on /livox/lidar."),
            sequences: Optional[int] = typer.Option(None, "--sequences", min=1,
                                                    help="Sequences drawn from every "
                                                    "randomised entry of the dataset file."),
            ) -> None:
    """Generate a dataset: one file per frame, poses, manifest with checksums, splits."""
    run_guarded(lambda: _dataset(source, out, frames, fmt, workers, scheduler, verify, quiet,
                                  livox, sequences))


def _dataset(source: Path, out: Path, frames: int | None, fmt: str | None,
             workers: int | None, scheduler: str | None, verify: bool, quiet: bool,
             livox: bool = False, sequences: int | None = None) -> None:
    from ..base.errors import ConfigError
    from ..base.limits import check_frames
    from ..dataset import generate_dataset
    from .progress import FrameBar, prepare_long_run

    if workers is not None and scheduler is not None:
        raise ConfigError("give --workers or --scheduler, not both", field="workers")
    if frames is not None:
        check_frames(frames, source=None, field="--frames")
    prepare_long_run()  # a bar while a first run on this machine compiles the kernels
    result = generate_dataset(source, out, frames=frames, format=fmt, workers=workers,
                              scheduler=scheduler, quiet=quiet, verify=verify,
                              livox=livox, display=FrameBar(), sequences=sequences)
    if quiet:
        return
    rate = result.frames_written / result.elapsed_s if result.elapsed_s > 0 else 0.0
    from .output import markup_safe as escape

    console().print(
        f"dataset {escape(str(result.root))}: {result.frames_total} frames ({result.frames_written} written, "
        f"{result.frames_skipped} already done), {result.points_written:,} points in "
        f"{result.elapsed_s:.1f} s ({rate:.2f} frames/s) → {result.manifest.name}")
