"""The plugin module named by the ``lidarsim`` entry point: registers a datasheet and a pattern."""

from __future__ import annotations

from importlib.resources import files
from typing import Any

from lidarsim_core.hookspecs import hookimpl


@hookimpl
def lidarsim_register_sensors(register: Any) -> None:
    """Register every datasheet shipped in this package's ``sensors/`` directory."""
    register(files("lidarsim_example_vendor") / "sensors")


@hookimpl
def lidarsim_register_scan_patterns(register: Any) -> None:
    """Register the spiral pattern (the class only; nothing heavy is imported here)."""
    from .spiral import SpiralPattern

    register(SpiralPattern)
