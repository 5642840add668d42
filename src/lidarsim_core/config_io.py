"""Reading configuration files (YAML, TOML, JSON) safely, with errors that name the file.

YAML is read with ``yaml.safe_load`` only: configuration never executes code.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from .components import first_validation_error
from .errors import ConfigError

CONFIG_SUFFIXES = (".yaml", ".yml", ".toml", ".json")


def read_config_file(path: str | Path) -> dict[str, Any]:
    """Parse a YAML/TOML/JSON file into a mapping.

    Raises
    ------
    ConfigError
        If the file is missing, unreadable, malformed, not a mapping, or of an unknown suffix.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in CONFIG_SUFFIXES:
        raise ConfigError(f"unsupported configuration format '{suffix or '(none)'}'; use one of "
                          f"{', '.join(CONFIG_SUFFIXES)}", source=path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError("file not found", source=path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read file: {exc}", source=path) from None
    data = parse_config_text(text, suffix, source=path)
    return data


def parse_config_text(text: str, suffix: str, *, source: str | Path = "<string>") -> dict[str, Any]:
    """Parse configuration ``text`` in the format given by ``suffix`` (``.yaml``, ``.toml``, ``.json``)."""
    try:
        if suffix in (".yaml", ".yml"):
            import yaml

            try:
                data = yaml.safe_load(text)
            except yaml.YAMLError as exc:
                mark = getattr(exc, "problem_mark", None)
                where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
                problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
                raise ConfigError(f"malformed YAML{where}: {problem}", source=source) from None
        elif suffix == ".toml":
            data = tomllib.loads(text)
        else:
            data = json.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"malformed TOML: {exc}", source=source) from None
    except json.JSONDecodeError as exc:
        raise ConfigError(f"malformed JSON: {exc}", source=source) from None
    if data is None:
        raise ConfigError("file is empty", source=source)
    if not isinstance(data, dict):
        raise ConfigError(f"top level must be a mapping, not {type(data).__name__}", source=source)
    return data


def validate_model(model: type[BaseModel], data: Any, *, source: str | Path | None,
                   prefix: str = "", context: dict[str, Any] | None = None) -> Any:
    """Validate ``data`` against a pydantic ``model``, turning the first error into a one-line
    :class:`ConfigError` that names ``source`` and the dotted field."""
    try:
        return model.model_validate(data, context=context)
    except ValidationError as exc:
        field, msg = first_validation_error(exc, prefix)
        raise ConfigError(msg, source=source, field=field) from None
