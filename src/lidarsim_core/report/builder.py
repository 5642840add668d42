"""Assemble a run's report: every figure as a PNG, ``report.json`` and ``report.html``."""

from __future__ import annotations

import json
import math
import shlex
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..base.atomic import write_text_atomic
from ..base.errors import LidarsimError
from .result import FIGURE_FILES, Figure, Report
from .run import Run, load_run


class VizMissing(LidarsimError):
    """The plotting libraries of the ``viz`` extra (matplotlib, pyvista) are not installed."""


THREE_D_FIGURES = ("scene", "errors", "cloud")


def report_files(colour_by: str = "part", *, three_d: bool = True) -> list[str]:
    """Names of every file :func:`write_report` may write (for the overwrite check)."""
    names = [name.format(colour_by=colour_by) for key, name in FIGURE_FILES.items()
             if three_d or key not in THREE_D_FIGURES]
    return names + ["report.json", "report.html"]


def require_viz() -> None:
    """Raise :class:`VizMissing` unless matplotlib and pyvista can be imported."""
    from importlib.util import find_spec

    from ..base.optional import require

    for module in ("matplotlib", "pyvista"):
        if find_spec(module) is None:  # found, not imported: the figures import them later
            require(module, extra="viz", what="report figures", error=VizMissing)


def write_report(run_dir: str | Path, out_dir: str | Path | None = None, *,
                 scenario: str | Path | None = None, frame: int | None = None,
                 colour_by: str = "part", coverage_time_s: float | None = None,
                 cell_deg: float = 0.5, three_d: bool = True,
                 overwrite: bool = False,
                 progress: Callable[[str], None] | None = None) -> Report:
    """Read a run directory and write its report figures and page.

    Parameters
    ----------
    run_dir
        The run: clouds (``.npz``) and their scenario (see :mod:`lidarsim_core.report.run`).
    out_dir
        Where to write (created if needed; default ``run_dir/report``).
    scenario
        The scenario file when it is not in ``run_dir``.
    frame
        The frame to show (default: the first).
    colour_by
        What colours the cloud in Fig. 12: ``part``, ``range``, ``time``, ``intensity`` (when
        the cloud has it) or any numeric column.
    coverage_time_s
        Integration time of the coverage map (default: the frame's duration).
    cell_deg
        Cell size of the coverage map (deg).
    three_d
        Draw the pyvista figures (7, 11, 12); False draws only the 2-D ones.
    overwrite
        Replace report files already in ``out_dir`` (otherwise :class:`OutputError` naming
        them, before anything is drawn; other files there are never touched).
    progress
        Called with a short line (``"drawing Fig. 5: scan pattern"``) before each step that
        takes a while, e.g. to show progress.

    Returns
    -------
    Report
        Paths of everything written, and the numbers shown.

    Raises
    ------
    VizMissing
        When the ``viz`` extra is not installed.
    ConfigError
        When the run directory, its scenario or an option is invalid.
    """
    require_viz()
    from ..base.outputs import check_files

    run_dir = Path(run_dir)
    out = Path(out_dir) if out_dir is not None else run_dir / "report"
    check_files(out, report_files(colour_by, three_d=three_d), overwrite=overwrite)
    step = progress or _quiet
    step(f"reading the run {run_dir}")
    run = load_run(run_dir, scenario=scenario, frame=frame)
    from .colouring import point_colours

    point_colours(run.noisy, colour_by)  # an unknown name fails before anything is drawn
    out.mkdir(parents=True, exist_ok=True)
    return build_report(run, out, colour_by=colour_by, coverage_time_s=coverage_time_s,
                        cell_deg=cell_deg, three_d=three_d, scenario=scenario,
                        progress=progress)


def _quiet(line: str) -> None:
    """No progress shown."""


def build_report(run: Run, out: Path, *, colour_by: str = "part",
                 coverage_time_s: float | None = None, cell_deg: float = 0.5,
                 three_d: bool = True, scenario: str | Path | None = None,
                 progress: Callable[[str], None] | None = None) -> Report:
    """Write the figures, ``report.json`` and ``report.html`` of a loaded :class:`Run`
    (``progress`` as in :func:`write_report`)."""
    from ..patterns.fov import fov_coverage
    from . import charts
    from .stats import angular_error_components, fit_normal, range_errors

    step = progress or _quiet

    report = Report(run.directory, out, command=_command(run, out, colour_by, coverage_time_s,
                                                         cell_deg, scenario, frame=run.frame))
    report.summary = _summary(run)
    report.notes += run.notes
    report.notes += [f"The run holds no cloud {role}: the report simulated it from the scenario "
                     "(same seed and poses)." for role in run.simulated]
    sheet, pattern = run.sensor, run.simulation.pattern
    name = FIGURE_FILES
    seg = charts.pattern_segment_s(pattern)
    step("drawing Fig. 5: scan pattern")
    charts.pattern_figure(pattern, out / name["pattern"])
    where = ("in azimuth and elevation (a panoramic FOV, unrolled)"
             if sheet.fov_type == "panoramic" else
             "where they cross a plane 1 m in front of the sensor")
    report.figures.append(Figure(
        "pattern", out / name["pattern"], "Scan pattern on a plane 1 m ahead (paper Fig. 5)",
        f"Rays of {sheet.name} emitted in three consecutive periods of {1e3 * seg:.2f} ms, "
        f"{where}, seen from behind the sensor (+Y left, +Z up). A period is one turn of φ "
        "for the rose pattern (after which the rosette rotates; paper: 5°), a third of a "
        "revolution for a spinning head, one period of the slower mirror axis for a Lissajous "
        "scanner, else 4000 pulses."))

    angles = np.degrees(angular_error_components(run.noisy)).ravel()
    fit = fit_normal(angles)
    if fit.n and fit.sigma > 1e-9:
        step("drawing Fig. 6: angular error")
        charts.error_histogram_figure(
            angles, fit, sheet.angular_precision_deg, out / name["angular_error"],
            title=f"Angular error injected ({sheet.name}; cf. paper Fig. 6)",
            xlabel="deviation of the flown ray from the nominal one, about two perpendicular "
                   "axes (deg)", unit="deg",
            sample_label=f"2 axes × {len(run.noisy):,} points = {fit.n:,}")
        report.figures.append(Figure(
            "angular_error", out / name["angular_error"], "Angular error (paper Fig. 6)",
            "Each point's flown direction (ground truth x_true/range_true) against its nominal "
            "direction (azimuth, elevation), split along the local azimuth and elevation axes; "
            "both components pooled. Red: the fitted normal; dashed: the datasheet's 1σ."))
        report.summary.update(angular_sigma_deg=fit.sigma, angular_mean_deg=fit.mean)
    else:
        report.notes.append("No angular error was injected in this run: Fig. 6 is not drawn.")

    errors_mm = 1e3 * range_errors(run.noisy)
    fit_r = fit_normal(errors_mm)
    if fit_r.n and fit_r.sigma > 1e-9:
        step("drawing Fig. 9: range error")
        charts.error_histogram_figure(
            errors_mm, fit_r, 1e3 * sheet.range_precision_m, out / name["range_error"],
            title=f"Range error injected ({sheet.name}; cf. paper Fig. 9)",
            xlabel="reported minus true range (mm)", unit="mm")
        report.figures.append(Figure(
            "range_error", out / name["range_error"], "Range error (paper Fig. 9)",
            "range − range_true of every point: the error added along the ray (paper Eq. 4). "
            "Red: the fitted normal; dashed: the datasheet's 1σ."))
        report.summary.update(range_sigma_mm=fit_r.sigma, range_mean_mm=fit_r.mean)
    else:
        report.notes.append("No range error was injected in this run: Fig. 9 is not drawn.")

    duration = coverage_time_s or (run.noisy.frame.t_end - run.noisy.frame.t_start)
    t0 = run.noisy.frame.t_start
    step("drawing the FOV coverage map")
    cmap = charts.coverage_map(pattern, duration, cell_deg, t_start_s=t0)
    cov = fov_coverage(pattern, duration, cell_deg, t_start_s=t0)
    charts.coverage_figure(cmap, out / name["coverage"], sensor=sheet.name, duration_s=duration,
                           coverage=cov.coverage)
    report.figures.append(Figure(
        "coverage", out / name["coverage"], f"FOV coverage in {duration:g} s",
        f"Rays per {cell_deg:g}° cell emitted in {duration:g} s from t = {t0:g} s, in the "
        f"{cmap.projection} projection about the boresight, seen from behind the sensor. "
        f"{cov.cells_hit:,} of {cov.cells_in_fov:,} FOV cells were reached "
        f"({100 * cov.coverage:.1f} %)."))
    report.summary.update(coverage=cov.coverage, coverage_time_s=duration,
                          coverage_cell_deg=cell_deg)

    if three_d:
        _three_d_figures(run, out, colour_by, report, step)
    order = list(FIGURE_FILES)
    report.figures.sort(key=lambda f: order.index(f.key))
    report.json = out / "report.json"
    write_text_atomic(report.json, json.dumps(
        {"summary": report.summary, "notes": report.notes,
         "figures": {f.key: f.path.name for f in report.figures}}, indent=2, default=_jsonable))
    from .html import write_html

    report.html = write_html(report, out / "report.html")
    return report


def _three_d_figures(run: Run, out: Path, colour_by: str, report: Report,
                     step: Callable[[str], None]) -> None:
    from .render import RenderingUnavailable, rendering_backend

    try:
        rendering_backend()
    except RenderingUnavailable as exc:
        report.notes.append(f"3-D figures (Figs. 7, 11, 12) skipped: {exc}")
        return
    from . import scene

    name = FIGURE_FILES
    step("drawing Fig. 7: scene set-up (3-D)")
    scene.scene_figure(run, out / name["scene"])
    report.figures.append(Figure(
        "scene", out / name["scene"], "Scene set-up (paper Fig. 7)",
        "The targets at their poses at frame start, in the scene frame, and the LiDAR (red) "
        "with its axes (+X boresight red, +Y green, +Z blue) and its datasheet field of view."))
    step("drawing Fig. 11: clouds without and with errors (3-D)")
    scene.errors_figure(run, out / name["errors"])
    if len(run.clean) >= 10:
        views, radius = scene.patch_views(run)
        report.summary.update(flat_patch_diameter_m=2 * radius,
                              flat_patch_spread_without_errors_mm=views["clean"].spread_mm,
                              flat_patch_spread_with_errors_mm=views["noisy"].spread_mm)
    report.figures.append(Figure(
        "errors", out / name["errors"], "Point clouds without and with errors (paper Fig. 11)",
        "Left: the cloud without errors; right: with the datasheet's angular and range errors "
        "(same pulses). Top: the whole cloud, coloured by range. Middle: a flat patch face-on "
        "(on the planar facet hit most, never across an edge); "
        "without errors the scan lines are exact, the angular error scatters the points along "
        "the surface. Bottom: the same patch edge-on with the normal axis stretched; without "
        "errors the points lie on the plane, the range error spreads them off it."))
    cloud_path = out / name["cloud"].format(colour_by=colour_by)
    step("drawing Fig. 12: model and cloud (3-D)")
    scene.cloud_figure(run, cloud_path, colour_by)
    report.figures.append(Figure(
        "cloud", cloud_path, f"Model and point cloud, coloured by {colour_by} (paper Fig. 12)",
        "a) The target model coloured by part; b) the simulated cloud (with errors) over the "
        "model, in the sensor frame at frame start."))


def _summary(run: Run) -> dict[str, Any]:
    noisy, clean, sheet = run.noisy, run.clean, run.sensor
    frame = noisy.frame
    info = noisy.summary()
    return {
        "sensor": sheet.name, "sensor_model": f"{sheet.manufacturer} {sheet.model}",
        "pattern": run.simulation.pattern.name, "targets": ", ".join(frame.target_names),
        "frame": frame.frame, "t_start_s": frame.t_start, "t_end_s": frame.t_end,
        "rays_emitted": frame.rays_emitted, "points_with_errors": len(noisy),
        "points_without_errors": len(clean), "hit_fraction": info["hit_fraction"],
        "range_min_m": info.get("range_min_m"), "range_max_m": info.get("range_max_m"),
        "points_per_part": info.get("points_per_part", {}), "backend": frame.backend,
        "seed": frame.seed, "noise": list(frame.noise), "config_hash": frame.config_hash,
        "software": frame.software or "lidarsim",
        "angular_sigma_datasheet_deg": sheet.angular_precision_deg,
        "range_sigma_datasheet_mm": 1e3 * sheet.range_precision_m,
        "simulated_by_report": list(run.simulated),
        "files": {role: path.name for role, path in run.files.items()},
    }


def _command(run: Run, out: Path, colour_by: str, coverage_time_s: float | None,
             cell_deg: float, scenario: str | Path | None, frame: int) -> str:
    parts = ["lidarsim", "report", str(run.directory), "--out", str(out)]
    if scenario is not None:
        parts += ["--scenario", str(scenario)]
    if frame:
        parts += ["--frame", str(frame)]
    if colour_by != "part":
        parts += ["--color-by", colour_by]
    if coverage_time_s:
        parts += ["--coverage-time", f"{coverage_time_s:g}"]
    if cell_deg != 0.5:
        parts += ["--cell-deg", f"{cell_deg:g}"]
    # the page regenerates itself: its own files are there, and are the ones replaced
    return shlex.join(parts + ["--overwrite"])


def _jsonable(value: Any) -> Any:
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating,)):
        return None if math.isnan(value) else float(value)
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
