"""The ``lidarsim pattern`` and ``lidarsim coverage`` commands: export and assess scan patterns."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import typer

from .app import app
from .errors import run_guarded
from .output import console as make_console


def console() -> Any:
    from .output import console

    return console()


def _pattern(sensor: str, options: list[str]) -> Any:
    """The scan pattern of a catalogue sensor or datasheet file, with ``KEY=VALUE`` overrides."""
    from ..base.config_io import parse_option_value
    from ..base.errors import ConfigError
    from ..plugins.resolve import get_sensor, pattern_for

    sheet = get_sensor(sensor, field="SENSOR")
    overrides: dict[str, Any] = {}
    for item in options:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--option expects KEY=VALUE, got {item!r}", field="--option")
        overrides[key.strip()] = parse_option_value(value, field=f"--option {key.strip()}")
    return pattern_for(sheet, overrides, source=sensor)


def _check_positive(value: float, flag: str) -> None:
    from .errors import check_number_option

    check_number_option(value, flag, positive=True)


@app.command()
def pattern(sensor: str = typer.Argument(..., help="Catalogue name or datasheet file."),
            duration: float = typer.Option(..., "--duration", help="Scan time to export (s)."),
            out: Path = typer.Option(..., "--out", "-o", help="Output .npz file."),
            start: float = typer.Option(0.0, "--start", help="Start time (s from scan start)."),
            option: list[str] = typer.Option([], "--option", help="Pattern option override, "
                                                                 "KEY=VALUE (repeatable)."),
            overwrite: bool = typer.Option(False, "--overwrite",
                                           help="Replace an existing output file."),
            ) -> None:
    """Write the rays a sensor emits: t (s), direction (N, 3) in the sensor frame, channel."""
    run_guarded(lambda: _export(sensor, duration, out, start, option, overwrite))


def _export(sensor: str, duration: float, out: Path, start: float, options: list[str],
            overwrite: bool) -> None:
    import numpy as np

    from ..base.atomic import atomic_output
    from ..base.errors import OutputError
    from ..base.limits import check_pattern_window
    from ..base.outputs import check_file, make_parent
    from .errors import check_number_option

    _check_positive(duration, "--duration")
    check_number_option(start, "--start", minimum=0.0)
    if out.suffix.lower() != ".npz":
        raise OutputError("the ray export is written as .npz; give a file ending in .npz",
                          source=out)
    check_file(out, overwrite=overwrite)  # the one overwrite policy (lidarsim_core.base.outputs)
    pat = _pattern(sensor, options)
    check_pattern_window(pat.rate_hz, start, duration, budget="pattern_rays")
    batch = pat.rays(start, start + duration)
    buffer = io.BytesIO()
    np.savez_compressed(buffer, t=batch.t, direction=batch.direction, channel=batch.channel,
                        index=batch.index, sensor=np.array(pat.sensor.name),
                        pattern=np.array(pat.name))
    make_parent(out)
    with atomic_output(out, overwrite=overwrite) as stream:
        stream.write(buffer.getvalue())
    from .output import markup_safe as escape

    make_console().print(f"{escape(pat.sensor.name)} ({escape(pat.name)}): {len(batch):,} rays in "
                     f"\\[{start:g}, {start + duration:g}) s → {escape(str(out))}")


@app.command()
def coverage(sensor: str = typer.Argument(..., help="Catalogue name or datasheet file."),
             time_s: float = typer.Option(..., "--time", help="Integration time (s)."),
             cell_deg: float = typer.Option(0.5, "--cell-deg", help="Cell size (deg)."),
             bin_deg: float = typer.Option(5.0, "--bin-deg",
                                           help="Off-axis bin width of the density profile."),
             start: float = typer.Option(0.0, "--start", help="Start time (s)."),
             option: list[str] = typer.Option([], "--option", help="Pattern option override, "
                                                                  "KEY=VALUE (repeatable)."),
             as_json: bool = typer.Option(False, "--json", help="Print JSON."),
             ) -> None:
    """Fraction of the FOV hit within an integration time, and density vs off-axis angle."""
    run_guarded(lambda: _coverage(sensor, time_s, cell_deg, bin_deg, start, option, as_json))


def _coverage(sensor: str, time_s: float, cell_deg: float, bin_deg: float, start: float,
              options: list[str], as_json: bool) -> None:
    from ..base.limits import check, check_pattern_window
    from ..patterns.fov import coverage_cells, fov_coverage
    from .errors import check_number_option
    from .output import Column, print_json, print_table

    _check_positive(time_s, "--time")
    check_number_option(cell_deg, "--cell-deg", positive=True, maximum=360.0)
    check_number_option(bin_deg, "--bin-deg", positive=True, maximum=180.0)
    check_number_option(start, "--start", minimum=0.0)
    check("profile_bins", 180.0 / bin_deg, what=f"--bin-deg {bin_deg:g}", field="--bin-deg")
    pat = _pattern(sensor, options)
    check("coverage_cells", coverage_cells(pat.sensor, cell_deg), field="--cell-deg",
          what=f"--cell-deg {cell_deg:g} over a {pat.sensor.fov_h_deg:g}° field of view")
    check_pattern_window(pat.rate_hz, start, time_s, budget="rays_per_frame",
                         duration_field="--time")
    report = fov_coverage(pat, time_s, cell_deg, t_start_s=start, bin_deg=bin_deg)
    if as_json:
        print_json(report.to_dict())
        return
    from .output import markup_safe

    console = make_console()
    console.print(f"[bold]{markup_safe(report.sensor)}[/] ({markup_safe(report.pattern)}): {100 * report.coverage:.1f} % "
                  f"of {report.cells_in_fov:,} cells of {cell_deg:g}° hit in {time_s:g} s "
                  f"({report.rays:,} rays; {report.projection} cells)")
    print_table([Column(c, right=True) for c in ("off-axis °", "points", "solid angle deg²",
                                                 "points/deg²", "points/deg²/s")],
                [[f"{b.off_axis_lo_deg:g}–{b.off_axis_hi_deg:g}", f"{b.points:,}",
                  f"{b.solid_angle_deg2:.1f}", f"{b.points_per_deg2:.3g}",
                  f"{b.points_per_deg2_per_s:.3g}"] for b in report.density])
