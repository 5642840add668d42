"""Scenarios from files, mappings or objects: validated once, with errors naming the file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..base.config_io import read_config_file
from ..base.validation import validate_model
from .model import Scenario


def as_scenario(scenario: Scenario | str | Path | dict[str, Any]) -> Scenario:
    """Accept a :class:`Scenario`, a path to a scenario file, or a mapping."""
    if isinstance(scenario, Scenario):
        return scenario
    if isinstance(scenario, dict):
        return scenario_from_dict(scenario)
    return load_scenario(scenario)


def scenario_from_dict(data: dict[str, Any], *, source: str | Path | None = None) -> Scenario:
    """Validate a mapping as a :class:`Scenario` (errors name ``source`` and the field)."""
    scenario = validate_model(Scenario, data, source=source or "<scenario>")
    if source is not None and Path(str(source)).suffix:
        scenario._source = Path(source).resolve()
    return scenario


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file (YAML, TOML or JSON).

    Raises
    ------
    ConfigError
        One line naming the file and the field when the file is malformed or invalid.
    """
    return scenario_from_dict(read_config_file(path), source=path)
