"""The seed paper's experiment, step by step from the Python API (the tutorial's script).

A Livox MID-70 (the paper's rose-pattern model) scans Envisat 30 m away for 1 s; the script
checks each step of the paper's method on the result and draws its Figs. 5, 6, 7, 9, 11 and 12.

Usage::

    python examples/paper_experiment.py [OUT_DIR]        # default OUT_DIR: paper-out

``LIDARSIM_EXAMPLE_DURATION`` shortens the scan (seconds; the tests use 0.1).
"""

from __future__ import annotations

# [start:setup]
import math
import os
import sys
from pathlib import Path

import numpy as np

OUT = Path(sys.argv[1] if len(sys.argv) > 1 else "paper-out")
DURATION_S = float(os.environ.get("LIDARSIM_EXAMPLE_DURATION", "1.0"))
OUT.mkdir(parents=True, exist_ok=True)
# [end:setup]

# [start:sensor]
import lidarsim_core as ls

sheet = ls.get_sensor("livox-mid70-rose")
print(f"1. sensor: {sheet.manufacturer} {sheet.model}")
print(f"   {sheet.fov_type} FOV {sheet.fov_h_deg:g}°, {sheet.point_rate_hz:,.0f} points/s, "
      f"range {sheet.range_max_m:g} m, σ_range {100 * sheet.range_precision_m:g} cm, "
      f"σ_angle {sheet.angular_precision_deg:g}°")
# [end:sensor]

# [start:pattern]
from lidarsim_core.plugins import pattern_for
from lidarsim_core.patterns.geometry import off_axis_angle

pattern = pattern_for(sheet)                      # the datasheet's scan_pattern: rose, B = 4
turn_s = pattern.options.turn_period_s            # one turn of φ
rays = pattern.rays(0.0, 3 * turn_s)              # three consecutive rosettes
phi, turn = pattern.phi_and_turn(rays.t)
a_rad = pattern.amplitude_rad                     # A = half the FOV
theta = off_axis_angle(rays.direction)            # r of Eq. 1, as an angle from the boresight
assert np.allclose(theta, np.abs(a_rad * np.sin(pattern.options.b * phi)), atol=1e-9)
print(f"2. pattern: {len(rays):,} rays in 3 turns of {1e3 * turn_s:.2f} ms; "
      f"r = A·sin(Bφ) with A = {math.degrees(a_rad):.1f}°, B = {pattern.options.b} "
      f"({pattern.petals_per_turn} petals per turn), rotated "
      f"{pattern.options.rotation_per_turn_deg:g}° after each turn")
# [end:pattern]

# [start:scenario]
from lidarsim_core.scenario import demo_target_pose
from lidarsim_core.scenario import scenario_from_dict

scenario = scenario_from_dict({
    "seed": 2024,
    "sensor": {"datasheet": "livox-mid70-rose", "pose": {"position_m": [0, 0, 0]}},
    "targets": [{"name": "envisat",
                 "mesh": {"model": "envisat", "options": {"detail": "medium"}},
                 "pose": demo_target_pose()}],      # 30 m ahead, three sides in view
    "scan": {"duration_s": DURATION_S},
    "noise": ["angular", "range"],                  # the datasheet's two errors, in order
})
print(f"3. scene: Envisat body origin at {scenario.targets[0].pose.position_m} m, quaternion "
      f"{[round(q, 3) for q in scenario.targets[0].pose.quaternion_xyzw]}")
# [end:scenario]

# [start:simulate]
from lidarsim_core.pipeline import Simulation

noisy = Simulation(scenario).run_frame(0)
clean = Simulation(scenario.with_updates(noise=[])).run_frame(0)
print(f"4. ray tracing: {noisy.frame.rays_emitted:,} rays, {len(noisy):,} points with errors, "
      f"{len(clean):,} without ({noisy.frame.backend} backend)")
# [end:simulate]

# [start:errors]
from lidarsim_core.report.stats import angular_error_components, fit_normal, range_errors

angular = fit_normal(np.degrees(angular_error_components(noisy)).ravel())
ranging = fit_normal(range_errors(noisy))
print(f"5. errors: angular σ = {angular.sigma:.4f}° "
      f"(datasheet {sheet.angular_precision_deg:g}°), range σ = {1e3 * ranging.sigma:.2f} mm "
      f"(datasheet {1e3 * sheet.range_precision_m:g} mm)")
# Eq. 4: the measured point is the true one moved by the range error e along the ray
v_dir = noisy.xyz_true / noisy["range_true"][:, None]
e = range_errors(noisy)
assert np.allclose(noisy.xyz, noisy.xyz_true + e[:, None] * v_dir, atol=1e-9)
# without errors the reported point is the surface point of the nominal ray
assert np.array_equal(clean["range"], clean["range_true"])
# [end:errors]

# [start:figures]
import yaml

from lidarsim_core.report import VizMissing, write_report

# this script may be rerun: it replaces its own files (lidarsim never does unasked)
noisy.save(OUT / "envisat_mid70_with_errors.npz", overwrite=True)
clean.save(OUT / "envisat_mid70_without_errors.npz", overwrite=True)
(OUT / "scenario.yaml").write_text(yaml.safe_dump(scenario.model_dump(mode="json")))
try:
    report = write_report(OUT, OUT, overwrite=True)   # the run is its own report folder
except VizMissing as exc:
    print(f"6. no figures: {exc}")
else:
    print(f"6. figures: {', '.join(f.path.name for f in report.figures)} and "
          f"{report.html.name} in {OUT}/")
# [end:figures]
