"""The ``lidarsim report`` command: figures and an HTML page of a run (needs the viz extra)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

import typer

from .app import app
from .errors import run_guarded


@app.command()
def report(run: Path = typer.Argument(..., help="Run directory: lidarsim .npz clouds and the "
                                                "scenario.yaml that produced them."),
           out: Optional[Path] = typer.Option(None, "--out", "-o",
                                              help="Output directory (default: RUN/report)."),
           scenario: Optional[Path] = typer.Option(None, "--scenario",
                                                   help="The scenario file, when it is not "
                                                        "RUN/scenario.yaml."),
           frame: Optional[int] = typer.Option(None, "--frame", help="Frame to show "
                                                                    "(default: the first)."),
           color_by: str = typer.Option("part", "--color-by",
                                        help="Colour of the cloud in Fig. 12: part, range, time, "
                                             "intensity (when simulated) or a column name."),
           coverage_time: Optional[float] = typer.Option(
               None, "--coverage-time", help="Integration time of the coverage map (s; default: "
                                             "the frame's duration)."),
           cell_deg: float = typer.Option(0.5, "--cell-deg", help="Coverage-map cell (deg)."),
           no_3d: bool = typer.Option(False, "--no-3d", help="Only the 2-D figures (no OpenGL "
                                                             "needed)."),
           overwrite: bool = typer.Option(False, "--overwrite", help="Replace report files "
                                          "already in --out."),
           ) -> None:
    """Write the report of a run: PNG figures after the seed paper's and one HTML page."""
    run_guarded(lambda: _report(run, out, scenario, frame, color_by, coverage_time, cell_deg,
                                not no_3d, overwrite))


def _report(run: Path, out: Path | None, scenario: Path | None, frame: int | None,
            color_by: str, coverage_time: float | None, cell_deg: float, three_d: bool,
            overwrite: bool = False) -> None:
    from ..report import write_report
    from .errors import check_number_option

    check_number_option(coverage_time, "--coverage-time", positive=True)
    check_number_option(cell_deg, "--cell-deg", positive=True, maximum=360.0)
    from .progress import status

    result = write_report(run, out, scenario=scenario, frame=frame, colour_by=color_by,
                          coverage_time_s=coverage_time, cell_deg=cell_deg, three_d=three_d,
                          overwrite=overwrite, progress=status)
    print_report_summary(result)


def print_report_summary(result: Any) -> None:
    """Print where a report went, its key numbers and its notes (used by ``demo`` too)."""
    from .output import markup_safe as escape

    from .output import console as make_console

    console = make_console()
    s = result.summary
    parts = []
    if "angular_sigma_deg" in s:
        parts.append(f"angular σ {s['angular_sigma_deg']:.4f}° "
                     f"(datasheet {s['angular_sigma_datasheet_deg']:g}°)")
    if "range_sigma_mm" in s:
        parts.append(f"range σ {s['range_sigma_mm']:.2f} mm "
                     f"(datasheet {s['range_sigma_datasheet_mm']:g} mm)")
    if "coverage" in s:
        parts.append(f"FOV coverage {100 * s['coverage']:.1f} % in {s['coverage_time_s']:g} s")
    if parts:
        console.print("report: " + "; ".join(parts))
    for note in result.notes:
        console.print(f"[yellow]note:[/] {escape(note)}", soft_wrap=True)
    console.print(f"wrote {len(result.figures)} figures, report.json and report.html to "
                  f"{escape(str(result.out_dir))}/")


def demo_report(out: Path, *, quiet: bool = False) -> Any:
    """The report of a ``lidarsim demo`` run, written into the demo's directory ``out``
    (whose files the demo has checked against the overwrite policy); returns the
    :class:`~lidarsim_core.report.Report`, or None without the viz extra.

    Without the viz extra the demo still succeeds: one line says how to get the figures.
    """
    from .output import markup_safe as escape

    from ..report import VizMissing, write_report
    from .output import console

    try:
        from .progress import status

        result = write_report(out, out, overwrite=True, progress=status)
    except VizMissing as exc:
        console().print(f"[yellow]note:[/] no report figures: {escape(str(exc))}")
        return None
    if not quiet:
        print_report_summary(result)
    return result
