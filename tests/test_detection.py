"""The link-budget detection model: calibration on the datasheet's range-at-reflectivity
figures, detection probability against range and incidence, the blind zone and range limit,
undetected returns kept for analysis, and reproducibility."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import datasheet, scenario
from scipy.special import ndtr

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.instrument.linkbudget import LinkBudget
from lidarsim_core.pipeline import Simulation
from lidarsim_core.plugins.resolve import get_sensor
from lidarsim_core.scenario.datasheet import RangeAtReflectivity

#: Livox MID-70 datasheet: 90 m at 10 %, 130 m at 20 %, 260 m at 80 % reflectivity.
MID70 = [(0.10, 90.0), (0.20, 130.0), (0.80, 260.0)]
PLATE = {"model": "plate", "options": {"size_m": [60, 60]}}


def _sheet(**overrides):
    """A narrow (2°) scanner with the MID-70's detection figures, 10 kHz."""
    base = dict(fov_h_deg=2.0, fov_v_deg=2.0, range_min_m=0.05, range_max_m=130.0,
                range_at_reflectivity=[{"reflectivity": r, "range_m": d} for r, d in MID70])
    base.update(overrides)
    return datasheet(**base)


def _plate_scenario(range_m, rho, *, angle_deg=0.0, detection=None, sheet=None, **extra):
    sc = scenario(PLATE, {"position_m": [range_m, 0, 0], "euler_deg": [0, 0, angle_deg]},
                  sheet=sheet or _sheet(), **extra)
    data = sc.model_dump()
    data["sensor"]["detection"] = {"range_max_m": 1000.0} if detection is None else detection
    data["targets"][0]["materials"] = {"plate": {"diffuse_reflectivity": rho}}
    from lidarsim_core.scenario import scenario_from_dict

    return scenario_from_dict(data)


def test_calibration_reproduces_the_mid70_datasheet_ranges():
    link = LinkBudget.fit([RangeAtReflectivity(reflectivity=r, range_m=d) for r, d in MID70])
    assert 1.8 < link.exponent < 2.1  # close to the inverse-square law of an extended target
    for rho, rng in MID70:
        assert link.range_at(rho) == pytest.approx(rng, rel=0.05)
        assert link.signal(rho, link.range_at(rho)) == pytest.approx(1.0)
        assert link.detection_probability(link.signal(rho, link.range_at(rho))) == \
            pytest.approx(0.5)


def test_one_figure_gives_the_inverse_square_law():
    link = LinkBudget.fit([RangeAtReflectivity(reflectivity=0.1, range_m=100.0)])
    assert link.exponent == 2.0
    assert link.range_at(0.1) == pytest.approx(100.0)
    assert link.range_at(0.4) == pytest.approx(200.0)  # R ∝ √ρ


@pytest.mark.parametrize("rho, datasheet_range", MID70)
def test_detection_probability_crosses_half_at_the_datasheet_range(rho, datasheet_range):
    factors = np.array([0.85, 0.95, 1.0, 1.05, 1.15])
    fractions = []
    for f in factors:
        cloud = Simulation(_plate_scenario(datasheet_range * f, rho)).run_frame(0)
        assert cloud.frame.rays_emitted == 2000
        fractions.append(len(cloud) / cloud.frame.rays_emitted)
    fractions = np.array(fractions)
    assert np.all(np.diff(fractions) < 0.05)  # falls with range (within sampling noise)
    assert fractions[0] > 0.75 and fractions[-1] < 0.25
    i = int(np.flatnonzero(fractions < 0.5)[0])
    crossing = np.interp(0.5, fractions[[i, i - 1]], factors[[i, i - 1]]) * datasheet_range
    assert crossing == pytest.approx(datasheet_range, rel=0.05)


@pytest.mark.parametrize("material", [{"diffuse_reflectivity": 0.8},
                                      {"diffuse_reflectivity": 0.3, "specular_reflectance": 0.5,
                                       "specular_slope_deg": 25.0}])
def test_detection_and_intensity_fall_with_incidence_as_the_formula(material):
    """Tilted plates; every hit kept (detected or not) with its incidence and range, so the
    detection count is tested against Σ P_d = Σ Φ(TNR (C ρ_eff(θ)/R^n − 1))."""
    from lidarsim_core.scene.materials import Material

    mat = Material(**material)
    sim0 = Simulation(_plate_scenario(140.0, 0.8))
    link = sim0.link
    # range where a face-on hit gives S = 1.4
    rng = (link.constant * mat.effective_reflectivity(np.array([1.0]))[0] / 1.4) \
        ** (1 / link.exponent)
    previous = 1.1
    for angle in (0.0, 30.0, 50.0, 65.0):
        sc = _plate_scenario(rng, 0.0, angle_deg=angle,
                             detection={"keep_undetected": True, "range_max_m": 1000.0})
        data = sc.model_dump()
        data["targets"][0]["materials"] = {"plate": material}
        from lidarsim_core.scenario import scenario_from_dict

        cloud = Simulation(scenario_from_dict(data)).run_frame(0)
        assert len(cloud) == cloud.frame.rays_emitted  # every pulse hits the plate
        theta = cloud["incidence_angle"]
        assert np.all(np.abs(np.degrees(theta) - angle) < 1.5)
        rho_eff = mat.effective_reflectivity(np.cos(theta))
        np.testing.assert_allclose(cloud["intensity"], rho_eff, rtol=1e-5)
        p = ndtr(link.threshold_to_noise
                 * (link.constant * rho_eff / cloud["range_true"] ** link.exponent - 1))
        detected = cloud["detected"].astype(bool)
        sigma = math.sqrt(np.sum(p * (1 - p))) + 1e-9
        assert abs(detected.sum() - p.sum()) < 4 * sigma + 1, angle
        fraction = detected.mean()
        assert fraction < previous + 0.03  # falls with incidence
        previous = fraction
    assert previous < 0.5


def test_undetected_returns_are_flagged_noiseless_and_unnumbered():
    sc = _plate_scenario(130.0, 0.2, detection={"keep_undetected": True},
                         noise=[{"name": "range"}])
    cloud = Simulation(sc).run_frame(0)
    assert len(cloud) == cloud.frame.rays_emitted
    missed = cloud["detected"] == 0
    assert 0.2 < missed.mean() < 0.8
    assert np.all(cloud["return_number"][missed] == 0)
    assert np.all(cloud["number_of_returns"][missed] == 0)
    assert np.all(cloud["range"][missed] == cloud["range_true"][missed])
    assert np.all(cloud["return_number"][~missed] == 1)
    assert np.all(cloud["range"][~missed] != cloud["range_true"][~missed])
    # the same run without keeping them reports exactly the detected ones, bit for bit
    plain = Simulation(_plate_scenario(130.0, 0.2, detection={},
                                       noise=[{"name": "range"}])).run_frame(0)
    np.testing.assert_array_equal(plain["ray_index"], cloud["ray_index"][~missed])
    np.testing.assert_array_equal(plain["range"], cloud["range"][~missed])


def test_blind_zone_and_range_limit():
    near = Simulation(_plate_scenario(0.5, 0.8, sheet=_sheet(range_min_m=1.0))).run_frame(0)
    assert len(near) == 0
    kept = Simulation(_plate_scenario(0.5, 0.8, sheet=_sheet(range_min_m=1.0),
                                      detection={"keep_undetected": True})).run_frame(0)
    assert len(kept) == kept.frame.rays_emitted and not kept["detected"].any()
    # default limit with detection: the longest datasheet figure (260 m), not range_max_m
    sim = Simulation(_plate_scenario(200.0, 0.8, detection={}))
    assert sim.range_limit == 260.0
    assert len(sim.run_frame(0)) > 0.9 * 2000
    beyond = Simulation(_plate_scenario(200.0, 0.8, detection={"range_max_m": 150.0}))
    assert len(beyond.run_frame(0)) == 0


def test_strong_returns_are_all_detected_with_unchanged_noise():
    """Detection draws come from their own stream: where everything is detected, the cloud is
    the one without the detection model, bit for bit (apart from the new columns' meaning)."""
    noise = [{"name": "angular"}, {"name": "range"}]
    with_det = Simulation(_plate_scenario(10.0, 0.8, detection={}, noise=noise)).run_frame(0)
    data = _plate_scenario(10.0, 0.8, noise=noise).model_dump()
    data["sensor"]["detection"] = None
    from lidarsim_core.scenario import scenario_from_dict

    without = Simulation(scenario_from_dict(data)).run_frame(0)
    assert len(with_det) == len(without) == 2000
    for name in without.columns:
        np.testing.assert_array_equal(with_det[name], without[name], err_msg=name)


def test_detection_is_independent_of_chunking_and_threads(monkeypatch):
    import lidarsim_core.pipeline.simulation as pipeline_module

    sc = _plate_scenario(130.0, 0.2, detection={})
    reference = Simulation(sc).run_frame(0)
    monkeypatch.setattr(pipeline_module, "PIECE_RAYS", 333)
    monkeypatch.setenv("LIDARSIM_THREADS", "2")
    other = Simulation(sc).run_frame(0, chunk_rays=777)
    for name in reference.columns:
        np.testing.assert_array_equal(reference[name], other[name], err_msg=name)


def test_link_budget_is_in_the_frame_metadata():
    cloud = Simulation(_plate_scenario(50.0, 0.2, detection={})).run_frame(0)
    info = cloud.frame.extra["measurement"]["link_budget"]
    assert info["exponent"] == pytest.approx(1.9657, abs=1e-3)
    assert info["range_limit_m"] == 260.0


def test_detection_without_calibration_figures_is_a_config_error():
    sheet = _sheet(range_at_reflectivity=[])
    with pytest.raises(ConfigError) as err:
        Simulation(_plate_scenario(50.0, 0.2, detection={}, sheet=sheet))
    assert err.value.field == "sensor.detection.range_at_reflectivity"
    override = {"range_at_reflectivity": [{"reflectivity": 0.1, "range_m": 50.0}]}
    assert Simulation(_plate_scenario(50.0, 0.2, detection=override, sheet=sheet)).link


def test_catalogue_mid70_calibrates_within_five_percent():
    sheet = get_sensor("livox-mid70")
    link = LinkBudget.fit(sheet.range_at_reflectivity)
    for fig in sheet.range_at_reflectivity:
        assert link.range_at(fig.reflectivity) == pytest.approx(fig.range_m, rel=0.05)


def test_unknown_detection_key_is_rejected():
    data = _plate_scenario(50.0, 0.2).model_dump()
    data["sensor"]["detection"] = {"treshold": 3}
    from lidarsim_core.scenario import scenario_from_dict

    with pytest.raises(ConfigError) as err:
        scenario_from_dict(data)
    assert err.value.field == "sensor.detection.treshold"


def test_config_hash_changes_only_when_realism_is_set():
    plain = scenario(PLATE, {"position_m": [50, 0, 0]})
    data = plain.model_dump()
    from lidarsim_core.scenario import scenario_from_dict

    assert scenario_from_dict(data).config_hash() == plain.config_hash()
    data["sensor"]["detection"] = {}
    with_detection = scenario_from_dict(data)
    assert with_detection.config_hash() != plain.config_hash()
    data["sensor"]["detection"] = {"threshold_to_noise": 5.0}
    assert scenario_from_dict(data).config_hash() != with_detection.config_hash()
    data["sensor"]["detection"] = None
    data["targets"][0]["materials"] = {"plate": "white_paint"}
    assert scenario_from_dict(data).config_hash() != plain.config_hash()
