"""Your own sensor from a datasheet file: write it, validate it, scan a target with it.

The datasheet below describes a fictitious "ACME RS-1" MEMS LiDAR with a Lissajous scan. It is
written to a YAML file, loaded and validated (units in the field names, sources required), then
used by a scenario by its path. A mistake in the file is one line naming the file and the field.

Usage::

    python examples/custom_datasheet.py [OUT_DIR]           # default OUT_DIR: custom-sensor-out

``LIDARSIM_EXAMPLE_DURATION`` sets the scan time (s; default 0.5).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import yaml

from lidarsim_core.scenario.datasheet import load_datasheet
from lidarsim_core.base.errors import ConfigError
from lidarsim_core.scenario import scenario_from_dict
from lidarsim_core.pipeline import simulate

OUT = Path(sys.argv[1] if len(sys.argv) > 1 else "custom-sensor-out")
DURATION_S = float(os.environ.get("LIDARSIM_EXAMPLE_DURATION", "0.5"))
OUT.mkdir(parents=True, exist_ok=True)

DATASHEET = {
    "name": "acme-rs1",
    "manufacturer": "ACME Photonics",
    "model": "RS-1",
    "description": "Example MEMS LiDAR: a two-axis mirror drawing a Lissajous figure.",
    "sources": [{"title": "ACME RS-1 datasheet rev. A (fictitious, for this example)"}],
    "estimated_fields": ["angular_precision_deg"],
    "fov_type": "rectangular",
    "fov_h_deg": 30.0,
    "fov_v_deg": 20.0,
    "range_min_m": 0.5,
    "range_max_m": 200.0,
    "range_precision_m": 0.015,
    "angular_precision_deg": 0.05,
    "point_rate_hz": 50000,
    "wavelength_nm": 905,
    "scan_pattern": {"name": "lissajous",
                     "options": {"azimuth_hz": 97.0, "elevation_hz": 101.0}},
}

sheet_path = OUT / "acme-rs1.yaml"
sheet_path.write_text(yaml.safe_dump(DATASHEET, sort_keys=False))
sheet = load_datasheet(sheet_path)
print(f"loaded {sheet.name}: {sheet.fov_h_deg:g}° × {sheet.fov_v_deg:g}° {sheet.fov_type}, "
      f"{sheet.point_rate_hz:,.0f} points/s, pattern '{sheet.scan_pattern.name}'")

# a box 4 m × 3 m × 2 m, 25 m ahead and turned 30° about Z
scenario = scenario_from_dict({
    "seed": 1,
    "sensor": {"datasheet": str(sheet_path)},
    "targets": [{"name": "box", "mesh": {"model": "box", "options": {"extents_m": [4, 3, 2]}},
                 "pose": {"position_m": [25, 0, 0], "euler_deg": [0, 0, 30]}}],
    "scan": {"duration_s": DURATION_S},
})
cloud = simulate(scenario)
err = cloud["range"] - cloud["range_true"]
print(f"{len(cloud):,} points of {cloud.frame.rays_emitted:,} rays on the box; ranges "
      f"{cloud['range_true'].min():.2f}–{cloud['range_true'].max():.2f} m; range error σ "
      f"{1e3 * err.std():.1f} mm (datasheet {1e3 * sheet.range_precision_m:g} mm)")
assert len(cloud) > 0 and np.all(np.abs(np.degrees(cloud["azimuth"])) <= 15 + 1e-6)
cloud.save(OUT / "acme-rs1_box.ply", overwrite=True)  # a rerun replaces its own file

# a wrong value: one line naming the file and the field
broken = dict(DATASHEET, fov_h_deg=200.0)
broken_path = OUT / "acme-rs1-broken.yaml"
broken_path.write_text(yaml.safe_dump(broken, sort_keys=False))
try:
    load_datasheet(broken_path)
except ConfigError as exc:
    print(f"as expected: {exc}")
else:
    raise SystemExit("the broken datasheet was accepted")
