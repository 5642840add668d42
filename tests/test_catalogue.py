"""The built-in sensor catalogue: contents, sources, estimates, an Envisat run per sensor, and a
vendor plugin adding its own sensor and pattern."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pytest
from typer.testing import CliRunner

from lidarsim_core.base.resources import package_data_dir
from lidarsim_core.cli import app
from lidarsim_core.pipeline import Simulation
from lidarsim_core.plugins import get_registry
from lidarsim_core.plugins.resolve import get_sensor, pattern_for
from lidarsim_core.scenario import demo_scenario

REQUIRED = {
    "livox-mid70": "risley", "livox-mid70-rose": "rose", "livox-mid40": "risley",
    "livox-avia": "risley", "velodyne-vlp16": "spinning", "velodyne-hdl32e": "spinning",
    "ouster-os1-64": "spinning", "ball-vns-flash": "flash", "rvs-class-lissajous": "lissajous",
    "opromolla2015-space-lidar": "raster",
}
CATALOGUE = get_registry().names("sensor")
PLUGIN_DIR = Path(__file__).resolve().parents[1] / "plugins" / "lidarsim-example-vendor"


def test_catalogue_has_the_required_sensors():
    assert len(CATALOGUE) >= 12
    for name, pattern in REQUIRED.items():
        assert get_sensor(name).scan_pattern.name == pattern, name


def test_default_mid70_is_the_physical_risley_model():
    sheet = get_sensor("livox-mid70")
    assert sheet.scan_pattern.name == "risley"
    assert sheet.fov_type == "circular" and sheet.fov_h_deg == 70.4


def test_flash_sensor_is_a_256_by_256_array():
    options = get_sensor("ball-vns-flash").scan_pattern.options
    assert (options["rows"], options["columns"]) == (256, 256)


@pytest.mark.parametrize("name", CATALOGUE)
def test_datasheet_states_sources_and_estimates(name):
    sheet = get_sensor(name)
    assert (package_data_dir("sensors") / f"{name}.yaml").is_file()
    assert sheet.sources and all(s.title.strip() for s in sheet.sources)
    notes = " ".join((s.note or "") for s in sheet.sources).lower()
    if "estimate" in notes:
        assert sheet.estimated_fields, f"{name} mentions estimates but lists none"


@pytest.mark.parametrize("name", CATALOGUE)
def test_every_sensor_scans_the_embedded_envisat(name):
    pattern = pattern_for(get_sensor(name))
    cycle = getattr(pattern, "rays_per_cycle", 1) / getattr(pattern, "mean_rate_hz",
                                                            pattern.rate_hz)
    duration = min(max(0.02, cycle), 1.0)
    scenario = demo_scenario(duration_s=duration, sensor=name, detail="coarse", seed=5)
    cloud = Simulation(scenario).run_frame(0)
    assert cloud.frame.sensor == name
    assert cloud.frame.rays_emitted > 0
    assert len(cloud) > 0, f"{name}: no ray hit Envisat 30 m ahead in {duration:g} s"
    assert (cloud["range_true"] > 10).all() and (cloud["range_true"] < 60).all()


# ---- the vendor plugin example --------------------------------------------------------------
def test_vendor_plugin_adds_a_sensor_and_a_pattern(monkeypatch, fresh_registry):
    monkeypatch.syspath_prepend(str(PLUGIN_DIR / "src"))
    monkeypatch.setenv("LIDARSIM_PLUGINS", "lidarsim_example_vendor.plugin")
    result = CliRunner().invoke(app, ["sensors", "--json"])
    assert result.exit_code == 0, result.output
    rows = {row["name"]: row for row in json.loads(result.output)}
    assert rows["example-vendor-spiral"]["scan_pattern"]["name"] == "example-spiral"
    assert "lidarsim_example_vendor" in rows["example-vendor-spiral"]["provider"]
    assert "livox-mid70" in rows  # the built-ins are still there
    pattern = pattern_for(get_sensor("example-vendor-spiral"))
    assert pattern.inside_fov(pattern.rays(0.0, 0.1).direction).all()


def _installed(dist: str) -> bool:
    try:
        metadata.distribution(dist)
    except metadata.PackageNotFoundError:
        return False
    return True


@pytest.mark.skipif(not _installed("lidarsim-example-vendor"),
                    reason="plugins/lidarsim-example-vendor is not installed (CI installs it)")
def test_installed_vendor_plugin_is_found_through_its_entry_point():
    env = {k: v for k, v in os.environ.items()
           if k not in ("LIDARSIM_DISABLE_PLUGIN_AUTOLOAD", "LIDARSIM_PLUGINS")}
    out = subprocess.run([sys.executable, "-m", "lidarsim_core.cli", "sensors", "--json"],
                         capture_output=True, text=True, env=env, check=True).stdout
    rows = {row["name"]: row for row in json.loads(out)}
    assert rows["example-vendor-spiral"]["provider"].startswith("lidarsim-example-vendor")
