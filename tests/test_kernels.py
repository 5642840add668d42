"""The compiled kernels against the NumPy code they replace (lidarsim_core.kernels)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lidarsim_core import kernels
from lidarsim_core.base.errors import ConfigError
from lidarsim_core.noise import rng
from lidarsim_core.pipeline import Simulation
from lidarsim_core.scenario import demo_scenario

numba = pytest.importorskip("numba", reason="the compiled kernels need numba (extra 'fast')")


def _ulps(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a - b| in units of the last place of b (of 1e-300 at zero)."""
    return np.abs(a - b) / np.spacing(np.maximum(np.abs(b), 1e-300))


@pytest.mark.parametrize("draws", [1, 2, 3, 4, 5, 9])
def test_philox_words_are_numpys_bit_for_bit(draws, monkeypatch):
    index = np.array([0, 1, 7, 4095, 123_456_789, 2**40 + 3, 5], dtype=np.int64)
    monkeypatch.setenv("LIDARSIM_KERNELS", "numba")
    compiled = rng.ray_uniforms(11, 4, "noise.0.angular", index, draws)
    monkeypatch.setenv("LIDARSIM_KERNELS", "numpy")
    reference = np.vstack([rng.ray_uniforms(11, 4, "noise.0.angular", index[i:i + 1], draws)
                           for i in range(len(index))])  # NumPy needs a contiguous run
    np.testing.assert_array_equal(compiled, reference)


def test_uniforms_stay_inside_the_open_interval_and_normals_are_bounded():
    from scipy.special import ndtri

    from lidarsim_core.kernels.philox import to_unit

    @numba.njit
    def extremes():
        return to_unit(np.uint64(0)), to_unit(np.uint64(0xFFFFFFFFFFFFFFFF))

    low, high = extremes()
    assert low == 2.0 ** -53 and high == 1.0 - 2.0 ** -53 and high < 1.0
    assert rng.MAX_ABS_NORMAL == pytest.approx(-ndtri(low), rel=1e-15)
    assert ndtri(high) == pytest.approx(rng.MAX_ABS_NORMAL, rel=1e-15)
    # and the draws of a real stream respect it
    z = rng.ray_normals(3, 0, "s", np.arange(200_000), 4)
    assert np.abs(z).max() <= rng.MAX_ABS_NORMAL


def _over_array(func):
    """A compiled loop of ``func`` (a sine-and-cosine kernel) over an array."""
    @numba.njit
    def both(x):
        s, c = np.empty_like(x), np.empty_like(x)
        for i in range(x.size):
            s[i], c[i] = func(x[i])
        return s, c

    return both


@pytest.mark.parametrize("scale", [1.0, 10.0, 1e3, 1e5, 2.0 ** 20 * 3])
def test_sincos_is_within_two_ulp_of_the_c_library(scale):
    from lidarsim_core.kernels.trig import sincos

    both = _over_array(sincos)
    x = np.random.default_rng(1).uniform(-scale, scale, 400_000)
    x[:4] = [0.0, -0.0, math.pi / 4, scale]
    s, c = both(x)
    # absolute error: near a zero of sin or cos the relative error of any argument
    # reduction grows; 2 ulp of 1 is the library's own accuracy class
    assert np.abs(s - np.sin(x)).max() <= 2 * np.spacing(1.0)
    assert np.abs(c - np.cos(x)).max() <= 2 * np.spacing(1.0)
    big = np.abs(np.sin(x)) > 0.5
    assert _ulps(s[big], np.sin(x)[big]).max() <= 2


def test_sincos_reduced_takes_each_quadrant_as_the_integer_did():
    """The quadrant is a float (vectorises on AVX2): k - 4·floor(k/4) equals k & 3 for every
    k that |x| < 2**20 reaches, and the results at the quadrants' edges, on both sides of
    zero, are the exact values (the same as with the integer quadrant)."""
    from lidarsim_core.kernels.trig import _LIMIT, sincos_reduced

    k = np.arange(-(2 ** 20), 2 ** 20 + 1, dtype=np.float64)  # |k| <= |x|·2/π + 1/2
    assert np.all(k - 4.0 * np.floor(k * 0.25) == (k.astype(np.int64) & 3))
    both = _over_array(sincos_reduced)
    quarter = np.arange(-8, 9) * (math.pi / 2)
    s, c = both(quarter)
    expected_s = np.array([0.0, 1.0, 0.0, -1.0])[np.arange(-8, 9) % 4]
    expected_c = np.array([1.0, 0.0, -1.0, 0.0])[np.arange(-8, 9) % 4]
    assert np.abs(s - expected_s).max() < 1e-15 and np.abs(c - expected_c).max() < 1e-15
    x = np.random.default_rng(5).uniform(-_LIMIT, _LIMIT, 200_000)
    s, c = both(x)
    assert np.abs(s - np.sin(x)).max() <= 2 * np.spacing(1.0)
    assert np.abs(c - np.cos(x)).max() <= 2 * np.spacing(1.0)


def test_sincos_of_non_finite_arguments_is_nan():
    from lidarsim_core.kernels.trig import sincos

    @numba.njit
    def one(x):
        return sincos(x)

    for value in (np.inf, -np.inf, np.nan):
        assert all(math.isnan(v) for v in one(value))


@pytest.mark.parametrize("start", [0, 10**9, 10**13])
def test_rose_kernel_matches_the_numpy_pattern(start, monkeypatch):
    sim = Simulation(demo_scenario(duration_s=0.01))
    index = np.arange(start, start + 20_000, dtype=np.int64)
    monkeypatch.setenv("LIDARSIM_KERNELS", "numpy")
    reference = sim.pattern.rays_for_indices(index)
    monkeypatch.setenv("LIDARSIM_KERNELS", "numba")
    compiled = sim.pattern.rays_for_indices(index)
    np.testing.assert_array_equal(compiled.t, reference.t)
    np.testing.assert_array_equal(compiled.index, reference.index)
    # start 10**13 (a scan of 3 years) takes the C library's path for the roll angle
    assert np.abs(compiled.direction - reference.direction).max() <= 4 * np.spacing(1.0)


def test_angular_error_kernel_gives_the_numpy_bits(monkeypatch):
    from lidarsim_core.noise.base import NoiseContext
    from lidarsim_core.noise.gaussian import AngularError

    sim = Simulation(demo_scenario(duration_s=0.01))
    directions = np.random.default_rng(2).normal(size=(50_000, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    directions[:5] = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, 0.6, 0.8], [0.3, 0, 0.95393920]]
    directions[:5] /= np.linalg.norm(directions[:5], axis=1, keepdims=True)
    index = np.arange(50_000, dtype=np.int64) * 7
    model = AngularError.from_config({"sigma_deg": 2.0})
    ctx = NoiseContext(sim.sensor, 5, 1, "noise.0.angular")
    monkeypatch.setenv("LIDARSIM_KERNELS", "numpy")
    reference = model.perturb_rays(directions, index, ctx)
    monkeypatch.setenv("LIDARSIM_KERNELS", "numba")
    np.testing.assert_array_equal(model.perturb_rays(directions, index, ctx), reference)


def test_embree_kernels_give_the_numpy_bits(monkeypatch):
    pytest.importorskip("embreex")
    from lidarsim_core.bench import scan_rays

    sim = Simulation(demo_scenario(duration_s=0.1, backend="embree"))
    origins, directions = scan_rays(sim)
    mesh = sim.targets[0].mesh
    casts = {}
    for mode in ("numpy", "numba"):
        monkeypatch.setenv("LIDARSIM_KERNELS", mode)
        casts[mode] = sim.backend.cast(mesh, origins, directions)
    a, b = casts["numpy"], casts["numba"]
    assert a.hit.sum() > 500
    np.testing.assert_array_equal(a.face, b.face)
    np.testing.assert_array_equal(a.distance, b.distance)
    np.testing.assert_array_equal(a.normal, b.normal)


def test_whole_simulation_agrees_with_and_without_kernels(monkeypatch):
    clouds = {}
    for mode in ("numpy", "numba"):
        monkeypatch.setenv("LIDARSIM_KERNELS", mode)
        clouds[mode] = Simulation(demo_scenario(duration_s=0.2, backend="numpy")).run_frame(0)
    a, b = clouds["numpy"], clouds["numba"]
    assert len(a) == len(b) > 1000
    for name in ("ray_index", "face_index", "part", "return_number"):
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    # the rose directions differ by a few ulp (kernels.trig); everything downstream follows
    for name in ("x", "y", "z", "x_true", "y_true", "z_true", "range", "range_true"):
        np.testing.assert_allclose(a[name], b[name], rtol=0, atol=1e-11, err_msg=name)


def test_kernel_mode_is_validated_and_numba_can_be_required(monkeypatch):
    monkeypatch.setenv("LIDARSIM_KERNELS", "fortran")
    with pytest.raises(ConfigError, match="LIDARSIM_KERNELS must be one of auto, numba, numpy"):
        kernels.enabled()
    monkeypatch.setenv("LIDARSIM_KERNELS", "numba")
    monkeypatch.setattr(kernels, "numba_importable", lambda: False)
    with pytest.raises(ConfigError, match=r"numba is not installed.*lidarsim-core\[fast\]"):
        kernels.enabled()
    monkeypatch.setenv("LIDARSIM_KERNELS", "auto")
    assert kernels.enabled() is False and kernels.describe() == "numpy"


def test_warm_up_compiles_every_kernel():
    assert kernels.warm_up() is True
