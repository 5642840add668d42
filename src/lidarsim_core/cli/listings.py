"""The listings: ``lidarsim sensors``, ``lidarsim plugins`` and ``lidarsim schema``."""

from __future__ import annotations

import json

import typer

from .app import app, schema_app
from .errors import run_guarded
from .output import Column, print_json, print_table


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
