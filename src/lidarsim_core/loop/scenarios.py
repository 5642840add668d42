"""Ready-made closed-loop scenes (plain mappings: scenario files in code)."""

from __future__ import annotations

from typing import Any

#: Envisat's orbit (estimate, ~780 km) and its 2013 tumble (docs/motion.md).
_ORBIT = {"altitude_km": 780}


def vbar_approach(*, start_m: float = 50.0, detail: str = "coarse", seed: int = 0,
                  dt: float = 0.1) -> dict[str, Any]:
    """A Livox MID-70 on +V-bar ``start_m`` ahead of Envisat tumbling at 2.67 °/s.

    The chaser's ``hcw`` trajectory gives the start state (at rest on V-bar, a natural
    equilibrium) and the attitude law (boresight at the target's centre, +Z along H-bar);
    the loop steers it from there.
    """
    return {
        "seed": seed,
        "sensor": {"datasheet": "livox-mid70-rose",
                   "trajectory": {"kind": "hcw", "orbit": _ORBIT,
                                  "position_m": [0.0, float(start_m), 0.0]}},
        "targets": [{
            "name": "envisat",
            "mesh": {"model": "envisat", "options": {"detail": detail}},
            "trajectory": {"kind": "tumbling", "position_m": [0, 0, 0],
                           "centre_of_mass_m": [0, 0, 0], "euler_deg": [-90, 0, -90],
                           "symmetry_axis": [0, 1, 0], "angular_momentum_axis": [0, 0, -1],
                           "spin_rate_deg_s": 2.67, "orbit": _ORBIT}}],
        "scan": {"duration_s": dt, "motion": "per_ray"},
    }
