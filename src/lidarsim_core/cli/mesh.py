"""``lidarsim mesh SOURCE --out FILE``: the target model a simulation scans, as a mesh file.

SOURCE is a built-in (or plugin) target model name, with ``--option key=value`` for its
options, or a scenario file: then every target is written exactly as the simulation builds
it (model options, mesh file, scale), one file per target, to ``--out`` as a directory
(``<target>.obj``, or the ``--format`` suffix) or a template with ``{target}``. An ``--out``
without a suffix is a directory; missing folders are created, and every output is checked
before any mesh is built or written. Meshes are in
the target's body frame (the frame of ``targets_in_sensor`` and ``lidarsim poses``), parts as
named objects (:mod:`lidarsim_core.io.meshfile`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer

from ..base.errors import OutputError
from ..base.outputs import make_parent
from ..base.terminal import terminal_safe
from .app import app
from .errors import run_guarded

_SCENARIO_SUFFIXES = (".yaml", ".yml", ".toml", ".json")


@app.command()
def mesh(source: str = typer.Argument(..., help="Target model name (e.g. envisat) or a "
                                                "scenario file (one mesh per target)."),
         out: Path = typer.Option(..., "--out", "-o",
                                  help="Output file (.obj, .ply, .glb, .stl); for a scenario "
                                       "a directory or a name with '{target}'."),
         option: list[str] = typer.Option([], "--option",
                                          help="Model option key=value (repeatable), e.g. "
                                               "detail=fine."),
         fmt: str = typer.Option("obj", "--format",
                                 help="Suffix of the files written into an --out directory."),
         overwrite: bool = typer.Option(False, help="Replace existing files."),
         ) -> None:
    """Write a target model, or every target of a scenario, as a mesh file (body frame)."""
    run_guarded(lambda: _mesh(source, out, option, fmt, overwrite))


def _parse_options(items: list[str]) -> dict[str, Any]:
    import yaml

    from ..base.errors import ConfigError

    options: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--option '{item}' is not key=value", field="--option")
        try:
            options[key.strip()] = yaml.safe_load(text) if text.strip() else text
        except yaml.YAMLError:
            options[key.strip()] = text
    return options


def _mesh(source: str, out: Path, option: list[str], fmt: str, overwrite: bool) -> None:
    from ..base.errors import ConfigError
    from ..io.meshfile import MESH_EXPORT_SUFFIXES, export_mesh
    from ..plugins.manager import get_registry

    suffix = "." + fmt.lower().lstrip(".")
    if suffix not in MESH_EXPORT_SUFFIXES:
        raise OutputError(f"--format {fmt}: known mesh formats are "
                          f"{', '.join(s[1:] for s in MESH_EXPORT_SUFFIXES)}", field="--format")
    path = Path(source)
    is_scenario = path.suffix.lower() in _SCENARIO_SUFFIXES or path.is_file()
    if is_scenario:
        if option:
            raise ConfigError("--option applies to a model name; a scenario sets its targets' "
                              "options itself", field="--option")
        from ..pipeline.simulation import Simulation
        from ..scenario.load import load_scenario

        scenario = load_scenario(path)
        names = [t.name for t in scenario.targets]
        jobs = _checked_outputs(out, names, suffix, overwrite)  # before any mesh is built
        targets = [(t.name, t.mesh) for t in Simulation(scenario).targets]
    else:
        registry = get_registry()
        model = registry.get("target_model", source, field="SOURCE")
        config = model.from_config(_parse_options(option), field="--option")
        jobs = _checked_outputs(out, [source], suffix, overwrite)
        targets = [(source, config.mesh())]
    for (name, mesh_), target in zip(targets, jobs):
        make_parent(target)
        export_mesh(mesh_, target, overwrite=overwrite)
        typer.echo(terminal_safe(f"{name}: {mesh_.n_faces:,} triangles, "
                                 f"{len(mesh_.part_names)} parts "
                                 f"({', '.join(mesh_.part_names)}) → {target}"))


def _checked_outputs(out: Path, names: list[str], suffix: str, overwrite: bool) -> list[Path]:
    """The files to write, every one checked (format, overwrite policy, folder that can be
    created) before any mesh is built or written; an ``.obj`` brings its ``.mtl``."""
    from ..base.outputs import check_group
    from ..io.meshfile import MESH_EXPORT_SUFFIXES, mesh_output_files

    jobs = _outputs(out, names, suffix)
    for target in jobs:
        if target.suffix.lower() not in MESH_EXPORT_SUFFIXES:
            raise OutputError(f"no mesh format for suffix '{target.suffix or '(none)'}'; known: "
                              f"{', '.join(MESH_EXPORT_SUFFIXES)}", source=target)
    # every file of every target (an OBJ's MTL too), all checked before the first is written
    check_group([f for target in jobs for f in mesh_output_files(target)], overwrite=overwrite)
    return jobs


def _outputs(out: Path, names: list[str], suffix: str) -> list[Path]:
    """``--out`` as files: a template with ``{target}``, a directory (an existing one, or a
    name without a suffix, created when missing), or one file."""

    text = str(out)
    for name in names:
        if not name or "/" in name or "\\" in name or name in (".", ".."):
            raise OutputError(f"target name {name!r} cannot be a file name", source=out)
    if "{target}" in text:
        if "{target}" in str(out.parent):
            raise OutputError("'{target}' may appear in the file name only", source=out)
        return [Path(text.replace("{target}", name)) for name in names]
    if out.is_dir() or (not out.suffix and not out.exists()):
        return [out / f"{name}{suffix}" for name in names]
    if len(names) > 1:
        raise OutputError(f"the scenario has {len(names)} targets: give a directory or put "
                          "'{target}' in --out (e.g. meshes/{target}.obj)", source=out)
    return [out]
