"""The Earth behind the target: pointed at the dayside the false-alarm rate is the receiver
model's (computed here from the equations of docs/realism.md and the geometry of the orbit);
at the night side or deep space it is the dark rate; a target in front of the Earth hides it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import datasheet
from scipy.special import ndtr
from scipy.stats import binomtest

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.pipeline import Simulation
from lidarsim_core.scenario.load import scenario_from_dict
from lidarsim_core.scenario.earth import EARTH_BOND_ALBEDO
from lidarsim_core.scenario.sun import SunOrbit
from lidarsim_core.pipeline.stages.sun import solar_spectral_irradiance, sun_in_lvlh

EQUINOX = "2024-03-20T03:06:00Z"  # with u0 = 0 on an equatorial orbit: noon (Sun at +R-bar)
ALTITUDE_KM = 780.0
NADIR = [0.0, 0.0, 1.0, 0.0]  # boresight (+x) turned to −x (toward the Earth)
ORBIT_NORMAL = [0.0, -math.sqrt(0.5), 0.0, math.sqrt(0.5)]  # boresight to +z (deep space)
R_MIN, R_MAX, RES = 0.5, 100.0, 0.5
TNR = 4.0


def _scene(u0_deg, pointing, *, e_eq=10.0, noise=(), fov=2.0, duration_s=0.5, plate=None,
           earth=True, sun_extra=None, sheet_extra=None):
    sheet = datasheet(fov_h_deg=fov, fov_v_deg=fov, range_min_m=R_MIN, range_max_m=R_MAX,
                      range_resolution_m=RES, wavelength_nm=905.0,
                      range_at_reflectivity=[{"reflectivity": 0.1, "range_m": 15.0}],
                      **(sheet_extra or {}))
    # without a plate the only target is far behind the sensor, out of its view
    targets = [plate or {"name": "away", "mesh": {"model": "plate", "options": {"size_m": [1, 1]}},
                         "pose": {"position_m": [0.0, 0.0, -50.0] if pointing == ORBIT_NORMAL
                                  else [50.0, 0.0, 0.0]}}]
    sun = {"orbit": {"epoch": EQUINOX, "altitude_km": ALTITUDE_KM, "inclination_deg": 0.0,
                     "argument_of_latitude_deg": u0_deg},
           "noise_equivalent_irradiance_w_m2": e_eq, **(sun_extra or {})}
    data = {"seed": 11, "scan": {"duration_s": duration_s}, "backend": "numpy",
            "noise": list(noise), "targets": targets, "sun": sun,
            "sensor": {"datasheet": sheet, "pose": {"quaternion_xyzw": pointing},
                       "detection": {"range_max_m": R_MAX, "keep_undetected": True},
                       "returns": {"mode": "multi", "max_returns": 2}}}
    if earth:
        data["earth"] = {}
    return scenario_from_dict(data)


def _p_pulse(background):
    """P(B) = 1 − (1 − Q(TNR/√(1+B)))^N, N range cells in the gate."""
    cells = (R_MAX - R_MIN) / RES
    return 1.0 - (1.0 - ndtr(-TNR / np.sqrt(1.0 + background))) ** cells


def _sun_lvlh(u0_deg):
    orbit = SunOrbit(epoch=EQUINOX, altitude_km=ALTITUDE_KM, inclination_deg=0.0,
                     argument_of_latitude_deg=u0_deg)
    return sun_in_lvlh(orbit, np.array([0.0]))[0][0]


def _pulses(sim):
    return sim.frame_rays(0)[1] - sim.frame_rays(0)[0]


def test_dayside_false_alarm_rate_equals_the_model():
    sim = Simulation(_scene(0.0, NADIR))
    cloud = sim.run_frame(0)
    pulses = _pulses(sim)
    alarms = int((cloud["part"] == sim.false_alarm_part).sum())
    assert (cloud["target"] == -1).sum() == alarms == len(cloud)  # nothing else returns
    # the ground below the 2° field of view is within 0.12° of the sub-solar point
    cos_sun = _sun_lvlh(0.0)[0]
    background = EARTH_BOND_ALBEDO * cos_sun * solar_spectral_irradiance(905.0) * 10.0 / 10.0
    expected = float(_p_pulse(background) - _p_pulse(0.0))
    assert 0.02 < expected < 0.2
    test = binomtest(alarms, pulses, expected)
    print(f"\ndayside: {alarms} false alarms in {pulses} pulses ({alarms / pulses:.4f}), "
          f"model {expected:.4f}, p = {test.pvalue:.3f}")
    assert test.pvalue > 0.01
    # and without the Earth, nothing at all
    plain = Simulation(_scene(0.0, NADIR, earth=False)).run_frame(0)
    assert len(plain) == 0


@pytest.mark.parametrize("u0, pointing, what", [(180.0, NADIR, "night side"),
                                                 (0.0, ORBIT_NORMAL, "deep space")])
def test_night_side_and_deep_space_give_the_dark_rate(u0, pointing, what):
    dark = 0.03  # the receiver's own false alarms (noise model false_alarms)
    noise = [{"name": "false_alarms", "options": {"probability": dark}}]
    sim = Simulation(_scene(u0, pointing, noise=noise, duration_s=1.0))
    cloud = sim.run_frame(0)
    pulses = _pulses(sim)
    alarms = int((cloud["part"] == sim.false_alarm_part).sum())
    test = binomtest(alarms, pulses, dark)
    print(f"\n{what}: {alarms} false alarms in {pulses} pulses, dark rate {dark}, "
          f"p = {test.pvalue:.3f}")
    assert test.pvalue > 0.01
    # exactly the draws of the run without the Earth
    plain = Simulation(_scene(u0, pointing, noise=noise, duration_s=1.0, earth=False))
    np.testing.assert_array_equal(plain.run_frame(0)["ray_index"], cloud["ray_index"])


def test_target_in_front_of_the_earth_keeps_its_returns():
    """A plate below the sensor, its visible face turned away from the Sun, covering part of
    a 10° field of view over the dayside: its returns are detected with Φ(TNR (S − 1)) (no
    background: the plate hides the Earth) and raise no false alarm; the pulses past it see
    the Earth."""
    sun = _sun_lvlh(60.0)  # 60° past noon: (0.5, −0.87, 0)
    normal = np.array([math.sqrt(0.5), math.sqrt(0.5), 0.0])
    assert normal @ sun < -0.2 and sun[0] > 0.45  # the plate's face is dark, the ground lit
    rho = 0.3
    plate = {"name": "plate", "mesh": {"model": "plate", "options": {"size_m": [20, 20]}},
             "pose": {"position_m": [-20.0, 0.0, 10.0], "euler_deg": [0, 0, 45]},
             "materials": {"plate": {"diffuse_reflectivity": rho}}}
    sim = Simulation(_scene(60.0, NADIR, e_eq=1.0, fov=10.0, plate=plate))
    cloud = sim.run_frame(0)
    on_plate = cloud["target"] == 0
    plate_pulses = set(cloud["ray_index"][on_plate].tolist())
    alarm_pulses = set(cloud["ray_index"][cloud["target"] == -1].tolist())
    pulses = _pulses(sim)
    assert 1000 < len(plate_pulses) < pulses - 1000
    assert not plate_pulses & alarm_pulses
    # detection against Σ P_d with S = C ρ cos θ / R² (C = 15² / 0.1, one figure: n = 2)
    d = np.stack([cloud["x_true"], cloud["y_true"], cloud["z_true"]], axis=1)[on_plate]
    rng = np.linalg.norm(d, axis=1)
    # the sensor frame is the scene frame turned by 180° about z: the normal's x, y flip
    cos_inc = np.abs(d @ (normal * [-1, -1, 1])) / rng
    signal = 2250.0 * rho * cos_inc / rng ** 2
    assert 1.05 < signal.mean() < 1.6
    p_d = ndtr(TNR * (signal - 1.0))
    detected = int(cloud["detected"][on_plate].sum())
    z = (detected - p_d.sum()) / math.sqrt((p_d * (1 - p_d)).sum())
    # with the Earth's background on these pulses the prediction would be far lower
    b_earth = EARTH_BOND_ALBEDO * sun[0] * solar_spectral_irradiance(905.0) * 10.0 / 1.0
    p_wrong = ndtr(TNR * (signal - 1.0) / math.sqrt(1.0 + b_earth)).sum()
    print(f"\ntarget in front of the Earth: {detected} of {on_plate.sum()} detected, "
          f"model {p_d.sum():.1f} (z = {z:.2f}); with the Earth's background it would be "
          f"{p_wrong:.1f}")
    assert abs(z) < 4.0
    assert (p_d.sum() - p_wrong) > 6 * math.sqrt((p_d * (1 - p_d)).sum())
    # the pulses past the plate see the lit Earth: their rate is the dayside's
    past = pulses - len(plate_pulses)
    alarms = len(alarm_pulses)
    expected_max = float(_p_pulse(b_earth * 1.01) - _p_pulse(0.0))
    assert 0.5 * expected_max * past < alarms <= past


def test_earth_needs_the_orbit():
    data = _scene(0.0, NADIR).model_dump(mode="json")
    data["sun"] = {"direction": [1.0, 0.0, 0.0]}
    with pytest.raises(ConfigError, match="earth"):
        Simulation(scenario_from_dict(data))
    data["sun"] = None
    with pytest.raises(ConfigError, match="earth"):
        Simulation(scenario_from_dict(data))
    data["earth"] = {"albedo": 1.5}
    with pytest.raises(ConfigError, match="earth.albedo"):
        scenario_from_dict(data)


@pytest.mark.parametrize("sub_rays", [None, 8])
def test_earth_is_byte_identical_across_chunks_and_threads(monkeypatch, sub_rays):
    sc = _scene(60.0, NADIR, fov=10.0, duration_s=0.2, e_eq=1.0,
                noise=[{"name": "angular"}, {"name": "range_signal"}],
                sheet_extra={"beam_divergence_deg": [0.5, 0.5]})
    if sub_rays:
        data = sc.model_dump(mode="json")
        data["sensor"]["beam"] = {"sub_rays": sub_rays}
        sc = scenario_from_dict(data)
    ref = Simulation(sc).run_frame(0)
    assert (ref["target"] == -1).sum() > 20
    for chunk, threads in ((131, "1"), (977, "2")):
        monkeypatch.setenv("LIDARSIM_THREADS", threads)
        other = Simulation(sc).run_frame(0, chunk_rays=chunk)
        for key in ref.columns:
            assert np.array_equal(ref[key], other[key], equal_nan=True), key


def test_earth_enters_the_hash_only_when_given():
    with_earth = _scene(0.0, NADIR)
    without = _scene(0.0, NADIR, earth=False)
    assert with_earth.config_hash() != without.config_hash()
    assert "earth" not in without.model_dump(exclude_none=True)


def test_sub_rays_share_the_earths_background_by_their_energy():
    """With divergence, B is the energy-weighted sum over the sub-rays that meet no target: a
    pulse whose footprint lies wholly on the dayside gets the single ray's B."""
    from lidarsim_core.pipeline.stages.earth import EarthBackground
    from lidarsim_core.scenario.earth import EarthConfig

    earth = EarthBackground(EarthConfig(albedo=0.3), ALTITUDE_KM, 2.0)
    nadir = np.array([[-1.0, 0.0, 0.0]])
    sun = np.array([[1.0, 0.0, 0.0]])
    full = earth.background(np.zeros((1, 3)), np.repeat(nadir, 4, axis=0), np.zeros(4, int),
                            np.full(4, 0.25), sun, 1)
    assert full[0] == pytest.approx(0.3 * 2.0, rel=1e-12)
    half = earth.background(np.zeros((1, 3)), np.repeat(nadir, 2, axis=0), np.zeros(2, int),
                            np.full(2, 0.25), sun, 1)  # half the energy sees a target
    assert half[0] == pytest.approx(0.3, rel=1e-12)
    # a ray past the limb (63.4° from nadir at 780 km) sees deep space
    limb = math.degrees(math.asin(6378.137 / (6378.137 + ALTITUDE_KM)))
    for angle, seen in ((limb - 0.1, True), (limb + 0.1, False)):
        a = math.radians(angle)
        d = np.array([[-math.cos(a), math.sin(a), 0.0]])
        hit, normal = earth.surface(np.zeros((1, 3)), d)
        assert bool(hit[0]) == seen
        if seen:
            assert np.linalg.norm(normal[0]) == pytest.approx(1.0, abs=1e-12)
