"""The signal-driven range error ``range_signal``: the datasheet's precision at its stated
condition, the model's σ elsewhere (computed here from the geometry and the link-budget
equations), and the seed paper's model untouched when it is not selected."""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest
from golden_outputs import AVX2_X86_64, AVX512_X86_64, bits_class
from helpers import datasheet, scenario

from lidarsim_core.noise.signal import TDC_FLOOR_M
from lidarsim_core.pipeline import Simulation
from lidarsim_core.noise.rng import ray_normals

SIGMA_REF = 0.02  # Livox: 2 cm 1σ at 20 m (80 % target)
#: The MID-70's range-at-reflectivity figures (its datasheet): they calibrate the link budget.
FIGURES = [{"reflectivity": 0.1, "range_m": 90.0}, {"reflectivity": 0.2, "range_m": 130.0},
           {"reflectivity": 0.8, "range_m": 260.0}]


def _sheet(**extra):
    # a 2° scanner: every pulse hits the plate within 1° of its normal
    return datasheet(fov_h_deg=2.0, fov_v_deg=2.0, range_precision_m=SIGMA_REF,
                     range_max_m=300.0, range_at_reflectivity=FIGURES, **extra)


def _plate_run(range_m, yaw_deg=0.0, *, detection=True, options=None, duration_s=1.0,
               sheet=None, rho=0.8):
    extra = {"detection": {}} if detection else {}
    sc = scenario({"model": "plate", "options": {"size_m": [60, 60]}},
                  {"position_m": [range_m, 0, 0], "euler_deg": [0, 0, yaw_deg]},
                  sheet=sheet or _sheet(), duration_s=duration_s,
                  noise=[{"name": "range_signal", "options": options or {}}])
    data = sc.model_dump()
    data["targets"][0]["materials"] = {"*": {"diffuse_reflectivity": rho}}
    data["sensor"].update(extra)
    from lidarsim_core.scenario.load import scenario_from_dict

    sim = Simulation(scenario_from_dict(data))
    return sim, sim.run_frame(0)


def _cos_incidence(cloud, yaw_deg):
    """|d · n| of each return from the plate's normal (body x turned by the yaw)."""
    yaw = math.radians(yaw_deg)
    normal = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    d = np.stack([cloud["x_true"], cloud["y_true"], cloud["z_true"]], axis=1)
    d /= np.linalg.norm(d, axis=1)[:, None]
    return np.abs(d @ normal)


def _model_sigma(sim, cloud, yaw_deg, rho=0.8, floor=TDC_FLOOR_M):
    """σ_R from the equations of docs/realism.md, with the calibrated C and n."""
    c, n = sim.link.constant, sim.link.exponent
    s_ref = c * 0.8 / 20.0 ** n
    s = c * rho * _cos_incidence(cloud, yaw_deg) / cloud["range_true"] ** n
    return np.sqrt(floor ** 2 + (SIGMA_REF ** 2 - floor ** 2) * (s_ref / s) ** 2)


def test_reference_condition_gives_the_datasheet_precision():
    """20 m, face-on, 80 %: σ within 3 % of the datasheet's 2 cm on 10,000 returns."""
    sim, cloud = _plate_run(20.0)
    error = cloud["range"] - cloud["range_true"]
    assert len(error) == 10_000
    measured = float(error.std())
    print(f"\nreference: σ = {measured * 1000:.3f} mm (datasheet 20 mm), n = {len(error)}")
    assert abs(measured / SIGMA_REF - 1.0) < 0.03
    assert abs(error.mean()) < 4 * SIGMA_REF / math.sqrt(len(error))


@pytest.mark.parametrize("range_m, yaw_deg", [(20.0, 60.0), (40.0, 0.0), (40.0, 60.0)])
def test_incidence_and_range_follow_the_model(range_m, yaw_deg):
    """60° incidence and 40 m: measured σ within 5 % of the model's prediction."""
    sim, cloud = _plate_run(range_m, yaw_deg)
    error = cloud["range"] - cloud["range_true"]
    model = _model_sigma(sim, cloud, yaw_deg)
    predicted = float(np.sqrt(np.mean(model ** 2)))
    measured = float(error.std())
    print(f"\n{range_m:g} m, {yaw_deg:g}°: σ = {measured * 1000:.2f} mm, model "
          f"{predicted * 1000:.2f} mm, n = {len(error)}")
    assert len(error) > 9000
    assert abs(measured / predicted - 1.0) < 0.05
    z = error / model  # and point by point, N(0, 1)
    assert abs(z.std() - 1.0) < 0.05
    # the model is far from the datasheet's constant figure: the test can tell them apart
    assert predicted > 1.8 * SIGMA_REF


def test_dark_target_is_noisier_and_bright_one_quieter():
    _, dark = _plate_run(20.0, rho=0.2)
    sim, bright = _plate_run(10.0, rho=0.8, duration_s=0.5)
    f = TDC_FLOOR_M
    # a 20 % plate: S a quarter of the reference's
    expected = math.sqrt(f ** 2 + (SIGMA_REF ** 2 - f ** 2) * 4.0 ** 2)
    assert abs((dark["range"] - dark["range_true"]).std() / expected - 1) < 0.05
    # bright and near: S is 2^n (3.9) times the reference's; the floor (c/2 · 35 ps = 5.2 mm)
    # is added in quadrature
    expected = math.sqrt(f ** 2 + (SIGMA_REF ** 2 - f ** 2) / 2.0 ** (2 * sim.link.exponent))
    sigma = (bright["range"] - bright["range_true"]).std()
    assert abs(sigma / expected - 1) < 0.05 and sigma < SIGMA_REF / 2


def test_without_detection_the_budget_is_rho_over_r_squared():
    sim, cloud = _plate_run(40.0, detection=False, options={"floor_m": 0.0})
    assert sim.link is None
    # S ∝ ρ/R²: at twice the reference range, four times the error
    error = cloud["range"] - cloud["range_true"]
    assert abs(error.std() / (4 * SIGMA_REF * (cloud["range_true"] / 40.0).mean() ** 2) - 1) \
        < 0.03


def test_reference_condition_from_the_datasheet():
    sheet = _sheet(range_precision_condition={"range_m": 40.0, "reflectivity": 0.8})
    _, cloud = _plate_run(40.0, sheet=sheet)
    assert abs((cloud["range"] - cloud["range_true"]).std() / SIGMA_REF - 1) < 0.03


def test_floor_bounds_the_error_of_strong_returns():
    _, cloud = _plate_run(5.0, options={"floor_m": 0.004}, duration_s=0.5)
    # S is 16x the reference: √(4² + (20² − 4²)/16²) = 4.11 mm
    expected = math.sqrt(0.004 ** 2 + (SIGMA_REF ** 2 - 0.004 ** 2) / 16.0 ** 2)
    measured = (cloud["range"] - cloud["range_true"]).std()
    assert abs(measured / expected - 1) < 0.05


def test_seed_papers_model_is_unchanged():
    """The default chain (angular, range) draws exactly what it always drew: range error =
    σ × the 'noise.1.range' normals of each ray, and the point record's bytes are those of the
    release before this model existed."""
    sc = scenario({"model": "plate", "options": {"size_m": [60, 60]}},
                  {"position_m": [20, 0, 0], "euler_deg": [0, 0, 30]}, duration_s=0.2,
                  noise=None)
    cloud = Simulation(sc).run_frame(0)
    normals = ray_normals(sc.seed, 0, "noise.1.range", cloud["ray_index"], 1)[:, 0]
    np.testing.assert_array_equal(cloud["range"], cloud["range_true"] + normals * 0.01)
    digest = hashlib.sha256()
    for name in cloud.columns:
        digest.update(name.encode())
        digest.update(np.ascontiguousarray(cloud[name]).tobytes())
    from lidarsim_core import kernels

    recorded = SEED_MODEL_SHA256.get(bits_class())
    if recorded is None:
        pytest.skip(f"no reference for CPUs of the class '{bits_class()}' "
                    "(tests/golden_outputs.py)")
    assert digest.hexdigest() == recorded[kernels.enabled()]


#: sha256 of the point record above, computed on main (bcd879e) before ``range_signal``, with
#: the compiled kernels (True) and with the NumPy pipeline (False; the two differ in the last
#: bits of the rotated rays), per class of CPU (``golden_outputs.bits_class``: NumPy's
#: AVX-512 builds of its float64 functions round differently from its AVX2 ones); the AVX2
#: class's recorded from 00fecf3, whose outputs on AVX-512 were still those of bcd879e.
SEED_MODEL_SHA256 = {
    AVX512_X86_64: {
        True: "b39c4fc5bc506fa1e1d114ad7be9f3782df4dec1f480a19eb051ccb104cb688b",
        False: "9a491821636a78f30fd1ddf9c2780e3ca04ac45f529761a2f9f4e16999e67ff5"},
    AVX2_X86_64: {
        True: "5a073e9f606597459a6d179ff33e8592c54566b72f55816e822cb747ab75000c",
        False: "cf58acd6cff0e2ab17c90529ad03117436af327bfbea4a490e2b45a26389eac2"}}


def test_background_light_raises_the_error_by_its_noise():
    """σ_R scales with the receiver's noise: k = √(1 + B) multiplies S_ref/S."""
    from lidarsim_core.scenario.datasheet import SensorDatasheet
    from lidarsim_core.noise.base import NoiseContext
    from lidarsim_core.noise.signal import RangeSignalError
    from lidarsim_core.instrument.linkbudget import LinkBudget

    sheet = SensorDatasheet(**_sheet())
    ctx = NoiseContext(sheet, 1, 0, "s", LinkBudget(1000.0, 2.0))
    model = RangeSignalError.from_config({"floor_m": 0.001})
    s_ref = 1000.0 * 0.8 / 400.0
    sigma = model.sigma_at(np.array([s_ref, s_ref, s_ref / 2, 0.0]), ctx,
                           np.array([1.0, 2.0, 1.0, 1.0]))
    inner = SIGMA_REF ** 2 - 0.001 ** 2
    np.testing.assert_allclose(sigma, [SIGMA_REF, math.sqrt(0.001 ** 2 + 4 * inner),
                                       math.sqrt(0.001 ** 2 + 4 * inner), 0.0], rtol=1e-12)
