"""The light-in-orbit report figures: written off-screen, with the physics they illustrate."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from lidarsim_core.pipeline import Simulation  # noqa: E402
from lidarsim_core.report import light  # noqa: E402


def test_ghost_figure_shows_the_bus_behind_the_panel(tmp_path):
    counts = light.ghost_figure(tmp_path / "ghosts.png", duration_s=0.05)
    assert (tmp_path / "ghosts.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert counts["ghosts"] > 50
    cloud = Simulation(light.ghost_scenario(0.05)).run_frame(0)
    ghost = cloud["bounces"] > 0
    assert (cloud["target"][ghost] == 0).all()  # every ghost comes from the bus
    # the reported points are the bus points mirrored through the panel's plane
    a = math.radians(light.PANEL_YAW_DEG)
    n = np.array([math.cos(a), math.sin(a), 0.0])
    q = np.stack([cloud["x_true"], cloud["y_true"], cloud["z_true"]], axis=1)[ghost]
    image = q - 2.0 * ((q - np.array(light.PANEL_CENTRE)) @ n)[:, None] * n
    measured = np.stack([cloud["x"], cloud["y"], cloud["z"]], axis=1)[ghost]
    # within the datasheet's noise (angular 0.1° at ~35 m, range 2 cm): a few centimetres
    assert np.percentile(np.linalg.norm(measured - image, axis=1), 99) < 0.2
    plain = Simulation(light.ghost_scenario(0.05, multipath=False)).run_frame(0)
    assert "bounces" not in plain.columns and (plain["target"] == 0).any()  # bus seen directly


def test_sun_sweep_follows_the_receiver_model(tmp_path):
    sweep = light.sun_angle_sweep(np.array([0.0, 90.0, 180.0]), duration_s=0.02)
    assert sweep["false_alarms"][0] == 0 and sweep["false_alarms"][1] == 0
    n = 2000  # pulses in 0.02 s of the MID-70
    p = sweep["predicted"][2]
    assert abs(sweep["false_alarms"][2] - p) < 5 * math.sqrt(p * (1 - p) / n)
    assert sweep["returns"][0] < sweep["returns"][1]  # blinded around the Sun


def test_earth_sweep_follows_the_receiver_model(tmp_path):
    """As the terminator crosses the field of view, the false alarms per pulse follow the mean
    of P(B) − P(0) over the pulses, B from the ray-sphere geometry of each."""
    sweep = light.earth_sweep(np.array([84.0, 90.0, 97.0]), duration_s=0.05)
    assert sweep["dayside"][0] == 1.0 and 0.3 < sweep["dayside"][1] < 0.7
    assert sweep["dayside"][2] == 0.0 and sweep["false_alarms"][2] == 0.0
    n = 5000  # pulses in 0.05 s of the MID-70
    for rate, p in zip(sweep["false_alarms"][:2], sweep["predicted"][:2]):
        assert p > 0.003
        assert abs(rate - p) < 5 * math.sqrt(p * (1 - p) / n)
