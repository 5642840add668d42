"""Every noise model: its statistics match its parameters, and switched off it gives the
noiseless run bit for bit. Scenes are flat plates hit by every ray of a rose scan, so each
sample is one independent draw."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import scenario

from lidarsim_core.noise.base import perpendicular_basis
from lidarsim_core.pipeline import Simulation
from lidarsim_core.scenario import scenario_from_dict

N_RAYS = 10000  # 1 s of the helper's 10 kHz scanner


def _plate(range_m: float = 20.0, noise=(), duration_s: float = 1.0, **sensor):
    sc = scenario({"model": "plate", "options": {"size_m": [80, 80]}},
                  {"position_m": [range_m, 0, 0]}, noise=list(noise), duration_s=duration_s)
    if not sensor:
        return sc
    data = sc.model_dump()
    data["sensor"].update(sensor)
    return scenario_from_dict(data)


def _run(range_m: float = 20.0, noise=(), **kwargs):
    cloud = Simulation(_plate(range_m, noise, **kwargs)).run_frame(0)
    return cloud


@pytest.fixture(scope="module")
def noiseless():
    cloud = _run()
    assert len(cloud) == N_RAYS
    return cloud


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _mean_ok(values: np.ndarray, expected: float, sigma: float) -> None:
    assert abs(values.mean() - expected) < 4 * sigma / math.sqrt(len(values))


def _std_ok(values: np.ndarray, sigma: float, rtol: float = 0.03) -> None:
    assert values.std() == pytest.approx(sigma, rel=rtol)


# ---- the seed paper's models ---------------------------------------------------------------
def test_range_error_is_gaussian_with_sigma(noiseless):
    cloud = _run(noise=[{"name": "range", "options": {"sigma_m": 0.02}}])
    err = cloud["range"] - cloud["range_true"]
    _mean_ok(err, 0.0, 0.02)
    _std_ok(err, 0.02)
    np.testing.assert_array_equal(cloud["range_true"], noiseless["range_true"])


def _angles(directions: np.ndarray, nominal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Components of the deviation of ``directions`` from ``nominal`` along the two
    perpendicular axes used by the angular models (small angles, rad)."""
    u, v = perpendicular_basis(nominal)
    return np.einsum("ij,ij->i", directions, u), np.einsum("ij,ij->i", directions, v)


def test_angular_error_turns_the_flown_ray_by_sigma_per_axis(noiseless):
    sigma = math.radians(0.1)
    cloud = _run(noise=[{"name": "angular", "options": {"sigma_deg": 0.1}}])
    np.testing.assert_array_equal(cloud["ray_index"], noiseless["ray_index"])
    flown = _unit(cloud.xyz_true)
    a_u, a_v = _angles(flown, _unit(noiseless.xyz_true))
    for comp in (a_u, a_v):
        _mean_ok(comp, 0.0, sigma)
        _std_ok(comp, sigma)
    # the point stays on the surface (the ray really went elsewhere)
    np.testing.assert_allclose(cloud["x_true"], 20.0, atol=1e-9)


def test_angular_point_error_moves_the_measured_point_off_the_surface(noiseless):
    sigma = math.radians(0.1)
    cloud = _run(noise=[{"name": "angular_point", "options": {"sigma_deg": 0.1}}])
    for name in ("x_true", "y_true", "z_true", "range_true"):
        np.testing.assert_array_equal(cloud[name], noiseless[name])  # ray not perturbed
    np.testing.assert_array_equal(cloud["range"], cloud["range_true"])
    a_u, a_v = _angles(_unit(cloud.xyz), _unit(noiseless.xyz_true))
    for comp in (a_u, a_v):
        _mean_ok(comp, 0.0, sigma)
        _std_ok(comp, sigma)
    assert np.abs(cloud["x"] - 20.0).max() > 0.01  # off the plate


# ---- range models ---------------------------------------------------------------------------
@pytest.mark.parametrize("range_m", [10.0, 40.0])
def test_range_growing_sigma_follows_the_power_law(range_m):
    options = {"sigma_m": 0.01, "reference_range_m": 20.0, "exponent": 2.0}
    cloud = _run(range_m, noise=[{"name": "range_growing", "options": options}])
    true = cloud["range_true"]
    sigma = 0.01 * (true / 20.0) ** 2
    z = (cloud["range"] - true) / sigma
    _mean_ok(z, 0.0, 1.0)
    _std_ok(z, 1.0)
    # and in metres, at this range
    _std_ok(cloud["range"] - true, 0.01 * (range_m / 20.0) ** 2, rtol=0.08)


def test_range_growing_floor():
    options = {"sigma_m": 0.01, "reference_range_m": 20.0, "floor_m": 0.005}
    cloud = _run(5.0, noise=[{"name": "range_growing", "options": options}])
    _std_ok(cloud["range"] - cloud["range_true"], 0.005)  # (5/20)² · 1 cm < 5 mm floor


def test_range_systematic_is_bias_plus_scale():
    options = {"bias_m": 0.037, "scale": 2e-4}
    cloud = _run(noise=[{"name": "range_systematic", "options": options}])
    np.testing.assert_allclose(cloud["range"], cloud["range_true"] * (1 + 2e-4) + 0.037,
                               rtol=0, atol=1e-12)


def test_range_quantisation_is_uniform_within_half_a_step():
    q = 0.01
    # a plate at 50° spreads the true ranges over metres (face-on, the symmetric rose
    # pattern repeats a few ranges and their rounding errors would not be a sample)
    sc = scenario({"model": "plate", "options": {"size_m": [200, 200]}},
                  {"position_m": [20, 0, 0], "euler_deg": [0, 0, 50]}, duration_s=1.0,
                  noise=[{"name": "range_quantisation", "options": {"step_m": q}}])
    cloud = Simulation(sc).run_frame(0)
    steps = cloud["range"] / q
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    err = cloud["range"] - cloud["range_true"]
    assert np.abs(err).max() <= q / 2 + 1e-12
    distinct = np.unique(cloud["range_true"], return_index=True)[1]
    assert len(distinct) > 5000
    _mean_ok(err[distinct], 0.0, q / math.sqrt(12))
    _std_ok(err[distinct], q / math.sqrt(12))


def test_chain_applies_in_order():
    chain = [{"name": "range_systematic", "options": {"bias_m": 0.013}},
             {"name": "range_quantisation", "options": {"step_m": 0.01}}]
    cloud = _run(noise=chain)
    np.testing.assert_allclose(cloud["range"],
                               np.round((cloud["range_true"] + 0.013) / 0.01) * 0.01, atol=1e-12)


# ---- outliers and false alarms ------------------------------------------------------------------
def test_uniform_outliers_rate_and_spread():
    p = 0.1
    cloud = _run(noise=[{"name": "outliers", "options": {"probability": p, "min_m": 5.0,
                                                         "max_m": 105.0}}])
    out = cloud["range"] != cloud["range_true"]
    count = out.sum()
    assert abs(count - p * N_RAYS) < 4 * math.sqrt(N_RAYS * p * (1 - p))
    ranges = cloud["range"][out]
    assert ranges.min() >= 5.0 and ranges.max() <= 105.0
    spread = 100.0 / math.sqrt(12)
    _mean_ok(ranges, 55.0, spread)
    _std_ok(ranges, spread, rtol=0.08)


def test_gaussian_outliers_spread():
    cloud = _run(noise=[{"name": "outliers", "options": {"probability": 0.2,
                                                         "distribution": "gaussian",
                                                         "sigma_m": 3.0}}])
    err = (cloud["range"] - cloud["range_true"])[cloud["range"] != cloud["range_true"]]
    assert abs(len(err) - 0.2 * N_RAYS) < 4 * math.sqrt(N_RAYS * 0.2 * 0.8)
    _mean_ok(err, 0.0, 3.0)
    _std_ok(err, 3.0, rtol=0.08)


@pytest.mark.parametrize("options", [{"probability": 0.05}, {"rate_hz": 500.0}])
def test_false_alarms_rate_and_ranges_with_nothing_in_view(options):
    cloud = _run(-20.0, noise=[{"name": "false_alarms", "options": options}])  # plate behind
    p = 0.05  # 500 Hz at 10,000 pulses/s
    assert abs(len(cloud) - p * N_RAYS) < 4 * math.sqrt(N_RAYS * p * (1 - p))
    lo, hi = 0.1, 500.0  # the helper datasheet's range gate
    assert cloud["range"].min() >= lo and cloud["range"].max() <= hi
    spread = (hi - lo) / math.sqrt(12)
    _mean_ok(cloud["range"], (lo + hi) / 2, spread)
    assert set(cloud.part_labels()) == {"noise/false_alarm"}
    assert np.all(cloud["target"] == -1) and np.all(cloud["face_index"] == -1)
    assert np.all(np.isnan(cloud["range_true"])) and np.all(np.isnan(cloud["x_true"]))
    # along the pulse's direction
    direction = _unit(cloud.xyz)
    np.testing.assert_allclose(np.arctan2(direction[:, 1], direction[:, 0]), cloud["azimuth"],
                               atol=1e-9)


def test_false_alarms_compete_with_real_returns_by_return_mode():
    noise = [{"name": "false_alarms", "options": {"probability": 0.3}}]
    first = _run(100.0, noise=noise, returns={"mode": "first"})
    strongest = _run(100.0, noise=noise, returns={"mode": "strongest"})
    alarm = first["part"] == first.frame.part_names.index("noise/false_alarm")
    # a first-return sensor reports the alarm exactly when it comes before the plate
    assert np.all(first["range"][alarm] < 100.0 / np.cos(np.radians(20.5)))
    assert 0.3 * 0.15 < alarm.mean() < 0.3 * 0.25  # 100 m of the 500 m window, p = 0.3
    assert len(first) == N_RAYS
    # without a calibrated link budget an alarm has no signal: the plate is stronger
    assert len(strongest) == N_RAYS
    assert not np.any(strongest["part"] == strongest.frame.part_names.index("noise/false_alarm"))
    dual = _run(100.0, noise=noise, returns={"mode": "dual", "dual": "first_last"})
    assert (dual["number_of_returns"] == 2).mean() == pytest.approx(0.3 * 2 / 1.3, abs=0.05)


# ---- off means off --------------------------------------------------------------------------
@pytest.mark.parametrize("model, options", [
    ("range", {"sigma_m": 0.0}),
    ("angular", {"sigma_deg": 0.0}),
    ("angular_point", {"sigma_deg": 0.0}),
    ("range_growing", {"sigma_m": 0.0}),
    ("range_systematic", {"bias_m": 0.0, "scale": 0.0}),
    ("range_quantisation", {"step_m": 0.0}),
    ("outliers", {"probability": 0.0}),
    ("false_alarms", {"probability": 0.0}),
])
def test_switched_off_model_is_bit_identical_to_the_noiseless_run(noiseless, model, options):
    cloud = _run(noise=[{"name": model, "options": options}])
    for name in noiseless.columns:
        assert cloud[name].tobytes() == noiseless[name].tobytes(), (model, name)


@pytest.mark.parametrize("noise", [
    [{"name": "outliers", "options": {"probability": 0.3}}],
    [{"name": "false_alarms", "options": {"probability": 0.3}},
     {"name": "range_growing", "options": {"sigma_m": 0.02}}],
])
def test_noise_is_independent_of_chunking_and_threads(monkeypatch, noise):
    import lidarsim_core.pipeline.simulation as pipeline_module

    reference = _run(noise=noise, duration_s=0.2)
    monkeypatch.setattr(pipeline_module, "PIECE_RAYS", 301)
    monkeypatch.setenv("LIDARSIM_THREADS", "2")
    sim = Simulation(_plate(noise=noise, duration_s=0.2))
    other = sim.run_frame(0, chunk_rays=555)
    for name in reference.columns:
        np.testing.assert_array_equal(reference[name], other[name], err_msg=name)
