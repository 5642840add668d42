"""Every look-up of a component by name, in one place: sensors, scan patterns, noise models,
ray backends, trajectories, target models and exporters.

Lower layers never consult the plugin registry themselves; the code that assembles a run
(:class:`~lidarsim_core.pipeline.simulation.Simulation`, the CLI, datasets, evaluation, the
benchmark) resolves names here and hands the components down. Each function takes the
registry to use (default: the process-wide one, :func:`~.manager.get_registry`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..backends.base import RayBackend
from ..base.errors import ConfigError, MeshError, OutputError
from ..io.base import Exporter
from ..noise.base import NoiseModel
from ..patterns.base import ScanPattern
from ..records.pointcloud import PointCloud
from ..scenario.datasheet import SensorDatasheet, load_datasheet
from ..scenario.model import NamedComponent, Scenario
from ..scene.mesh import Mesh, load_mesh_file
from ..trajectories.base import Trajectory
from .guards import guard_exporter
from .manager import get_registry
from .registry import Registry

#: Suffixes that make a sensor name a datasheet file.
DATASHEET_SUFFIXES = (".yaml", ".yml", ".toml", ".json")


def get_sensor(name_or_path: str | Path, *, source: str | None = None,
               field: str | None = None) -> SensorDatasheet:
    """A datasheet by catalogue name, or read from a file path (suffix ``.yaml``/``.toml``/``.json``)."""
    text = str(name_or_path)
    if text.endswith(DATASHEET_SUFFIXES) or Path(text).is_file():
        return load_datasheet(Path(text))
    return get_registry().get("sensor", text, source=source, field=field)


def datasheet_for(scenario: Scenario, registry: Registry | None = None) -> SensorDatasheet:
    """The datasheet ``sensor.datasheet`` of ``scenario`` names: an inline mapping, a file
    (relative to the scenario's folder) or a catalogue name."""
    from ..base.validation import validate_model

    spec = scenario.sensor.datasheet
    src = scenario.source
    if isinstance(spec, dict):
        return validate_model(SensorDatasheet, spec, source=src, prefix="sensor.datasheet")
    if spec.endswith(DATASHEET_SUFFIXES):
        path = scenario.resolve(Path(spec))
        if not path.is_file():
            raise ConfigError(f"datasheet file not found: {path}", source=src,
                              field="sensor.datasheet")
        return load_datasheet(path)
    return (registry or get_registry()).get("sensor", spec, source=src, field="sensor.datasheet")


def pattern_for(sensor: SensorDatasheet, overrides: dict[str, Any] | None = None, *,
                source: str | Path | None = None, field: str = "scan_pattern.name",
                registry: Registry | None = None) -> ScanPattern:
    """The scan pattern of a datasheet (its ``scan_pattern`` plus ``overrides``).

    Parameters
    ----------
    sensor
        A :class:`~lidarsim_core.scenario.datasheet.SensorDatasheet`.
    overrides
        Pattern options replacing the datasheet's.
    source, field
        Where the datasheet came from (its file) and the field naming its pattern, for errors.
    registry
        The registry to look the pattern up in (default: the process-wide one).
    """
    cls = (registry or get_registry()).get("scan_pattern", sensor.scan_pattern.name,
                                           source=source, field=field)
    return cls.for_sensor(sensor, overrides, source=source)


def pattern_for_cloud(cloud: PointCloud) -> ScanPattern:
    """The scan pattern of the catalogue sensor named in ``cloud.frame.sensor``, with its
    datasheet's options (a scenario's ``pattern_options`` are not in the frame metadata: pass
    ``Simulation(scenario).pattern`` for those)."""
    return pattern_for(get_sensor(cloud.frame.sensor), {})


def component(registry: Registry, kind: str, spec: NamedComponent, *, source: str | Path | None,
              field: str) -> Any:
    """An instance of the ``kind`` component ``spec`` names, built from its options."""
    cls = registry.get(kind, spec.name, source=source, field=f"{field}.name")
    return cls.from_config(spec.options, source=source, field=f"{field}.options")


def noise_chain(registry: Registry, specs: list[NamedComponent], *,
                source: str | Path | None) -> list[NoiseModel]:
    """The noise models of a scenario's ``noise`` list, in chain order."""
    return [component(registry, "noise_model", spec, source=source, field=f"noise.{i}")
            for i, spec in enumerate(specs)]


def resolve_backend(registry: Registry, spec: NamedComponent, *,
                    source: str | Path | None) -> RayBackend:
    """Instantiate the configured backend; ``auto`` picks Embree when available, else NumPy."""
    if spec.name == "auto":
        embree = registry.entries["ray_backend"].get("embree")
        usable = embree is not None and embree.obj.is_available()[0]
        spec = NamedComponent(name="embree" if usable else "numpy", options=spec.options)
    backend = component(registry, "ray_backend", spec, source=source, field="backend")
    ok, why = backend.is_available()
    if not ok:
        raise ConfigError(f"backend '{spec.name}' is not usable here: {why}", source=source,
                          field="backend.name")
    return backend


def trajectory_for(registry: Registry, posed: Any, *, source: str | Path | None,
                   field: str) -> Trajectory:
    """The trajectory of a posed scenario entry (the sensor or a target)."""
    config = posed.trajectory_config()
    cls = registry.get("trajectory", config.kind, source=source, field=f"{field}.kind")
    return cls.from_config(config.plugin_options(), source=source, field=field)


def target_mesh(registry: Registry, scenario: Scenario, index: int) -> Mesh:
    """The mesh of target ``index`` of ``scenario``: read from its file or built by its
    target model, scaled by ``scale``."""
    cfg = scenario.targets[index].mesh
    field = f"targets.{index}.mesh"
    if cfg.path is not None:
        return load_mesh_file(scenario.resolve(cfg.path), scale=cfg.scale,
                              source=scenario.source, field=f"{field}.path")
    model_cls = registry.get("target_model", cfg.model, source=scenario.source,
                             field=f"{field}.model")
    model = model_cls.from_config(cfg.options, source=scenario.source, field=f"{field}.options")
    try:  # a model's options or the scale can make an unusable mesh: name the field
        mesh = model.mesh()
        if cfg.scale != 1.0:
            mesh = Mesh.from_arrays(mesh.vertices * cfg.scale, mesh.faces, mesh.face_part,
                                    mesh.part_names, name=mesh.name,
                                    part_materials=mesh.part_materials)
    except MeshError as exc:  # a procedural model reads no file: the scenario is to blame
        raise MeshError(f"model '{cfg.model}': {exc.message}", source=scenario.source,
                        field=field) from None
    return mesh


def exporter_for(path: str | Path, format: str | None = None, *,
                 registry: Registry | None = None,
                 options: dict[str, Any] | None = None) -> Exporter:
    """The exporter selected by ``format`` (a registered name) or by the suffix of ``path``,
    built with ``options`` (e.g. ``{"dialect": "cloudcompare"}``); a third-party one is
    guarded (:mod:`lidarsim_core.plugins.guards`), so that its failure is reported by name and
    leaves no file.

    Raises
    ------
    OutputError
        If no exporter handles the suffix (naming the known ones).
    ConfigError
        If the exporter has no such option or rejects its value.
    """
    registry = registry or get_registry()
    if format:
        cls = registry.get("exporter", format, field="format")
        return guard_exporter(cls.from_config(options, field="exporter_options"), registry)
    suffix = Path(path).suffix.lower()
    for entry in registry.iter("exporter"):
        if suffix in entry.obj.suffixes:
            return guard_exporter(entry.obj.from_config(options, field="exporter_options"),
                                  registry)
    known = sorted(s for e in registry.iter("exporter") for s in e.obj.suffixes)
    raise OutputError(f"no exporter for suffix '{suffix or '(none)'}'; known: {', '.join(known)}",
                      source=path)


def exporter_named(name: str, options: dict[str, Any] | None = None, *,
                   registry: Registry | None = None) -> Exporter:
    """The exporter registered as ``name``, built with ``options`` (a dataset's ``format`` and
    ``exporter_options``), guarded like :func:`exporter_for`'s."""
    registry = registry or get_registry()
    cls = registry.get("exporter", name, field="format")
    return guard_exporter(cls.from_config(options or {}, field="exporter_options"), registry)
