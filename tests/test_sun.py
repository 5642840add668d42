"""The Sun: a plate half in the shadow of another has false alarms only where it is sunlit, at
the rate the receiver model predicts; pulses within the blinding angle return nothing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import datasheet
from scipy.special import ndtr
from scipy.stats import binomtest

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.pipeline import Simulation
from lidarsim_core.pipeline.stages.sun import solar_spectral_irradiance
from lidarsim_core.scenario import scenario_from_dict

RHO = 0.8
SUN = np.array([-1.0, 0.0, 1.0]) / math.sqrt(2.0)  # up and behind the sensor: lights the plate


def _scene(sun=None, *, occluder=True, duration_s=0.5, noise=()):
    sheet = datasheet(fov_h_deg=10.0, fov_v_deg=10.0, range_min_m=0.5, range_max_m=100.0,
                      range_resolution_m=0.5, wavelength_nm=905.0,
                      range_at_reflectivity=[{"reflectivity": 0.1, "range_m": 90.0}])
    targets = [{"name": "plate", "mesh": {"model": "plate", "options": {"size_m": [4, 4]}},
                "pose": {"position_m": [20.0, 0.0, 0.0]},
                "materials": {"plate": {"diffuse_reflectivity": RHO}}}]
    if occluder:  # horizontal, 5 m above, out of the sensor's view: shades z > 0 of the plate
        targets.append({"name": "shade", "mesh": {"model": "plate",
                                                  "options": {"size_m": [10, 5]}},
                        "pose": {"position_m": [17.5, 0.0, 5.0], "euler_deg": [0, 90, 0]}})
    data = {"seed": 5, "scan": {"duration_s": duration_s}, "backend": "numpy",
            "noise": list(noise), "targets": targets,
            "sensor": {"datasheet": sheet, "detection": {"range_max_m": 100.0},
                       "returns": {"mode": "multi", "max_returns": 2}}}
    if sun is not None:
        data["sun"] = sun
    return scenario_from_dict(data)


def test_false_alarms_only_where_sunlit_at_the_predicted_rate():
    sun = {"direction": SUN.tolist(), "noise_equivalent_irradiance_w_m2": 10.0}
    sim = Simulation(_scene(sun))
    cloud = sim.run_frame(0)
    alarm = cloud["part"] == sim.false_alarm_part
    surface = cloud["target"] == 0
    lit_pulses = set(cloud["ray_index"][surface & (cloud["z_true"] < -1e-6)].tolist())
    dark_pulses = set(cloud["ray_index"][surface & (cloud["z_true"] > 1e-6)].tolist())
    alarms = set(cloud["ray_index"][alarm].tolist())
    assert len(lit_pulses) > 1000 and len(dark_pulses) > 1000
    assert not alarms & dark_pulses  # the shadowed half is quiet
    assert alarms <= lit_pulses | set(cloud["ray_index"][surface & (np.abs(cloud["z_true"])
                                                                     <= 1e-6)].tolist())
    # the rate: receiver model, computed here from its equations
    e_lambda = solar_spectral_irradiance(905.0)
    b = RHO * math.cos(math.radians(45.0)) * e_lambda * 10.0 / 10.0
    cells = (100.0 - 0.5) / 0.5
    tnr = sim.link.threshold_to_noise

    def p_pulse(background):
        p_cell = ndtr(-tnr / math.sqrt(1.0 + background))
        return 1.0 - (1.0 - p_cell) ** cells

    expected = p_pulse(b) - p_pulse(0.0)
    assert 0.02 < expected < 0.5
    hits = len(alarms & lit_pulses)
    assert binomtest(hits, len(lit_pulses), expected).pvalue > 1e-4
    # alarms lie uniformly in the range gate (mean of U[0.5, 100] = 50.25 m, σ/√n)
    ranges = cloud["range"][alarm]
    assert abs(ranges.mean() - 50.25) < 5 * (99.5 / math.sqrt(12)) / math.sqrt(len(ranges))


def test_no_sun_no_solar_false_alarms_and_no_shadow_change():
    plain = Simulation(_scene()).run_frame(0)
    assert "noise/false_alarm" not in plain.frame.part_names
    # the plate faces away from a Sun behind it: not lit, no alarms
    away = Simulation(_scene({"direction": [1.0, 0.0, 0.3]})).run_frame(0)
    assert not (away["target"] == -1).any()
    assert np.array_equal(away["ray_index"], plain["ray_index"])


def test_pulses_within_the_blinding_angle_return_nothing():
    plain = Simulation(_scene(occluder=False)).run_frame(0)
    toward = np.array([1.0, 0.02, 0.03])
    toward /= np.linalg.norm(toward)
    sun = {"direction": toward.tolist(), "blinding_angle_deg": 1.5}
    sim = Simulation(_scene(sun, occluder=False))
    cloud = sim.run_frame(0)
    az, el = plain["azimuth"], plain["elevation"]
    d = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)
    angle = np.degrees(np.arccos(np.clip(d @ toward, -1, 1)))
    inside = set(plain["ray_index"][angle < 1.5].tolist())
    assert len(inside) > 50
    assert not inside & set(cloud["ray_index"].tolist())
    outside = set(plain["ray_index"][angle >= 1.5].tolist())
    assert outside == set(cloud["ray_index"][cloud["target"] == 0].tolist())


def test_default_blinding_angle_and_irradiance():
    sim = Simulation(_scene({"direction": SUN.tolist()}))
    info = sim.measurement_info()["measurement"]["sun"]
    assert info["blinding_angle_deg"] == pytest.approx(0.2666 + 0.05)
    # a 5772 K blackbody at the solar constant: ~0.9 W m⁻² nm⁻¹ at 905 nm (AM0 ≈ 0.9)
    assert 0.85 < info["spectral_irradiance_w_m2_nm"] < 0.95


def test_sun_needs_detection_and_a_direction():
    data = _scene({"direction": SUN.tolist()}).model_dump()
    data["sensor"]["detection"] = None
    with pytest.raises(ConfigError, match="sun"):
        Simulation(scenario_from_dict(data))
    data = _scene().model_dump()
    data["sun"] = {"direction": [0, 0, 0]}
    with pytest.raises(ConfigError, match="sun.direction"):
        scenario_from_dict(data)
    data["sun"] = {"direction": [1, 0, 0], "orbit": {"epoch": EQUINOX, "altitude_km": 500,
                                                     "inclination_deg": 51.6}}
    with pytest.raises(ConfigError, match="exactly one of direction or orbit"):
        scenario_from_dict(data)


def test_sun_is_byte_identical_across_chunks_and_threads(monkeypatch):
    sc = _scene({"direction": SUN.tolist()}, duration_s=0.2,
                noise=[{"name": "angular"}, {"name": "range"}])
    ref = Simulation(sc).run_frame(0)
    assert (ref["target"] == -1).sum() > 20
    for chunk, threads in ((131, "1"), (977, "2")):
        monkeypatch.setenv("LIDARSIM_THREADS", threads)
        other = Simulation(sc).run_frame(0, chunk_rays=chunk)
        for key in ref.columns:
            assert np.array_equal(ref[key], other[key], equal_nan=True), key


def test_filter_width_from_the_datasheet():
    data = _scene({"direction": SUN.tolist()}).model_dump()
    data["sensor"]["datasheet"]["optical_filter_nm"] = 20.0
    info = Simulation(scenario_from_dict(data)).measurement_info()["measurement"]["sun"]
    assert info["filter_width_nm"] == 20.0
    assert info["white_background"] == pytest.approx(2 * solar_spectral_irradiance(905.0))


# published instants (UTC): March equinox 2024-03-20 03:06, June solstice 2024-06-20 20:51
EQUINOX = "2024-03-20T03:06:00Z"


def test_solar_ephemeris_at_the_equinox_and_solstice():
    from datetime import datetime

    from lidarsim_core.pipeline.stages.sun import sun_direction_eci

    def at(iso):
        return sun_direction_eci(np.array([datetime.fromisoformat(iso).timestamp()]))[0]

    assert math.degrees(math.acos(at("2024-03-20T03:06:00+00:00")[0])) < 0.05
    eps = math.radians(23.439)
    solstice = np.array([0.0, math.cos(eps), math.sin(eps)])
    assert math.degrees(math.acos(at("2024-06-20T20:51:00+00:00") @ solstice)) < 0.05


@pytest.mark.parametrize("u0, expected, eclipse", [
    (0.0, [1.0, 0.0, 0.0], False),     # noon: the Sun at the zenith (+R-bar)
    (90.0, [0.0, -1.0, 0.0], False),   # dawn side: the Sun behind, along −V-bar
    (180.0, [-1.0, 0.0, 0.0], True),   # midnight: behind the Earth
])
def test_sun_in_the_lvlh_frame_of_an_equatorial_orbit(u0, expected, eclipse):
    from lidarsim_core.pipeline.stages.sun import sun_in_lvlh
    from lidarsim_core.scenario.sun import SunOrbit

    orbit = SunOrbit(epoch=EQUINOX, altitude_km=780, inclination_deg=0.0,
                     argument_of_latitude_deg=u0)
    direction, shadow = sun_in_lvlh(orbit, np.array([0.0]))
    assert math.degrees(math.acos(direction[0] @ np.array(expected))) < 0.05
    assert bool(shadow[0]) == eclipse
    # a quarter orbit later the frame has turned by 90°
    n = math.sqrt(3.986004418e14 / (6_378_137.0 + 780e3) ** 3)
    later, _ = sun_in_lvlh(orbit, np.array([0.5 * math.pi / n]))
    turned = np.array([expected[1], -expected[0], 0.0])  # rotate (x, y) by −90° about z
    assert math.degrees(math.acos(later[0] @ turned)) < 0.1


def test_sun_from_an_orbit_blinds_at_noon_and_not_in_the_earths_shadow():
    plain = Simulation(_scene(occluder=False)).run_frame(0)
    orbit = {"epoch": EQUINOX, "altitude_km": 780, "inclination_deg": 0.0}
    noon = Simulation(_scene({"orbit": {**orbit, "argument_of_latitude_deg": 0.0},
                              "blinding_angle_deg": 1.5}, occluder=False)).run_frame(0)
    midnight = Simulation(_scene({"orbit": {**orbit, "argument_of_latitude_deg": 180.0},
                                  "blinding_angle_deg": 1.5}, occluder=False)).run_frame(0)
    assert 50 < len(plain) - len(noon)  # pulses near the boresight (+R-bar) are blinded
    assert np.array_equal(midnight["ray_index"], plain["ray_index"])  # eclipse: no Sun
    assert not (midnight["target"] == -1).any()


def test_background_noise_lowers_detection_where_sunlit():
    """A dark plate (S ≈ 1.3 face-on at 20 m): the shaded half is detected with
    Φ(TNR (S − 1)), the lit half with Φ(TNR (S − 1)/√(1 + B)); every hit is kept, to count
    detections against Σ P_d."""
    rho = 1.3 * 20.0 ** 2 / 81000.0  # C = 90² / 0.1, n = 2
    e_eq = 0.05
    data = _scene({"direction": SUN.tolist(), "noise_equivalent_irradiance_w_m2": e_eq}
                  ).model_dump()
    data["sensor"]["detection"] = {"range_max_m": 100.0, "keep_undetected": True}
    data["targets"][0]["materials"] = {"plate": {"diffuse_reflectivity": rho}}
    sim = Simulation(scenario_from_dict(data))
    cloud = sim.run_frame(0)
    plate = cloud["target"] == 0
    s = sim.link.signal(cloud["intensity"][plate].astype(np.float64), cloud["range_true"][plate])
    b = rho * math.cos(math.radians(45.0)) * solar_spectral_irradiance(905.0) * 10.0 / e_eq
    assert 0.5 < b < 2.0
    lit = cloud["z_true"][plate] < -1e-6
    dark = cloud["z_true"][plate] > 1e-6
    detected = cloud["detected"][plate] == 1
    tnr = sim.link.threshold_to_noise
    for half, scale in ((lit, math.sqrt(1.0 + b)), (dark, 1.0)):
        p = ndtr(tnr * (s[half] - 1.0) / scale)
        assert half.sum() > 1000
        sd = math.sqrt((p * (1 - p)).sum())
        assert abs(detected[half].sum() - p.sum()) < 4.5 * sd
    assert detected[lit].mean() < detected[dark].mean() - 0.05
