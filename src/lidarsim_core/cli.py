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

from .errors import LidarsimError, UserInputError

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
        from ._version import __version__

        typer.echo(f"lidarsim-core {__version__}")
        raise typer.Exit()


@app.callback()
def _root(debug: bool = typer.Option(False, "--debug", help="Show tracebacks on errors."),
          version: bool = typer.Option(False, "--version", callback=_print_version,
                                       is_eager=True, help="Print the version and exit.")
          ) -> None:
    _state["debug"] = debug


def _console(stderr: bool = False):
    from rich.console import Console

    return Console(stderr=stderr, highlight=False)


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
    from .errors import ConfigError
    from .limits import MAX_SEED

    if seed is not None and not 0 <= seed <= MAX_SEED:
        raise ConfigError(f"{flag} {seed} is outside 0..{MAX_SEED} (2^64 - 1)", field=flag)


def check_number_option(value: float | None, flag: str, *, minimum: float | None = None,
                        maximum: float | None = None, positive: bool = False) -> None:
    """Refuse a number option that is NaN or infinite, not > 0 (``positive``), below
    ``minimum`` or above ``maximum``: options are checked at the edge like configuration
    fields."""
    import math

    from .errors import ConfigError

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
    :class:`~lidarsim_core.errors.PluginError`: fix the input or the installed plugins), 1 for
    any other failure, 130 after Ctrl-C (SIGINT), 143 after SIGTERM.
    """
    from .errors import PluginError
    from .guard import (SIGTERM_EXIT_CODE, Terminated, interrupt_behind, os_error_line,
                        quiet_numerics)

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
    except Terminated:
        _fail("terminated (SIGTERM); no partial output was kept", SIGTERM_EXIT_CODE)
    except KeyboardInterrupt:
        _fail("interrupted; no partial output was kept", 130)
    except Exception as exc:  # an unexpected bug: short line unless --debug
        if _state["debug"]:
            raise
        _fail(f"internal error: {type(exc).__name__}: {_one_line(exc)} (rerun with --debug "
              "for the traceback)", 1)


# ---- demo -------------------------------------------------------------------------------
@app.command()
def demo(out: Path = typer.Option(Path("demo-out"), "--out", "-o", help="Output directory."),
         duration: float = typer.Option(1.0, help="Scan time in seconds (paper: 1 s)."),
         backend: str = typer.Option("auto", help="Ray backend: auto, numpy, embree, ..."),
         detail: str = typer.Option("medium", help="Envisat detail: coarse, medium, fine."),
         seed: int = typer.Option(2024, help="Noise seed.")) -> None:
    """The seed paper's experiment: Envisat scanned by a Livox MID-70, with and without errors."""
    run_guarded(lambda: _demo(out, duration, backend, detail, seed))


def _demo(out: Path, duration: float, backend: str, detail: str, seed: int) -> None:
    import yaml

    from . import kernels
    from .demo import demo_scenario
    from .errors import OutputError
    from .pipeline import Simulation

    check_number_option(duration, "--duration", positive=True)
    check_seed_option(seed)
    if out.exists() and not out.is_dir():
        raise OutputError("--out must be a directory", source=out)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    kernels.warm_up()  # compile or load the kernels outside the timed runs
    results = {}
    for label, noisy in (("with_errors", True), ("without_errors", False)):
        scenario = demo_scenario(duration_s=duration, noise=noisy, detail=detail,
                                 backend=backend, seed=seed)
        sim = Simulation(scenario)
        sim.backend.prepared(sim.targets[0].mesh)  # build the BVH outside the timed cast
        t0 = time.perf_counter()
        cloud = sim.run_frame(0)
        elapsed = time.perf_counter() - t0
        cloud.save(out / f"envisat_mid70_{label}.ply")
        cloud.save(out / f"envisat_mid70_{label}.npz")
        results[label] = (cloud, elapsed, scenario)
    scenario = results["with_errors"][2]
    scenario_text = yaml.safe_dump(scenario.model_dump(mode="json"), sort_keys=False)
    from .io.base import write_text_atomic

    write_text_atomic(out / "scenario.yaml", scenario_text)
    _print_demo_summary(out, results, time.perf_counter() - started)
    from .cli_report import demo_report

    demo_report(out)


def _print_demo_summary(out: Path, results: dict[str, Any], wall: float) -> None:
    from rich.markup import escape
    from rich.table import Table

    noisy = results["with_errors"][0]
    console = _console()
    frame = noisy.frame
    console.print(f"[bold]lidarsim demo[/]: {frame.sensor} scanning Envisat for "
                  f"{frame.t_end - frame.t_start:g} s, backend [bold]{frame.backend}[/], seed "
                  f"{frame.seed}")
    table = Table(title=None, show_edge=False)
    for col in ("run", "rays", "points", "hit %", "range m", "sim s", "rays/s"):
        table.add_column(col, justify="right" if col != "run" else "left")
    for label, (cloud, elapsed, _) in results.items():
        rays = cloud.frame.rays_emitted
        rng = cloud["range_true"]
        span = f"{rng.min():.1f}–{rng.max():.1f}" if len(cloud) else "-"
        table.add_row(label.replace("_", " "), f"{rays:,}", f"{len(cloud):,}",
                      f"{100 * len(cloud) / max(rays, 1):.1f}", span, f"{elapsed:.2f}",
                      f"{rays / elapsed:,.0f}")
    console.print(table)
    if len(noisy):
        err = noisy["range"] - noisy["range_true"]
        console.print(f"range error: mean {1000 * err.mean():+.2f} mm, σ {1000 * err.std():.2f} mm "
                      "(datasheet 20 mm)")
    parts = Table(show_edge=False)
    parts.add_column("part")
    parts.add_column("points", justify="right")
    for name, count in sorted(noisy.summary().get("points_per_part", {}).items(),
                              key=lambda kv: -kv[1]):
        parts.add_row(name, f"{count:,}")
    console.print(parts)
    files = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    console.print(f"wrote {len(files)} files to {escape(str(out))}/: "
                  f"{escape(', '.join(files))}")
    console.print(f"total wall time {wall:.2f} s")


# ---- simulate ----------------------------------------------------------------------------
@app.command()
def simulate(scenario: Path = typer.Argument(..., help="Scenario file (YAML, TOML or JSON)."),
             out: Path = typer.Option(..., "--out", "-o",
                                      help="Output file; the suffix picks the format (.ply, "
                                           ".npz). With several frames, put '{frame}' in the "
                                           "name, e.g. cloud_{frame:04d}.ply."),
             frame: Optional[int] = typer.Option(None, help="Only this frame (default: all)."),
             fmt: Optional[str] = typer.Option(None, "--format", help="Exporter name."),
             overwrite: bool = typer.Option(False, help="Replace existing output files."),
             backend: Optional[str] = typer.Option(None, help="Override the scenario's backend."),
             seed: Optional[int] = typer.Option(None, help="Override the scenario's seed."),
             ) -> None:
    """Simulate a scenario file and write the point cloud(s)."""
    run_guarded(lambda: _simulate(scenario, out, frame, fmt, overwrite, backend, seed))


def _simulate(path: Path, out: Path, frame: int | None, fmt: str | None, overwrite: bool,
              backend: str | None, seed: int | None) -> None:
    from rich.markup import escape

    from .errors import ConfigError, OutputError
    from .guard import check_output_path
    from .io.base import exporter_for, write_points_file
    from .io.paths import frame_paths, has_frame_field
    from .io.points import PointSpool
    from .scenario import load_scenario
    from .pipeline import Simulation

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
    templated = has_frame_field(out)
    if len(frames) > 1 and not templated:
        raise OutputError(f"the scenario has {len(frames)} frames: put '{{frame}}' in --out "
                          "(e.g. cloud_{frame:04d}.ply) or choose one with --frame", source=out)
    targets = frame_paths(out, frames) if templated else [out]
    exporter = exporter_for(targets[0], fmt)  # unknown format: fail before simulating
    for target in targets:  # every output refused before simulating, not after
        check_output_path(target, overwrite=overwrite)
    sim = Simulation(scenario)  # guards third-party components itself
    console = _console()
    for f, target in zip(frames, targets):
        t0 = time.perf_counter()
        info = sim.frame_info(f)
        # stream the frame through a spool (memory, then a temporary file): any size fits
        with PointSpool(info, memory_limit=SPOOL_MEMORY_BYTES) as spool:
            spool.extend(sim.iter_chunks(f))
            write_points_file(spool, target, exporter=exporter, overwrite=overwrite)
            points = len(spool)
        console.print(f"frame {f}: {points:,} points from {info.rays_emitted:,} rays "
                      f"in {time.perf_counter() - t0:.2f} s → {escape(str(target))}")
        if points == 0:
            console.print(f"note: frame {f} is empty: no point was detected within "
                          f"{sim.sensor.range_min_m:g}–{sim.sensor.range_max_m:g} m (targets "
                          "out of range, outside the field of view, behind the sensor or too "
                          "faint)")


# ---- listings ----------------------------------------------------------------------------
@app.command()
def sensors(as_json: bool = typer.Option(False, "--json", help="Print JSON.")) -> None:
    """List the sensor datasheets in the catalogue (built-in and from plugins)."""
    run_guarded(lambda: _sensors(as_json))


def _sensors(as_json: bool) -> None:
    from rich.table import Table

    from .plugins import get_registry

    entries = list(get_registry().iter("sensor"))
    if as_json:
        typer.echo(json.dumps([{**e.obj.model_dump(mode="json"), "provider": e.provider}
                               for e in entries], indent=2))
        return
    table = Table(show_edge=False)
    for col in ("name", "sensor", "FOV", "range m", "points/s", "σ range", "σ angle",
                "pattern", "provider"):
        table.add_column(col)
    for e in entries:
        s = e.obj
        fov = f"{s.fov_h_deg:g}° {s.fov_type}" if s.fov_type == "circular" else \
            f"{s.fov_h_deg:g}°×{s.fov_v_deg:g}°"
        table.add_row(s.name, f"{s.manufacturer} {s.model}", fov,
                      f"{s.range_min_m:g}–{s.range_max_m:g}", f"{s.point_rate_hz:,.0f}",
                      f"{100 * s.range_precision_m:g} cm", f"{s.angular_precision_deg:g}°",
                      s.scan_pattern.name, e.provider)
    _console().print(table)


@app.command()
def plugins(as_json: bool = typer.Option(False, "--json", help="Print JSON.")) -> None:
    """List every registered component with the distribution that provides it."""
    run_guarded(lambda: _plugins(as_json))


def _plugins(as_json: bool) -> None:
    from rich.table import Table

    from .plugins import get_registry
    from .registry import KINDS

    registry = get_registry()
    rows = []
    for kind in KINDS:
        for e in registry.iter(kind):
            summary = e.obj.description.split("\n")[0] if kind == "sensor" else e.obj.summary()
            rows.append({"kind": kind, "name": e.name, "provider": e.provider,
                         "summary": summary.strip()})
    if as_json:
        typer.echo(json.dumps(rows, indent=2))
        return
    table = Table(show_edge=False)
    for col in ("kind", "name", "provider", "summary"):
        table.add_column(col)
    for row in rows:
        table.add_row(*row.values())
    _console().print(table)


@schema_app.command("sensor")
def schema_sensor() -> None:
    """JSON schema of a sensor datasheet."""
    from .datasheet import datasheet_json_schema

    typer.echo(json.dumps(datasheet_json_schema(), indent=2))


@schema_app.command("scenario")
def schema_scenario() -> None:
    """JSON schema of a scenario file."""
    from .scenario import Scenario

    typer.echo(json.dumps(Scenario.model_json_schema(), indent=2))


#: Modules that add further commands to :data:`app` when imported (one module per command group).
COMMAND_MODULES: tuple[str, ...] = ("cli_patterns", "cli_motion", "cli_bench", "cli_report",
                                     "cli_dataset")


def _load_command_modules() -> None:
    from importlib import import_module

    for name in COMMAND_MODULES:
        import_module(f"{__package__}.{name}")


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point; exits the process with the command's status."""
    sys.exit(_run_app(argv))


def _run_app(argv: list[str] | None) -> int:
    from .guard import sigterm_as_interrupt

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
    from lidarsim_core.cli import main as _main

    sys.exit(_main())
