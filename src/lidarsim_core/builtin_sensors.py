"""Built-in plugin: the sensor catalogue shipped in ``sensors/``; and the sensor look-up API."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

from .datasheet import SensorDatasheet, load_datasheet
from .errors import ConfigError, PluginError
from .hookspecs import hookimpl
from .plugins import PluginLoadWarning, package_data_dir
from .registry import Registry


@hookimpl
def lidarsim_register_sensors(register: Any) -> None:
    """Register every datasheet in the built-in catalogue directory."""
    register(package_data_dir("sensors"))


def register_sensor_source(registry: Registry, source: Any, provider: str, *, strict: bool) -> None:
    """Add a datasheet, a datasheet file, or a directory of them to ``registry``.

    A third-party datasheet that fails validation becomes a warning naming file and provider
    (``strict=False``); a built-in one is an error, because it is our bug.
    """
    if isinstance(source, SensorDatasheet):
        registry.add("sensor", source.name, source, provider)
        return
    if hasattr(source, "is_dir") and hasattr(source, "iterdir"):
        path = Path(str(source))
    elif isinstance(source, (str, Path)):
        path = Path(source)
    else:
        raise PluginError(f"{provider} registered a sensor of unsupported type "
                          f"{type(source).__name__}; give a SensorDatasheet or a path")
    files = sorted(p for p in path.iterdir() if p.suffix in (".yaml", ".yml")) \
        if path.is_dir() else [path]
    for file in files:
        try:
            sheet = load_datasheet(file)
        except ConfigError as exc:
            if strict:
                raise
            warnings.warn(f"sensor datasheet from {provider} skipped: {exc}", PluginLoadWarning,
                          stacklevel=2)
            continue
        registry.add("sensor", sheet.name, sheet, provider)


def get_sensor(name_or_path: str | Path, *, source: str | None = None,
               field: str | None = None) -> SensorDatasheet:
    """A datasheet by catalogue name, or read from a file path (suffix ``.yaml``/``.toml``/``.json``)."""
    from .plugins import get_registry

    text = str(name_or_path)
    if text.endswith((".yaml", ".yml", ".toml", ".json")) or Path(text).is_file():
        return load_datasheet(Path(text))
    return get_registry().get("sensor", text, source=source, field=field)
