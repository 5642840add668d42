"""Report figures of light in orbit: multipath ghosts of a mirror-like panel beside a bus,
false alarms and returns against the Sun's angle, and false alarms against the share of the
field of view on the Earth's dayside (docs/realism.md).

Drawn with matplotlib off-screen (the ``viz`` extra). From the command line::

    python -m lidarsim_core.report.light docs/img

writes ``light_ghosts.png``, ``light_sun_angle.png`` and ``light_earth.png`` into the
directory given.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..pipeline.simulation import Simulation
from ..scenario.load import scenario_from_dict
from ..scenario.model import Scenario

#: A second-surface mirror made optically flat (RMS slope 0.02°), e.g. an OSR panel.
FLAT_OSR = {"diffuse_reflectivity": 0.02, "specular_reflectance": 0.85,
            "specular_slope_deg": 0.02, "description": "flat optical solar reflector panel"}
BUS_CENTRE = (30.0, 6.0, 0.0)
BUS_EXTENTS = (4.0, 4.0, 6.0)
PANEL_CENTRE = (26.0, -1.0, 0.0)
PANEL_YAW_DEG = -60.0  # normal bisects the sensor's ray (+x) and the way to the bus
PANEL_SIZE = (3.0, 3.0)


def ghost_scenario(duration_s: float = 0.2, *, multipath: bool = True) -> Scenario:
    """A bus (MLI box) and a flat mirror-like panel beside it, seen by a Livox MID-70."""
    sensor: dict[str, Any] = {"datasheet": "livox-mid70", "detection": {},
                              "returns": {"mode": "dual"}}
    if multipath:
        sensor["multipath"] = {"max_bounces": 2}
    return scenario_from_dict({
        "seed": 17, "sensor": sensor, "scan": {"duration_s": duration_s}, "backend": "numpy",
        "targets": [
            {"name": "bus", "mesh": {"model": "box", "options": {"extents_m": list(BUS_EXTENTS)}},
             "pose": {"position_m": list(BUS_CENTRE)},
             "materials": {"*": "mli_aluminised_kapton"}},
            {"name": "panel", "mesh": {"model": "plate", "options": {"size_m": list(PANEL_SIZE)}},
             "pose": {"position_m": list(PANEL_CENTRE), "euler_deg": [0, 0, PANEL_YAW_DEG]},
             "materials": {"plate": FLAT_OSR}}],
    })


def ghost_figure(path: str | Path, *, duration_s: float = 0.2) -> dict[str, int]:
    """Top view of the direct points, the ghosts behind the panel and the true surface points
    they came from. Returns the point counts."""
    from .charts import new_figure
    from .render import save_figure

    cloud = Simulation(ghost_scenario(duration_s)).run_frame(0)
    ghost = cloud["bounces"] > 0
    direct = ~ghost
    fig = new_figure(8.0, 6.0)
    ax = fig.add_subplot(1, 1, 1)
    ax.scatter(cloud["x"][direct], cloud["y"][direct], s=1, c="0.55", label="direct returns")
    ax.scatter(cloud["x_true"][ghost], cloud["y_true"][ghost], s=2, c="tab:blue",
               label="true surface of the ghosts (bus)")
    ax.scatter(cloud["x"][ghost], cloud["y"][ghost], s=2, c="tab:red",
               label="ghost points (reported)")
    a = math.radians(PANEL_YAW_DEG)
    along = np.array([-math.sin(a), math.cos(a)]) * PANEL_SIZE[0] / 2
    ends = np.array([PANEL_CENTRE[:2] - along, PANEL_CENTRE[:2] + along])
    ax.plot(ends[:, 0], ends[:, 1], c="k", lw=2.5, label="mirror-like panel (flat OSR)")
    bx, by = BUS_CENTRE[0], BUS_CENTRE[1]
    hx, hy = BUS_EXTENTS[0] / 2, BUS_EXTENTS[1] / 2
    box = np.array([[bx - hx, by - hy], [bx + hx, by - hy], [bx + hx, by + hy],
                    [bx - hx, by + hy], [bx - hx, by - hy]])
    ax.plot(box[:, 0], box[:, 1], c="tab:blue", lw=1, label="bus (MLI)")
    # the bus mirrored through the panel's plane: where its ghost must appear
    normal = np.array([math.cos(a), math.sin(a)])
    image = box - 2.0 * ((box - np.array(PANEL_CENTRE[:2])) @ normal)[:, None] * normal
    ax.plot(image[:, 0], image[:, 1], c="tab:red", lw=1, ls="--",
            label="bus mirrored through the panel's plane")
    ax.annotate("to the sensor at (0, 0)", xy=(20.5, 0.0), xytext=(22.5, 0.0),
                va="center", arrowprops={"arrowstyle": "->"})
    ax.set_xlim(20.0, 38.0)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m, sensor frame)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"Multipath ghosts of a flat mirror-like panel beside a bus (Livox MID-70, "
                 f"max_bounces 2): {int(ghost.sum())} of {len(cloud)} points", fontsize=9)
    ax.legend(loc="upper right", fontsize=7, markerscale=4)
    ax.grid(alpha=0.3)
    save_figure(fig, path)
    return {"points": len(cloud), "ghosts": int(ghost.sum())}


def sun_scenario(sun_angle_deg: float, duration_s: float = 0.1,
                 blinding_angle_deg: float = 3.0) -> Scenario:
    """A white plate 20 m ahead, the Sun at ``sun_angle_deg`` from the boresight (in the x-z
    plane): 0° behind the plate, 180° behind the sensor."""
    a = math.radians(sun_angle_deg)
    return scenario_from_dict({
        "seed": 3, "scan": {"duration_s": duration_s}, "backend": "numpy",
        # multi: every false alarm is reported, before or behind the plate's echo
        "sensor": {"datasheet": "livox-mid70", "detection": {},
                   "returns": {"mode": "multi", "max_returns": 2}},
        "targets": [{"name": "plate", "mesh": {"model": "plate", "options": {"size_m": [40, 40]}},
                     "pose": {"position_m": [20.0, 0.0, 0.0]},
                     "materials": {"plate": "white_paint"}}],
        "sun": {"direction": [math.cos(a), 0.0, math.sin(a)],
                "blinding_angle_deg": blinding_angle_deg},
    })


def sun_angle_sweep(angles_deg: np.ndarray, duration_s: float = 0.1) -> dict[str, np.ndarray]:
    """Per Sun angle: fraction of pulses with a false alarm, with a plate return, and the
    receiver model's predicted false-alarm fraction on the plate."""
    alarms, returns, predicted = [], [], []
    for angle in angles_deg:
        sim = Simulation(sun_scenario(float(angle), duration_s))
        cloud = sim.run_frame(0)
        emitted = cloud.frame.rays_emitted
        alarms.append(float((cloud["part"] == sim.false_alarm_part).sum()) / emitted)
        returns.append(float((cloud["target"] == 0).sum()) / emitted)
        stage = next(s for s in sim.stages if s.name == "sun")
        cos_sun = max(0.0, -math.cos(math.radians(float(angle))))
        background = 0.8 * cos_sun * stage.white_background
        predicted.append(float(stage.probability(np.array([background]))[0]))
    return {"angle": np.asarray(angles_deg, dtype=float), "false_alarms": np.array(alarms),
            "returns": np.array(returns), "predicted": np.array(predicted)}


def sun_figure(path: str | Path, *, duration_s: float = 0.1) -> dict[str, np.ndarray]:
    """False alarms and returns against the Sun's angle from the boresight."""
    from .charts import new_figure
    from .render import save_figure

    sweep = sun_angle_sweep(np.arange(0.0, 181.0, 10.0), duration_s)
    fig = new_figure(8.0, 4.5)
    ax = fig.add_subplot(1, 1, 1)
    ax.plot(sweep["angle"], sweep["false_alarms"], "o", c="tab:red",
            label="false alarms per pulse (simulated)")
    ax.plot(sweep["angle"], sweep["predicted"], "-", c="tab:red", alpha=0.6,
            label="receiver model P(B) − P(0)")
    ax.plot(sweep["angle"], sweep["returns"], "s-", c="tab:blue", label="plate returns per pulse")
    ax.set_xlabel("Sun angle from the boresight (deg): 0 behind the plate, 180 behind the sensor")
    ax.set_ylabel("fraction of pulses")
    ax.set_title("White plate 20 m ahead, Livox MID-70: the Sun (blinding angle 3°)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    save_figure(fig, path)
    return sweep


#: The Earth figure's orbit: equatorial, 780 km (Envisat's), epoch the 2024 March equinox
#: (with u0 = 0: local noon below the target; u0 = 90°: dusk).
EARTH_ORBIT = {"epoch": "2024-03-20T03:06:00Z", "altitude_km": 780.0, "inclination_deg": 0.0}


#: Noise-equivalent irradiance of the Earth figure's receiver (W/m²; the default is 10).
EARTH_FIGURE_E_EQ = 1.0


def earth_scenario(u0_deg: float, duration_s: float = 0.05) -> Scenario:
    """A Livox MID-70 pointed at nadir from the target's orbit, ``u0_deg`` past noon, with no
    target in view (the only one is 50 m above, behind the sensor)."""
    return scenario_from_dict({
        "seed": 5, "scan": {"duration_s": duration_s}, "backend": "numpy", "noise": [],
        "sensor": {"datasheet": "livox-mid70", "detection": {},
                   "pose": {"quaternion_xyzw": [0.0, 0.0, 1.0, 0.0]},  # boresight to −R-bar
                   "returns": {"mode": "multi", "max_returns": 2}},
        "targets": [{"name": "above", "mesh": {"model": "plate", "options": {"size_m": [1, 1]}},
                     "pose": {"position_m": [50.0, 0.0, 0.0]}}],
        # a receiver 10x more sensitive to background light than the default, so that the
        # dimly lit ground near the terminator gives countable false alarms
        "sun": {"orbit": {**EARTH_ORBIT, "argument_of_latitude_deg": u0_deg},
                "noise_equivalent_irradiance_w_m2": EARTH_FIGURE_E_EQ},
        "earth": {},
    })


def earth_sweep(u0_deg: np.ndarray, duration_s: float = 0.05) -> dict[str, np.ndarray]:
    """Per orbit position: the share of pulses whose ray meets the Earth's dayside, the
    simulated false alarms per pulse and the model's mean P(B) − P(0), with B computed here
    from the ray-sphere geometry of each pulse."""
    from ..pipeline.stages.sun import sun_in_lvlh
    from ..scenario.earth import EarthConfig
    from ..trajectories.orbit import R_EARTH_M

    day, alarms, predicted = [], [], []
    a = R_EARTH_M + 1000.0 * EARTH_ORBIT["altitude_km"]
    albedo = EarthConfig().albedo
    for u0 in u0_deg:
        scenario = earth_scenario(float(u0), duration_s)
        sim = Simulation(scenario)
        cloud = sim.run_frame(0)
        stage = next(s for s in sim.stages if s.name == "sun")
        rays = sim.pattern.rays(*scenario.scan.frame_interval(0))
        d = rays.direction * np.array([-1.0, -1.0, 1.0])  # the sensor turned 180° about z
        # |o + t d − c| = R⊕ with o = 0, c = (−a, 0, 0): t² + 2 a d_x t + a² − R⊕² = 0
        disc = (a * d[:, 0]) ** 2 - (a - R_EARTH_M) * (a + R_EARTH_M)
        t = -a * d[:, 0] - np.sqrt(np.maximum(disc, 0.0))
        normal = (d * t[:, None] + np.array([a, 0.0, 0.0])) / R_EARTH_M
        sun = sun_in_lvlh(scenario.sun.orbit, rays.t)[0]
        cos_sun = np.where(disc >= 0, np.einsum("ij,ij->i", normal, sun), 0.0)
        background = albedo * np.maximum(cos_sun, 0.0) * stage.white_background
        day.append(float((cos_sun > 0).mean()))
        alarms.append(float((cloud["part"] == sim.false_alarm_part).sum()) / len(rays))
        predicted.append(float(stage.probability(background).mean()))
    return {"u0": np.asarray(u0_deg, dtype=float), "dayside": np.array(day),
            "false_alarms": np.array(alarms), "predicted": np.array(predicted)}


def earth_figure(path: str | Path, *, duration_s: float = 0.1) -> dict[str, np.ndarray]:
    """False alarms per pulse against the share of the field of view on the dayside, as the
    terminator crosses the MID-70's view at dusk."""
    from .charts import new_figure
    from .render import save_figure

    sweep = earth_sweep(np.arange(83.0, 97.5, 1.0), duration_s)
    fig = new_figure(8.0, 4.5)
    ax = fig.add_subplot(1, 1, 1)
    ax.plot(sweep["dayside"], sweep["false_alarms"], "o", c="tab:red",
            label="false alarms per pulse (simulated)")
    ax.plot(sweep["dayside"], sweep["predicted"], "-", c="tab:red", alpha=0.6,
            label="receiver model, mean of P(B) − P(0) over the pulses")
    ax.set_xlabel("share of the field of view on the Earth's dayside")
    ax.set_ylabel("false alarms per pulse")
    ax.set_title("Livox MID-70 pointed at nadir from 780 km at dusk, no target in view "
                 f"(E_eq = {EARTH_FIGURE_E_EQ:g} W/m²)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    save_figure(fig, path)
    return sweep


def main(argv: list[str] | None = None) -> int:
    """Write both figures into the directory given (default ``.``)."""
    args = sys.argv[1:] if argv is None else argv
    out = Path(args[0] if args else ".")
    out.mkdir(parents=True, exist_ok=True)
    counts = ghost_figure(out / "light_ghosts.png")
    sweep = sun_figure(out / "light_sun_angle.png")
    print(f"ghosts: {counts['ghosts']} of {counts['points']} points -> "
          f"{out / 'light_ghosts.png'}")
    for a, f, r, p in zip(sweep["angle"], sweep["false_alarms"], sweep["returns"],
                          sweep["predicted"]):
        print(f"sun {a:5.0f} deg: false alarms {f:.4f}, returns {r:.4f}, model {p:.4f}")
    print(f"-> {out / 'light_sun_angle.png'}")
    earth = earth_figure(out / "light_earth.png")
    for u, f, a, p in zip(earth["u0"], earth["dayside"], earth["false_alarms"],
                          earth["predicted"]):
        print(f"u0 {u:5.1f} deg: dayside {f:.3f}, false alarms {a:.4f}, model {p:.4f}")
    print(f"-> {out / 'light_earth.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
