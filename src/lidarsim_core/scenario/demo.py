"""The embedded default scene: the seed paper's experiment, Envisat scanned by a Livox MID-70.

Needs no file: the target is the parametric Envisat model and the sensor the catalogue's
``livox-mid70-rose`` datasheet (the paper's rose-pattern model of the MID-70).
"""

from __future__ import annotations

from typing import Any

from .load import scenario_from_dict
from .model import Scenario

#: Distance from the sensor to the centre of Envisat's bounding box in the demo (m).
DEMO_RANGE_M = 30.0
#: Centre of the Envisat model's bounding box in its body frame (m), aimed at the boresight.
_ENVISAT_BOX_CENTRE_M = (8.0, 3.3, -0.17)


def demo_target_pose(range_m: float = DEMO_RANGE_M) -> dict[str, Any]:
    """The demo's Envisat pose: long axis across the view (scene +Y), nadir face and solar
    array turned toward the sensor, then yawed 35° and pitched 20° so three sides show; the
    centre of its bounding box ``range_m`` ahead of the sensor (30 m)."""
    import numpy as np
    from scipy.spatial.transform import Rotation

    # body X -> scene +Y, body Z (nadir, array normal) -> scene -X (toward the sensor)
    facing = Rotation.from_matrix(np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0],
                                            [0.0, -1.0, 0.0]]))
    rotation = Rotation.from_euler("zy", [35.0, -20.0], degrees=True) * facing
    position = np.array([range_m, 0.0, 0.0]) - rotation.apply(_ENVISAT_BOX_CENTRE_M)
    return {"position_m": [round(float(v), 6) for v in position],
            "quaternion_xyzw": [round(float(v), 9) for v in rotation.as_quat()]}


def demo_scenario(*, duration_s: float = 1.0, noise: bool = True, detail: str = "medium",
                  backend: str = "auto", seed: int = 2024,
                  sensor: str = "livox-mid70-rose", range_m: float = DEMO_RANGE_M) -> Scenario:
    """The demo scenario: Envisat 30 m in front of the sensor, seen obliquely.

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
    range_m
        Distance from the sensor to the centre of Envisat's bounding box (m).
    """
    data: dict[str, Any] = {
        "seed": seed,
        "sensor": {"datasheet": sensor, "pose": {"position_m": [0.0, 0.0, 0.0]}},
        "targets": [{
            "name": "envisat",
            "mesh": {"model": "envisat", "options": {"detail": detail}},
            "pose": demo_target_pose(range_m),
        }],
        "scan": {"duration_s": duration_s},
        "backend": {"name": backend},
    }
    if not noise:
        data["noise"] = []
    return scenario_from_dict(data, source="<demo>")
