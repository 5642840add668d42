"""The ``lidarsim`` command line.

User errors (bad files, fields, names, paths) and failing plugins print one line and exit with
code 2; other failures print one line and exit with code 1; Ctrl-C (SIGINT) exits with 130 and
SIGTERM with 143, after removing any partly written file. ``--debug`` shows the traceback
instead of the one line.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any, Callable, Optional

import typer
from rich.markup import escape

from ..base.errors import LidarsimError, UserInputError
from .output import Column, hide_flag_metavars, print_json, print_table

hide_flag_metavars()
app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="LiDAR point-cloud simulator for space in-orbit close-range operations.")
schema_app = typer.Typer(no_args_is_help=True, help="Print JSON schemas of the input files.")
app.add_typer(schema_app, name="schema")

_state = {"debug": False}
#: Bytes of points ``lidarsim simulate`` holds in memory per frame before spilling them to a
#: temporary file (the frame is then streamed to its output file).
SPOOL_MEMORY_BYTES = 64 * 2 ** 20


def _print_version(value: bool) -> None:
    if value:
        from .._version import __version__

        typer.echo(f"lidarsim-core {__version__}")
        raise typer.Exit()


@app.callback()
def _root(debug: bool = typer.Option(False, "--debug", help="Show tracebacks on errors."),
          version: bool = typer.Option(False, "--version", callback=_print_version,
                                       is_eager=True, help="Print the version and exit.")
          ) -> None:
    _state["debug"] = debug


def _console(stderr: bool = False):
    from .output import console

    return console(stderr)


def _fail(message: str, code: int) -> None:
    from rich.text import Text

    # a Text is never parsed for markup: file names, keys and values are printed verbatim
    _console(stderr=True).print(Text.assemble(("error:", "bold red"), " ", message),
                                soft_wrap=True)
    raise typer.Exit(code)


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


def check_seed_option(seed: int | None, flag: str = "--seed") -> None:
    """Refuse a seed option outside 0 to 2^64 - 1 (a larger one would alias a smaller)."""
    from ..base.errors import ConfigError
    from ..base.limits import MAX_SEED

    if seed is not None and not 0 <= seed <= MAX_SEED:
        raise ConfigError(f"{flag} {seed} is outside 0..{MAX_SEED} (2^64 - 1)", field=flag)


def check_number_option(value: float | None, flag: str, *, minimum: float | None = None,
                        maximum: float | None = None, positive: bool = False) -> None:
    """Refuse a number option that is NaN or infinite, not > 0 (``positive``), below
    ``minimum`` or above ``maximum``: options are checked at the edge like configuration
    fields."""
    import math

    from ..base.errors import ConfigError

    if value is None:
        return
    if not math.isfinite(value):
        raise ConfigError(f"{flag} must be a finite number, got {value}", field=flag)
    if positive and not value > 0:
        raise ConfigError(f"{flag} must be > 0, got {value:g}", field=flag)
    if minimum is not None and value < minimum:
        raise ConfigError(f"{flag} must be >= {minimum:g}, got {value:g}", field=flag)
    if maximum is not None and value > maximum:
        raise ConfigError(f"{flag} must be <= {maximum:g}, got {value:g}", field=flag)


def run_guarded(func: Callable[[], Any]) -> Any:
    """Run a command body, turning lidarsim errors into one line and an exit code.

    Exit codes: 2 for a user error or a failing plugin (:class:`UserInputError`,
    :class:`~lidarsim_core.base.errors.PluginError`: fix the input or the installed plugins), 1 for
    any other failure, 130 after Ctrl-C (SIGINT), 143 after SIGTERM.
    """
    from ..base.errors import PluginError
    from ..base.numerics import quiet_numerics
    from ..base.oserrors import os_error_line
    from ..base.signals import SIGTERM_EXIT_CODE, Terminated, interrupt_behind

    try:
        try:
            with quiet_numerics():
                return func()
        except Exception as exc:  # an interrupt surfacing through a compiled kernel
            interrupt = interrupt_behind(exc)
            if interrupt is None:
                raise
            raise interrupt from None
    except typer.Exit:
        raise
    except (UserInputError, PluginError) as exc:
        if _state["debug"]:
            raise
        _fail(_one_line(exc), 2)
    except LidarsimError as exc:
        if _state["debug"]:
            raise
        _fail(_one_line(exc), 1)
    except OSError as exc:  # a path the user gave cannot be read or written (ENOSPC, EROFS...)
        if _state["debug"]:
            raise
        _fail(_one_line(os_error_line(exc)), 2)
    except Terminated as exc:  # a command that keeps finished work says so in the message
        _fail(f"terminated (SIGTERM); {str(exc) or 'no partial output was kept'}",
              SIGTERM_EXIT_CODE)
    except KeyboardInterrupt as exc:
        _fail(f"interrupted; {str(exc) or 'no partial output was kept'}", 130)
    except Exception as exc:  # an unexpected bug: short line unless --debug
        if _state["debug"]:
            raise
        _fail(f"internal error: {type(exc).__name__}: {_one_line(exc)} (rerun with --debug "
              "for the traceback)", 1)


# ---- demo -------------------------------------------------------------------------------
#: Cloud files of ``lidarsim demo`` (each with a sidecar ``.json``), by run label.
DEMO_CLOUDS = {label: [f"envisat_mid70_{label}{suffix}" for suffix in (".ply", ".npz")]
               for label in ("with_errors", "without_errors")}
#: Timed repetitions of each demo simulation (the best is shown; the first run of a process
#: also warms caches and thread pools, and is not the steady rate).
DEMO_REPEATS = 3


@app.command()
def demo(out: Path = typer.Option(Path("demo-out"), "--out", "-o", help="Output directory."),
         duration: float = typer.Option(1.0, help="Scan time in seconds (paper: 1 s)."),
         backend: str = typer.Option("auto", help="Ray backend: auto, numpy, embree, ..."),
         detail: str = typer.Option("medium", help="Envisat detail: coarse, medium, fine."),
         seed: int = typer.Option(2024, help="Noise seed."),
         overwrite: bool = typer.Option(False, "--overwrite",
                                        help="Replace the demo's files if --out has them."),
         as_json: bool = typer.Option(False, "--json", help="Print the summary as JSON."),
         ) -> None:
    """The seed paper's experiment: Envisat scanned by a Livox MID-70, with and without errors."""
    run_guarded(lambda: _demo(out, duration, backend, detail, seed, overwrite, as_json))


def demo_files(three_d: bool = True) -> list[str]:
    """Every file ``lidarsim demo`` writes into its directory."""
    from ..io.sidecar import sidecar_path

    names = [n for files in DEMO_CLOUDS.values() for f in files
             for n in (f, sidecar_path(f).name)]
    names.append("scenario.yaml")
    from ..report.builder import (
        report_files,  # light: the plotting libraries load later
    )

    return names + report_files("part", three_d=three_d)


def _demo(out: Path, duration: float, backend: str, detail: str, seed: int,
          overwrite: bool = False, as_json: bool = False) -> None:
    import yaml

    from .. import kernels
    from ..base.atomic import write_text_atomic
    from ..base.outputs import check_files
    from ..pipeline.simulation import Simulation
    from ..scenario.demo import demo_scenario

    check_number_option(duration, "--duration", positive=True)
    check_seed_option(seed)
    check_files(out, demo_files(), overwrite=overwrite)  # before any work: nothing replaced
    started = time.perf_counter()
    t0 = time.perf_counter()
    kernels_used = kernels.warm_up()  # compile or load the kernels outside the timed runs
    compile_s = time.perf_counter() - t0
    runs = {}
    for label, noisy in (("with_errors", True), ("without_errors", False)):
        scenario = demo_scenario(duration_s=duration, noise=noisy, detail=detail,
                                 backend=backend, seed=seed)
        sim = Simulation(scenario)
        t0 = time.perf_counter()
        sim.backend.prepared(sim.targets[0].mesh)  # the BVH, built once per mesh
        setup_s = time.perf_counter() - t0
        times = []
        for _ in range(DEMO_REPEATS):  # the same pulses and noise every time
            t0 = time.perf_counter()
            cloud = sim.run_frame(0)
            times.append(time.perf_counter() - t0)
        runs[label] = {"cloud": cloud, "scenario": scenario, "setup_s": setup_s,
                       "first_s": times[0], "best_s": min(times)}
    out.mkdir(parents=True, exist_ok=True)
    written: list[str] = []
    for label, run in runs.items():
        for name in DEMO_CLOUDS[label]:
            run["cloud"].save(out / name, overwrite=True)  # checked above
            written += [name, name + ".json"]
    scenario = runs["with_errors"]["scenario"]
    scenario_text = yaml.safe_dump(scenario.model_dump(mode="json"), sort_keys=False)
    write_text_atomic(out / "scenario.yaml", scenario_text)
    written.append("scenario.yaml")
    from .report import demo_report

    summary = _demo_summary(out, runs, compile_s if kernels_used else None)
    if not as_json:
        _print_demo_summary(summary)
    report = demo_report(out, quiet=as_json)
    if report is not None:
        written += [p.name for p in report.files()]
    summary["files"] = sorted(written)
    summary["wall_s"] = time.perf_counter() - started
    if as_json:
        print_json(summary)
        return
    console = _console()
    console.print(f"wrote {len(written)} files to {escape(str(out))}/: the clouds with and without errors "
                  "(.ply, .npz, each with a sidecar .json), scenario.yaml and the report")
    console.print(f"total wall time {summary['wall_s']:.2f} s")


def _demo_summary(out: Path, runs: dict[str, Any], compile_s: float | None) -> dict[str, Any]:
    noisy = runs["with_errors"]["cloud"]
    frame = noisy.frame
    rows = []
    for label, run in runs.items():
        cloud = run["cloud"]
        rays = cloud.frame.rays_emitted
        rng = cloud["range_true"]
        rows.append({"run": label, "rays": rays, "points": len(cloud),
                     "hit_fraction": len(cloud) / max(rays, 1),
                     "range_min_m": float(rng.min()) if len(cloud) else None,
                     "range_max_m": float(rng.max()) if len(cloud) else None,
                     "setup_s": run["setup_s"], "first_run_s": run["first_s"],
                     "sim_s": run["best_s"], "rays_per_s": rays / run["best_s"]})
    summary: dict[str, Any] = {
        "out": str(out), "sensor": frame.sensor, "duration_s": frame.t_end - frame.t_start,
        "backend": frame.backend, "seed": frame.seed, "kernels_ready_s": compile_s,
        "repeats": DEMO_REPEATS, "runs": rows,
        "points_per_part": dict(sorted(noisy.summary().get("points_per_part", {}).items(),
                                       key=lambda kv: -kv[1]))}
    if len(noisy):
        err = noisy["range"] - noisy["range_true"]
        summary["range_error_mean_mm"] = 1000 * float(err.mean())
        summary["range_error_sigma_mm"] = 1000 * float(err.std())
    return summary


def _print_demo_summary(summary: dict[str, Any]) -> None:
    console = _console()
    console.print(f"[bold]lidarsim demo[/]: {escape(summary['sensor'])} scanning Envisat for "
                  f"{summary['duration_s']:g} s, backend [bold]{escape(summary['backend'])}[/], seed "
                  f"{summary['seed']}")
    if summary["kernels_ready_s"] is not None:
        console.print(f"compiled kernels ready in {summary['kernels_ready_s']:.2f} s (compiled "
                      "on the first run after installing, then loaded from numba's cache; not "
                      "included below)")
    rows = []
    for r in summary["runs"]:
        span = (f"{r['range_min_m']:.1f}–{r['range_max_m']:.1f}"
                if r["range_min_m"] is not None else "-")
        rows.append([r["run"].replace("_", " "), f"{r['rays']:,}", f"{r['points']:,}",
                     f"{100 * r['hit_fraction']:.1f}", span, f"{r['sim_s']:.3f}",
                     f"{r['rays_per_s']:,.0f}"])
    print_table([Column("run", whole=True), Column("rays", right=True),
                 Column("points", right=True), Column("hit %", right=True),
                 Column("range m", right=True), Column("sim s", right=True),
                 Column("rays/s", right=True)], rows)
    console.print(f"sim s: best of {summary['repeats']} runs of the same frame, after building "
                  f"the BVH; a frame this short ({summary['runs'][0]['rays']:,} rays) is "
                  "dominated by fixed costs per frame: `lidarsim bench` measures long scans")
    if "range_error_sigma_mm" in summary:
        console.print(f"range error: mean {summary['range_error_mean_mm']:+.2f} mm, "
                      f"σ {summary['range_error_sigma_mm']:.2f} mm (datasheet 20 mm)")
    print_table([Column("part", whole=True), Column("points", right=True)],
                [[name, f"{count:,}"] for name, count in summary["points_per_part"].items()])


# ---- simulate ----------------------------------------------------------------------------
@app.command()
def simulate(scenario: Path = typer.Argument(..., help="Scenario file (YAML, TOML or JSON)."),
             out: Path = typer.Option(..., "--out", "-o",
                                      help="Output file; the suffix picks the format (.ply, "
                                           ".npz). With several frames, put '{frame}' in the "
                                           "name, e.g. cloud_{frame:04d}.ply."),
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
             ) -> None:
    """Simulate a scenario file and write the point cloud(s), or one ROS 2 bag (.mcap)."""
    run_guarded(lambda: _simulate(scenario, out, frame, fmt, overwrite, backend, seed, livox,
                                  range_image))


def _simulate(path: Path, out: Path, frame: int | None, fmt: str | None, overwrite: bool,
              backend: str | None, seed: int | None, livox: bool = False,
              range_image: bool = False) -> None:
    from ..base.errors import ConfigError, OutputError
    from ..base.outputs import check_file, make_parent
    from ..io.base import write_points_file
    from ..io.paths import frame_paths, has_frame_field
    from ..io.points import PointSpool
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
    if out.suffix.lower() == ".mcap" or fmt == "mcap":  # every frame into one ROS 2 bag
        from .bag import simulate_to_bag

        return simulate_to_bag(scenario, frames, out, overwrite=overwrite, livox=livox,
                               range_image=range_image)
    if livox:
        raise OutputError("--livox applies to a ROS 2 bag (--out run.mcap)", source=out)
    templated = has_frame_field(out)
    if len(frames) > 1 and not templated:
        raise OutputError(f"the scenario has {len(frames)} frames: put '{{frame}}' in --out "
                          "(e.g. cloud_{frame:04d}.ply) or choose one with --frame", source=out)
    targets = frame_paths(out, frames) if templated else [out]
    exporter = exporter_for(targets[0], fmt)  # unknown format: fail before simulating
    for target in targets:  # every output is checked before any work (lidarsim_core.base.outputs)
        check_file(target, overwrite=overwrite)
    sim = Simulation(scenario)  # guards third-party components itself
    if range_image:
        from ..io.rangeimage import check_layout

        check_layout(sim.pattern)
    console = _console()
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


# ---- listings ----------------------------------------------------------------------------
@app.command()
def sensors(as_json: bool = typer.Option(False, "--json", help="Print JSON.")) -> None:
    """List the sensor datasheets in the catalogue (built-in and from plugins)."""
    run_guarded(lambda: _sensors(as_json))


def _sensors(as_json: bool) -> None:
    from ..plugins.manager import get_registry

    entries = list(get_registry().iter("sensor"))
    if as_json:
        print_json([{**e.obj.model_dump(mode="json"), "provider": e.provider} for e in entries])
        return
    rows = []
    for e in entries:
        s = e.obj
        fov = f"{s.fov_h_deg:g}° {s.fov_type}" if s.fov_type == "circular" else \
            f"{s.fov_h_deg:g}°×{s.fov_v_deg:g}°"
        rows.append([s.name, f"{s.manufacturer} {s.model}", fov,
                     f"{s.range_min_m:g}–{s.range_max_m:g}", f"{s.point_rate_hz:,.0f}",
                     f"{100 * s.range_precision_m:g} cm", f"{s.angular_precision_deg:g}°",
                     s.scan_pattern.name, e.provider])
    print_table([Column("name", whole=True), Column("sensor", optional=True),
                 Column("FOV", whole=True), Column("range m", whole=True),
                 Column("points/s", right=True, whole=True),
                 Column("σ range", optional=True), Column("σ angle", optional=True),
                 Column("pattern", whole=True), Column("provider", optional=True)], rows)


@app.command()
def plugins(as_json: bool = typer.Option(False, "--json", help="Print JSON.")) -> None:
    """List every registered component with the distribution that provides it."""
    run_guarded(lambda: _plugins(as_json))


def _plugins(as_json: bool) -> None:
    from ..plugins.manager import get_registry
    from ..plugins.registry import KINDS

    registry = get_registry()
    rows = []
    for kind in KINDS:
        for e in registry.iter(kind):
            summary = e.obj.description.split("\n")[0] if kind == "sensor" else e.obj.summary()
            rows.append({"kind": kind, "name": e.name, "provider": e.provider,
                         "summary": summary.strip()})
    if as_json:
        print_json(rows)
        return
    print_table([Column("kind", whole=True), Column("name", whole=True),
                 Column("provider", optional=True), Column("summary")],
                [list(row.values()) for row in rows])


@schema_app.command("sensor")
def schema_sensor() -> None:
    """JSON schema of a sensor datasheet."""
    from ..scenario.datasheet import datasheet_json_schema

    typer.echo(json.dumps(datasheet_json_schema(), indent=2))


@schema_app.command("scenario")
def schema_scenario() -> None:
    """JSON schema of a scenario file."""
    from ..scenario.model import Scenario

    typer.echo(json.dumps(Scenario.model_json_schema(), indent=2))


#: Modules that add further commands to :data:`app` when imported (one module per command group).
COMMAND_MODULES: tuple[str, ...] = ("patterns", "poses", "bench", "report",
                                     "dataset", "mesh", "view", "evaluate")


def _load_command_modules() -> None:
    from importlib import import_module

    for name in COMMAND_MODULES:
        import_module(f"{__package__}.{name}")


def _show_warning(message: Any, category: type[Warning], filename: str, lineno: int,
                  file: Any = None, line: str | None = None) -> None:
    """Warnings are one line on stderr, ``warning: ...``, like errors (no source location)."""
    _console(stderr=True).print(f"[yellow]warning:[/] {escape(str(message))}")


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point; exits the process with the command's status."""
    import warnings

    warnings.showwarning = _show_warning
    sys.exit(_run_app(argv))


def _run_app(argv: list[str] | None) -> int:
    from ..base.signals import sigterm_as_interrupt

    try:  # Typer >= 0.26 carries its own copy of Click
        from typer._click.exceptions import NoArgsIsHelpError, UsageError
    except ImportError:  # pragma: no cover - older Typer on Click
        from click.exceptions import NoArgsIsHelpError, UsageError  # type: ignore[no-redef]

    _load_command_modules()
    with sigterm_as_interrupt():
        try:
            # not standalone: a usage error (bad option value, unknown option) comes back here
            # and is printed as one line, like every other mistake
            code = app(args=argv, prog_name="lidarsim", standalone_mode=False)
        except NoArgsIsHelpError as exc:
            exc.show()
            return exc.exit_code
        except UsageError as exc:
            command = exc.ctx.command_path if exc.ctx is not None else "lidarsim"
            return _fail_code(f"{command}: {_one_line(exc.format_message())}", 2)
        except typer.Abort:
            return _fail_code("interrupted; no partial output was kept", 130)
    return code if isinstance(code, int) else 0


def _fail_code(message: str, code: int) -> int:
    try:
        _fail(message, code)
    except typer.Exit as stop:
        return stop.exit_code
    return code


if __name__ == "__main__":  # pragma: no cover
    # run through the package module so command modules extend the same ``app``
    from .app import main as _main

    sys.exit(_main())
