"""Tests of the example vendor plugin: its pattern passes lidarsim's conformance suite, and
lidarsim finds its datasheet and pattern through the plugin machinery."""

from __future__ import annotations

import math
from importlib.resources import files

import numpy as np
import pytest

from lidarsim_core.scenario.datasheet import load_datasheet
from lidarsim_core.patterns.geometry import off_axis_angle
from lidarsim_core.testing.patterns import PatternConformance
from lidarsim_example_vendor.spiral import SpiralPattern

SHEET = load_datasheet(str(files("lidarsim_example_vendor") / "sensors"
                           / "example-vendor-spiral.yaml"))


class TestSpiralConformance(PatternConformance):
    """lidarsim's shipped pattern suite, run on the plugin's pattern."""

    @pytest.fixture
    def pattern(self):
        return SpiralPattern.for_sensor(SHEET)


def test_spiral_reaches_the_fov_edge_once_per_frame():
    pattern = SpiralPattern.for_sensor(SHEET)
    batch = pattern.rays(0.0, 0.1)  # exactly one frame at 10 Hz
    theta = off_axis_angle(batch.direction)
    # the off-axis angle grows linearly with time within a frame: A·u
    np.testing.assert_allclose(theta, math.radians(15.0) * batch.t / 0.1, atol=1e-12)


@pytest.fixture
def registry(monkeypatch):
    """A registry built with this plugin loaded by module name (no installation needed)."""
    from lidarsim_core.plugins import get_registry, reset_registry

    monkeypatch.setenv("LIDARSIM_DISABLE_PLUGIN_AUTOLOAD", "1")
    monkeypatch.setenv("LIDARSIM_PLUGINS", "lidarsim_example_vendor.plugin")
    reset_registry()
    yield get_registry()
    reset_registry()


def test_lidarsim_lists_the_plugin_sensor_and_pattern(registry):
    entry = registry.entry("sensor", "example-vendor-spiral")
    assert entry.obj.scan_pattern.name == "example-spiral"
    assert "lidarsim_example_vendor" in entry.provider
    assert registry.get("scan_pattern", "example-spiral") is SpiralPattern
