"""Beam divergence: the sub-ray footprint, returns formed by range resolution (mixed points at
an edge, two returns across a step), the return modes, reproducibility, and the cost."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import datasheet, scenario

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.instrument.beam import SubRays
from lidarsim_core.instrument.returns import _first_largest, select_returns
from lidarsim_core.pipeline import Simulation
from lidarsim_core.scenario import scenario_from_dict

FRONT_M = 30.0
#: Vertical footprint half-height at 30 m reached by the outermost of 32 sub-rays (0.28° 1/e²
#: full angle: σ = 0.07°, outermost sub-ray at 2.8σ), with margin.
EDGE_BAND_M = 0.12


def _edge_scene(gap_m: float, *, mode: str = "strongest", front_rho: float = 0.5,
                back_rho: float = 0.5, noise=(), sub_rays: int = 32, **returns):
    """A plate whose top edge lies on the boresight plane (z = 0) at 30 m, in front of a wide
    background plate ``gap_m`` farther; a 2° scanner with the MID-70's beam."""
    sheet = datasheet(fov_h_deg=2.0, fov_v_deg=2.0, range_min_m=0.05,
                      beam_divergence_deg=[0.03, 0.28], range_resolution_m=0.6)
    data = scenario({"model": "plate", "options": {"size_m": [20, 20]}},
                    {"position_m": [FRONT_M, 0, -10]}, sheet=sheet, noise=list(noise)).model_dump()
    data["targets"].append({"name": "back", "mesh": {"model": "plate",
                                                     "options": {"size_m": [40, 40]}},
                            "pose": {"position_m": [FRONT_M + gap_m, 0, 0]},
                            "materials": {"plate": {"diffuse_reflectivity": back_rho}}})
    data["targets"][0]["materials"] = {"plate": {"diffuse_reflectivity": front_rho}}
    data["sensor"]["beam"] = {"sub_rays": sub_rays}
    data["sensor"]["returns"] = {"mode": mode, **returns}
    return scenario_from_dict(data)


# ---- the footprint ----------------------------------------------------------------------------
def test_gaussian_sub_rays_have_the_datasheet_divergence():
    div = (math.radians(0.03), math.radians(0.28))
    rays = SubRays.layout(64, div)
    assert rays.weights.sum() == pytest.approx(1.0)
    # 1/e² full angle = 4σ of the intensity profile, per axis
    std = np.sqrt(np.sum(rays.weights[:, None] * rays.angles ** 2, axis=0))
    np.testing.assert_allclose(std, np.array(div) / 4, rtol=0.1)
    np.testing.assert_allclose(np.sum(rays.weights[:, None] * rays.angles, axis=0), 0,
                               atol=0.05 * div[1] / 4)
    np.testing.assert_allclose(np.linalg.norm(rays.coefficients, axis=1), 1.0, atol=1e-15)


def test_uniform_sub_rays_fill_the_ellipse():
    div = (math.radians(0.2), math.radians(0.4))
    rays = SubRays.layout(50, div, "uniform")
    r2 = (rays.angles[:, 0] / (div[0] / 2)) ** 2 + (rays.angles[:, 1] / (div[1] / 2)) ** 2
    assert r2.max() <= 1.0 and r2.max() > 0.95
    # uniform over the disc: the mean of r² is 1/2
    assert np.mean(r2) == pytest.approx(0.5, abs=0.03)


def test_one_sub_ray_is_the_central_ray():
    rays = SubRays.layout(1, (0.01, 0.01))
    np.testing.assert_array_equal(rays.coefficients, [[1.0, 0.0, 0.0]])


def test_footprint_is_horizontal_along_y_and_vertical_along_z():
    rays = SubRays.layout(32, (math.radians(0.03), math.radians(0.28)))
    d = np.array([[1.0, 0, 0]])
    u, v = np.array([[0, 1.0, 0]]), np.array([[0, 0, 1.0]])
    dirs = rays.directions(d, u, v)
    spread = np.degrees(np.ptp(dirs, axis=0))
    assert spread[2] > 5 * spread[1]  # the MID-70 beam is tall and narrow
    np.testing.assert_allclose(dirs[rays.count // 2], rays.direction_of(
        np.array([rays.count // 2]), d, u, v)[0])


# ---- mixed points and two returns --------------------------------------------------------------
def test_edge_within_range_resolution_gives_mixed_points():
    cloud = Simulation(_edge_scene(0.3)).run_frame(0)
    x, z = cloud["x"], cloud["z"]
    assert np.all(cloud["number_of_returns"] == 1)
    mixed = (x > FRONT_M + 0.02) & (x < FRONT_M + 0.28)
    assert mixed.sum() >= 10
    assert np.all(np.abs(z[mixed]) < EDGE_BAND_M)  # only where the footprint straddles
    far = np.abs(z) > EDGE_BAND_M
    on_front, on_back = far & (z < 0), far & (z > 0)
    np.testing.assert_allclose(x[on_front], FRONT_M, atol=1e-3)
    np.testing.assert_allclose(x[on_back], FRONT_M + 0.3, atol=1e-3)
    # ground truth of a mixed point is a real surface point of its strongest sub-ray
    truth = cloud["x_true"][mixed]
    assert np.all(np.isclose(truth, FRONT_M, atol=1e-3) | np.isclose(truth, FRONT_M + 0.3,
                                                                    atol=1e-3))
    assert np.all(cloud["range"][mixed] != cloud["range_true"][mixed])


def test_step_beyond_range_resolution_gives_two_returns():
    cloud = Simulation(_edge_scene(2.0, mode="dual")).run_frame(0)
    x, z = cloud["x"], cloud["z"]
    assert not np.any((x > FRONT_M + 0.05) & (x < FRONT_M + 1.95))  # no mixed points
    two = cloud["number_of_returns"] == 2
    assert two.sum() >= 20 and np.all(np.abs(z[two]) < EDGE_BAND_M)
    first = two & (cloud["return_number"] == 1)
    second = two & (cloud["return_number"] == 2)
    np.testing.assert_array_equal(cloud["ray_index"][first], cloud["ray_index"][second])
    np.testing.assert_allclose(x[first], FRONT_M, atol=1e-3)
    np.testing.assert_allclose(x[second], FRONT_M + 2.0, atol=1e-3)
    assert cloud["target"][first].tolist() == [0] * first.sum()
    assert cloud["target"][second].tolist() == [1] * second.sum()
    # the straddling pulses share the energy: each return is fainter than a full hit
    assert np.all(cloud["intensity"][two] < 0.5 + 1e-6)


@pytest.mark.parametrize("mode, expected_x", [("first", FRONT_M), ("last", FRONT_M + 2.0)])
def test_first_and_last_modes(mode, expected_x):
    cloud = Simulation(_edge_scene(2.0, mode=mode)).run_frame(0)
    both = Simulation(_edge_scene(2.0, mode="multi", max_returns=2)).run_frame(0)
    straddling = np.unique(both["ray_index"][both["number_of_returns"] == 2])
    sel = np.isin(cloud["ray_index"], straddling)
    assert sel.sum() == len(straddling) and np.all(cloud["number_of_returns"] == 1)
    np.testing.assert_allclose(cloud["x"][sel], expected_x, atol=1e-3)


def test_strongest_mode_reports_the_return_with_the_largest_signal():
    kwargs = dict(front_rho=0.05, back_rho=0.8)
    sim = Simulation(_edge_scene(2.0, mode="multi", max_returns=2, **kwargs))
    both = sim.run_frame(0)
    strongest = Simulation(_edge_scene(2.0, mode="strongest", **kwargs)).run_frame(0)
    # signal ∝ intensity / R^n (the apparent reflectivity is range-compensated)
    signal = both["intensity"].astype(np.float64) / both["range"] ** 2
    for ray in np.unique(both["ray_index"][both["number_of_returns"] == 2]):
        rows = np.flatnonzero(both["ray_index"] == ray)
        pick = rows[np.argmax(signal[rows])]
        got = np.flatnonzero(strongest["ray_index"] == ray)
        assert len(got) == 1 and strongest["x"][got[0]] == both["x"][pick]


def test_select_returns_modes_on_crafted_pulses():
    # pulse 0: three returns, strongest in the middle; pulse 1: strongest is the last;
    # pulse 2: strongest is the first; pulse 3: one return
    pulse = np.array([0, 0, 0, 1, 1, 2, 2, 3])
    signal = np.array([1.0, 5.0, 2.0, 1.0, 4.0, 9.0, 3.0, 1.0])

    def picked(mode, **kw):
        keep, number, count = select_returns(pulse, signal, mode, **kw)
        return np.flatnonzero(keep).tolist(), number[keep].tolist(), count[keep].tolist()

    assert picked("first")[0] == [0, 3, 5, 7]
    assert picked("last")[0] == [2, 4, 6, 7]
    assert picked("strongest")[0] == [1, 4, 5, 7]
    # Velodyne dual: strongest + last; second strongest when the strongest is the last
    assert picked("dual", dual="strongest_last") == ([1, 2, 3, 4, 5, 6, 7],
                                                     [1, 2, 1, 2, 1, 2, 1],
                                                     [2, 2, 2, 2, 2, 2, 1])
    # first + strongest; second strongest when the strongest is the first
    assert picked("dual", dual="first_strongest")[0] == [0, 1, 3, 4, 5, 6, 7]
    assert picked("dual", dual="first_last")[0] == [0, 2, 3, 4, 5, 6, 7]
    assert picked("multi", max_returns=2)[0] == [0, 1, 3, 4, 5, 6, 7]
    assert picked("multi", max_returns=3)[0] == list(range(8))


def test_strongest_sub_ray_of_each_return_is_the_sorts_choice():
    """The strongest sub-ray of each return, found in linear time, is the row a stable sort
    by group and falling power picks: the first of equal powers, NaN as smallest, a group of
    NaN its first row, -0.0 equal to 0.0, infinities (300 random cases)."""
    rng = np.random.default_rng(5)
    for case in range(300):
        n = int(rng.integers(1, 400))
        first = rng.random(n) < 0.3
        first[0] = True
        starts, group = np.flatnonzero(first), np.cumsum(first) - 1
        power = rng.random(n) if case % 2 else \
            rng.choice([0.0, -0.0, 0.5, 1.0, 2.0, np.nan, np.inf], n)
        np.testing.assert_array_equal(_first_largest(power, starts, group),
                                      np.lexsort((-power, group))[starts], err_msg=str(case))


def test_second_returns_get_independent_range_noise():
    noise = [{"name": "range", "options": {"sigma_m": 0.05}}]
    cloud = Simulation(_edge_scene(2.0, mode="dual", noise=noise)).run_frame(0)
    two = cloud["number_of_returns"] == 2
    err = cloud["range"] - cloud["range_true"]
    # mixed within a return is absent here (each return is one flat surface), so the error
    # is the noise; the two returns of a pulse must not share it
    e1 = err[two & (cloud["return_number"] == 1)]
    e2 = err[two & (cloud["return_number"] == 2)]
    assert len(e1) == len(e2) >= 20
    assert not np.any(np.isclose(e1, e2, rtol=0, atol=1e-12))


def test_divergence_is_independent_of_chunking_and_threads(monkeypatch):
    import lidarsim_core.pipeline.simulation as pipeline_module

    sc = _edge_scene(0.3, noise=[{"name": "angular"}, {"name": "range"}])
    reference = Simulation(sc).run_frame(0)
    monkeypatch.setattr(pipeline_module, "PIECE_RAYS", 1000)  # 31 pulses per piece
    monkeypatch.setenv("LIDARSIM_THREADS", "2")
    other = Simulation(sc).run_frame(0, chunk_rays=333)
    for name in reference.columns:
        np.testing.assert_array_equal(reference[name], other[name], err_msg=name)


def test_missing_divergence_or_resolution_is_a_config_error():
    sheet = datasheet(range_resolution_m=0.5)
    data = scenario({"model": "plate"}, {"position_m": [5, 0, 0]}, sheet=sheet).model_dump()
    data["sensor"]["beam"] = {"sub_rays": 8}
    with pytest.raises(ConfigError) as err:
        Simulation(scenario_from_dict(data))
    assert err.value.field == "sensor.beam.divergence_deg"
    data["sensor"]["beam"]["divergence_deg"] = [0.1, 0.1]
    data["sensor"]["datasheet"] = datasheet()
    with pytest.raises(ConfigError) as err:
        Simulation(scenario_from_dict(data))
    assert err.value.field == "sensor.returns.range_resolution_m"
    data["sensor"]["returns"] = {"range_resolution_m": 0.5}
    assert Simulation(scenario_from_dict(data)).rays_per_pulse == 8


def test_divergence_costs_at_most_one_and_a_half_independent_rays():
    from lidarsim_core.bench import bench_divergence

    result = bench_divergence("coarse", duration_s=0.05, sub_rays=16, rounds=3)
    assert result["pulses"] * 16 == result["single_rays"]
    assert result["ratio"] <= 1.5, result
