"""Helpers shared by the scan-pattern tests: datasheets built in code, patterns by name."""

from __future__ import annotations

from typing import Any

from lidarsim_core.patterns.base import ScanPattern
from lidarsim_core.plugins import get_registry
from lidarsim_core.scenario.datasheet import SensorDatasheet


def make_sheet(pattern: str, options: dict[str, Any] | None = None, *, fov_type: str = "circular",
               fov_h_deg: float = 40.0, fov_v_deg: float | None = None, rate: float = 10_000.0,
               fov_v_center_deg: float = 0.0, name: str = "test-sensor") -> SensorDatasheet:
    """A minimal valid datasheet using ``pattern`` with ``options``."""
    return SensorDatasheet(
        name=name, manufacturer="Test", model="Test", sources=[{"title": "unit test"}],
        fov_type=fov_type, fov_h_deg=fov_h_deg,
        fov_v_deg=fov_v_deg if fov_v_deg is not None else fov_h_deg,
        fov_v_center_deg=fov_v_center_deg, range_max_m=100.0, range_precision_m=0.02,
        angular_precision_deg=0.1, point_rate_hz=rate,
        scan_pattern={"name": pattern, "options": options or {}})


def build(sheet: SensorDatasheet, **overrides: Any) -> ScanPattern:
    """The registered pattern of ``sheet`` with option ``overrides``."""
    cls = get_registry().get("scan_pattern", sheet.scan_pattern.name)
    return cls.for_sensor(sheet, overrides)
