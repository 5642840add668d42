"""``lidarsim poses``: write a sequence's ground-truth poses (JSON or CSV) from a scenario.

The poses come from the trajectories alone, so no ray is cast; run it beside
``lidarsim simulate`` (same scenario, same frames) to get the pose file of the clouds::

    lidarsim simulate approach.yaml --out 'out/cloud_{frame:04d}.ply'
    lidarsim poses approach.yaml --out out/poses.json --clouds 'cloud_{frame:04d}.ply'
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..base.terminal import terminal_safe

from .app import app
from .errors import run_guarded


@app.command()
def poses(scenario: Path = typer.Argument(..., help="Scenario file (YAML, TOML or JSON)."),
          out: Path = typer.Option(..., "--out", "-o",
                                   help="Pose file to write: .json or .csv."),
          clouds: Optional[str] = typer.Option(
              None, help="Cloud file name of each frame to record beside its poses, with "
                         "'{frame}', e.g. cloud_{frame:04d}.ply."),
          frame: Optional[int] = typer.Option(None, help="Only this frame (default: all)."),
          overwrite: bool = typer.Option(False, "--overwrite",
                                         help="Replace an existing pose file."),
          ) -> None:
    """Write the sensor and target poses of every frame (q_target_in_sensor, scalar-last)."""
    run_guarded(lambda: _poses(scenario, out, clouds, frame, overwrite))


def _poses(path: Path, out: Path, clouds: str | None, frame: int | None,
           overwrite: bool) -> None:
    from ..base.errors import ConfigError, OutputError
    from ..base.outputs import check_file, make_parent
    from ..io.groundtruth import write_ground_truth
    from ..io.paths import frame_paths
    from ..pipeline.simulation import sequence_frame_infos
    from ..scenario.load import load_scenario

    scenario = load_scenario(path)
    n_frames = scenario.scan.frames
    if frame is not None and not 0 <= frame < n_frames:
        raise ConfigError(f"--frame {frame} is outside 0..{n_frames - 1}", source=path,
                          field="scan.frames")
    if clouds is not None and n_frames > 1 and frame is None and "{frame" not in clouds:
        raise OutputError("--clouds needs '{frame}' in it for a sequence "
                          "(e.g. cloud_{frame:04d}.ply)", source=clouds)
    check_file(out, overwrite=overwrite)  # the one overwrite policy (lidarsim_core.base.outputs)
    indices = [frame] if frame is not None else list(range(n_frames))
    # the same template rules as --out: only {frame}, with a zero-padded width
    names = [str(p) for p in frame_paths(clouds, indices)] if clouds is not None else None
    infos = sequence_frame_infos(scenario, indices)
    make_parent(out)
    write_ground_truth(out, infos, clouds=names, overwrite=overwrite)
    typer.echo(terminal_safe(f"wrote poses of {len(infos)} frame(s) and "
                             f"{len(infos[0].target_names)} target(s) to {out}"))
