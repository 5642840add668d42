"""Receiver dynamic range: a retro-reflector's intensity clips at the saturation level, and
the range walk of saturated returns follows ΔR(S) = −σ_R (√(2 ln S) − √(2 ln S_sat))."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import datasheet, scenario

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.pipeline import Simulation
from lidarsim_core.scenario import scenario_from_dict

RETRO = {"diffuse_reflectivity": 0.1, "retro_reflectivity": 1000.0, "retro_acceptance_deg": 30}


def _retro(range_m, receiver=None, angle_deg=20.0):
    sheet = datasheet(fov_h_deg=2.0, fov_v_deg=2.0, range_min_m=0.05, range_max_m=500.0,
                      range_resolution_m=0.6,
                      range_at_reflectivity=[{"reflectivity": 0.1, "range_m": 90.0}])
    sc = scenario({"model": "plate", "options": {"size_m": [20, 20]}},
                  {"position_m": [range_m, 0, 0], "euler_deg": [0, 0, angle_deg]}, sheet=sheet,
                  duration_s=0.05)
    data = sc.model_dump()
    data["sensor"]["detection"] = {}
    if receiver is not None:
        data["sensor"]["receiver"] = receiver
    data["targets"][0]["materials"] = {"plate": RETRO}
    return scenario_from_dict(data)


@pytest.mark.parametrize("range_m", [20.0, 60.0, 450.0])
def test_retro_reflector_intensity_clips_at_saturation(range_m):
    free = Simulation(_retro(range_m)).run_frame(0)
    sim = Simulation(_retro(range_m, {"saturation_signal": 200.0}))
    clipped = sim.run_frame(0)
    assert np.array_equal(free["ray_index"], clipped["ray_index"])
    link = sim.link
    ceiling = 200.0 * clipped["range"] ** link.exponent / link.constant
    expected = np.minimum(free["intensity"].astype(np.float64), ceiling)
    np.testing.assert_allclose(clipped["intensity"], expected, rtol=1e-6)
    signal = link.signal(free["intensity"].astype(np.float64), free["range"])
    if range_m < 100:  # close: every return of the retro-reflector saturates
        assert (signal > 200).all()
        np.testing.assert_allclose(clipped["intensity"], ceiling, rtol=1e-6)
    else:  # far: none does
        assert (signal < 200).all()
        assert np.array_equal(clipped["intensity"], free["intensity"])
    # without the walk, saturation moves no point
    assert np.array_equal(clipped["range"], free["range"])


def test_range_walk_follows_its_function():
    sat = 20.0
    sim = Simulation(_retro(25.0, {"saturation_signal": sat, "range_walk": True}))
    cloud = sim.run_frame(0)
    assert len(cloud) == 500  # every pulse hits the retro-reflector
    link = sim.link
    # the unsaturated signal from the material's closed form at the true incidence and range
    theta = cloud["incidence_angle"]
    rho = 0.1 * np.cos(theta) + 1000.0 * np.maximum(0.0, 1.0 - theta / math.radians(30))
    s = link.constant * rho / cloud["range_true"] ** link.exponent
    assert s.min() > sat
    sigma = 0.6 / (2.0 * math.sqrt(2.0 * math.log(2.0)))
    walk = -sigma * (np.sqrt(2.0 * np.log(s)) - math.sqrt(2.0 * math.log(sat)))
    np.testing.assert_allclose(cloud["range"] - cloud["range_true"], walk, atol=1e-9)
    assert walk.max() < -0.1  # a bias of decimetres: visible, as on real sensors
    # the point moves along its ray by the walk
    np.testing.assert_allclose(np.hypot(np.hypot(cloud["x"], cloud["y"]), cloud["z"]),
                               cloud["range"], rtol=1e-12)


def test_receiver_needs_detection():
    data = _retro(20.0, {"saturation_signal": 5.0}).model_dump()
    data["sensor"]["detection"] = None
    with pytest.raises(ConfigError, match="sensor.receiver"):
        Simulation(scenario_from_dict(data))


def test_saturation_level_from_the_datasheet():
    data = _retro(20.0, {}).model_dump()
    with pytest.raises(ConfigError, match="sensor.receiver.saturation_signal"):
        Simulation(scenario_from_dict(data))
    data["sensor"]["datasheet"]["saturation_signal"] = 200.0
    from_sheet = Simulation(scenario_from_dict(data)).run_frame(0)
    given = Simulation(_retro(20.0, {"saturation_signal": 200.0})).run_frame(0)
    assert np.array_equal(from_sheet["intensity"], given["intensity"])
