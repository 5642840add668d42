"""The embedded default scene: the seed paper's experiment, Envisat scanned by a Livox MID-70.

Needs no file: the target is the parametric Envisat model and the sensor the catalogue's
``livox-mid70-rose`` datasheet (the paper's rose-pattern model of the MID-70).
"""

from __future__ import annotations

from typing import Any

from .scenario import Scenario, scenario_from_dict

#: Distance from the sensor to Envisat's body origin in the demo (m).
DEMO_RANGE_M = 35.0


def demo_scenario(*, duration_s: float = 1.0, noise: bool = True, detail: str = "medium",
                  backend: str = "auto", seed: int = 2024,
                  sensor: str = "livox-mid70-rose") -> Scenario:
    """The demo scenario: Envisat 35 m in front of the sensor, seen obliquely.

    Parameters
    ----------
    duration_s
        Scan time (s); the paper's figure uses 1 s.
    noise
        With the datasheet's angular and range errors (True) or without any (False).
    detail
        Envisat model detail: 'coarse', 'medium' or 'fine'.
    backend
        Ray backend name ('auto', 'numpy', 'embree').
    seed
        Noise seed.
    sensor
        Catalogue sensor name.
    """
    data: dict[str, Any] = {
        "seed": seed,
        "sensor": {"datasheet": sensor, "pose": {"position_m": [0.0, 0.0, 0.0]}},
        "targets": [{
            "name": "envisat",
            "mesh": {"model": "envisat", "options": {"detail": detail}},
            # long axis across the view, turned and tilted so three faces are visible
            "pose": {"position_m": [DEMO_RANGE_M, 0.0, 0.0], "euler_deg": [-20.0, 15.0, 60.0],
                     "euler_sequence": "xyz"},
        }],
        "scan": {"duration_s": duration_s},
        "backend": {"name": backend},
    }
    if not noise:
        data["noise"] = []
    return scenario_from_dict(data, source="<demo>")
