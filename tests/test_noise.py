"""The paper's noise models: statistics against the datasheet, switching off, reproducibility."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import datasheet, scenario

import lidarsim_core as ls
from lidarsim_core.noise.base import perpendicular_basis
from lidarsim_core.patterns.geometry import directions_from_az_el

# A plate 20 m ahead, far wider than the 40° FOV: every ray hits, at a known range.
WALL = {"model": "plate", "options": {"size_m": [200.0, 200.0]}}
WALL_POSE = {"position_m": [20.0, 0.0, 0.0]}


def _cloud(noise, *, seed=11, duration_s=1.0, **sheet):
    return ls.simulate(scenario(WALL, WALL_POSE, sheet=datasheet(**sheet), noise=noise, seed=seed,
                                duration_s=duration_s))


def _assert_normal(samples: np.ndarray, sigma: float) -> None:
    """Mean 0 and standard deviation sigma, within 5 standard errors."""
    n = len(samples)
    assert abs(samples.mean()) < 5 * sigma / np.sqrt(n)
    assert abs(samples.std(ddof=1) / sigma - 1) < 5 / np.sqrt(2 * (n - 1))
    # Gaussian shape: about 68.3 % within 1 sigma (binomial standard error)
    inside = np.mean(np.abs(samples) < sigma)
    assert abs(inside - 0.6827) < 5 * np.sqrt(0.6827 * 0.3173 / n)


def test_range_error_has_datasheet_sigma():
    cloud = _cloud(["range"], range_precision_m=0.02)
    assert len(cloud) == 10000
    _assert_normal(cloud["range"] - cloud["range_true"], 0.02)
    # Eq. 4: the measured point moves along the ray only
    along = cloud.xyz - cloud.xyz_true
    ray = cloud.xyz_true / cloud["range_true"][:, None]
    np.testing.assert_allclose(np.cross(along, ray), 0.0, atol=1e-12)


def test_angular_error_has_datasheet_sigma_about_both_perpendicular_axes():
    sigma_deg = 0.1
    cloud = _cloud(["angular"], angular_precision_deg=sigma_deg)
    nominal = directions_from_az_el(cloud["azimuth"], cloud["elevation"])
    flown = cloud.xyz_true / cloud["range_true"][:, None]
    u, v = perpendicular_basis(nominal)
    for axis in (u, v):
        angle = np.arcsin(np.einsum("ij,ij->i", flown - nominal, axis))
        _assert_normal(angle, np.radians(sigma_deg))
    # the paper's angular error moves the ray, so points stay on the surface: no range error
    np.testing.assert_array_equal(cloud["range"], cloud["range_true"])


def test_noise_off_is_bit_identical_to_noiseless_geometry():
    off = _cloud([])
    zero_sigma = _cloud(["angular", "range"], range_precision_m=0.0, angular_precision_deg=0.0)
    for key in ("x", "y", "z", "range", "ray_index"):
        np.testing.assert_array_equal(off[key], zero_sigma[key])
    np.testing.assert_array_equal(off.xyz, off.xyz_true)


def test_same_seed_same_output_different_seed_different_noise():
    a = _cloud(None, seed=5, duration_s=0.2)
    b = _cloud(None, seed=5, duration_s=0.2)
    c = _cloud(None, seed=6, duration_s=0.2)
    np.testing.assert_array_equal(a.xyz, b.xyz)
    assert a.to_structured().tobytes() == b.to_structured().tobytes()
    assert not np.allclose(a.xyz, c.xyz)
    assert np.abs(a["range"] - c["range"]).mean() > 0.005


def test_noise_does_not_depend_on_chunk_size():
    sc = scenario(WALL, WALL_POSE, sheet=datasheet(), noise=None, seed=3, duration_s=0.3)
    sim = ls.Simulation(sc)
    whole = sim.run_frame(0, chunk_rays=10 ** 6)
    pieces = sim.run_frame(0, chunk_rays=777)
    assert whole.to_structured().tobytes() == pieces.to_structured().tobytes()


def test_noise_options_override_the_datasheet():
    cloud = _cloud([{"name": "range", "options": {"sigma_m": 0.5}}], duration_s=0.3)
    _assert_normal(cloud["range"] - cloud["range_true"], 0.5)
    with pytest.raises(ls.ConfigError, match=r"noise\.0\.options\.sigma_m"):
        _cloud([{"name": "range", "options": {"sigma_m": -1}}])
