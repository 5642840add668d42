"""Small builders shared by the tests (plain functions, imported as ``from helpers import ...``)."""

from __future__ import annotations

from typing import Any

import lidarsim_core as ls

#: A small valid scenario file's contents for CLI tests: coarse Envisat 30 m away, MID-70
#: rose, 0.05 s, NumPy backend (callers copy it before changing it).
CLI_SCENARIO: dict[str, Any] = {
    "seed": 1,
    "sensor": {"datasheet": "livox-mid70-rose", "pose": {"position_m": [0, 0, 0]}},
    "targets": [{"name": "envisat", "mesh": {"model": "envisat", "options": {"detail": "coarse"}},
                 "pose": {"position_m": [30, -8, 0], "euler_deg": [0, 0, 90]}}],
    "scan": {"duration_s": 0.05},
    "backend": "numpy",
}


def datasheet(**overrides: Any) -> dict[str, Any]:
    """An inline test datasheet: circular 40° FOV rose scanner, 10 kHz, 1 cm / 0.05°."""
    sheet: dict[str, Any] = {
        "name": "test-rose", "manufacturer": "Test", "model": "Rose",
        "sources": [{"title": "unit test"}],
        "fov_type": "circular", "fov_h_deg": 40.0, "fov_v_deg": 40.0,
        "range_max_m": 500.0, "range_min_m": 0.1,
        "range_precision_m": 0.01, "angular_precision_deg": 0.05,
        "point_rate_hz": 10000.0,
        "scan_pattern": {"name": "rose", "options": {"b": 4, "turn_period_s": 0.02}},
    }
    sheet.update(overrides)
    return sheet


def scenario(target_mesh: dict[str, Any], target_pose: dict[str, Any] | None = None, *,
             sheet: dict[str, Any] | None = None, duration_s: float = 0.2,
             noise: list | tuple | None = (), backend: str = "numpy", seed: int = 1,
             sensor_pose: dict[str, Any] | None = None, **extra: Any) -> ls.Scenario:
    """A one-target scenario with an inline datasheet; noiseless unless ``noise`` is given
    (``None`` = the datasheet's default chain)."""
    data: dict[str, Any] = {
        "seed": seed,
        "sensor": {"datasheet": sheet or datasheet(), "pose": sensor_pose or {}},
        "targets": [{"name": "t", "mesh": target_mesh, "pose": target_pose or {}}],
        "scan": {"duration_s": duration_s},
        "backend": {"name": backend},
        "noise": list(noise) if noise is not None else None,  # None: datasheet default
        **extra,
    }
    from lidarsim_core.scenario import scenario_from_dict

    return scenario_from_dict(data)
