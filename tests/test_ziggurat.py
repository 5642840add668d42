"""The ``ziggurat`` normal generator (lidarsim_core.noise.ziggurat, kernels.ziggurat).

Against independent truth: the normal CDF and its tail probabilities (SciPy), the exact area
of the Ziggurat's layers (erfc), NumPy's own Philox generator for the words, and the
``inverse_cdf`` stream, which must not move. Every sample is a fixed function of its seed, so
each p-value below is a fixed number (printed in the assertion), not a flaky draw.
"""

from __future__ import annotations

import math
import typing
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from scipy import stats
from scipy.special import ndtri

import lidarsim_core as ls
from lidarsim_core import kernels
from lidarsim_core.base.errors import ConfigError
from lidarsim_core.noise import rng
from lidarsim_core.noise import ziggurat as zg
from lidarsim_core.noise.base import NoiseContext
from lidarsim_core.pipeline import Simulation
from lidarsim_core.scenario import demo_scenario, scenario_from_dict
from lidarsim_core.scenario.model import Scenario

SEED, STREAM = 2026, "noise.1.range"


def _normals(rays: int, draws: int = 4, *, seed: int = SEED, stream: str = STREAM,
             index: np.ndarray | None = None) -> np.ndarray:
    index = np.arange(rays) if index is None else index
    return rng.ray_normals(seed, 3, stream, index, draws, "ziggurat")


@pytest.fixture
def reference(monkeypatch):
    """The NumPy reference (no compiled kernels)."""
    monkeypatch.setenv("LIDARSIM_KERNELS", "numpy")


# -- the tables and the words


def test_layers_have_the_exact_area_and_close_at_the_top():
    r, v = zg.R, zg.V
    exact = r * math.exp(-r * r / 2) + math.sqrt(math.pi / 2) * math.erfc(r / math.sqrt(2))
    assert v == pytest.approx(exact, rel=1e-15)
    xs, fs = zg.X_TABLE, zg.F_TABLE
    assert len(xs) == zg.LAYERS + 1 and xs[1] == r and xs[-1] == 0.0 and fs[-1] == 1.0
    assert np.all(np.diff(xs) < 0)
    # every layer above the base has area v: width x[i] times the height between its edges
    areas = xs[1:-1] * (fs[2:] - fs[1:-1])
    np.testing.assert_allclose(areas, v, rtol=1e-12)
    assert zg.closure_residual() < 1e-12


def test_philox_blocks_are_numpys_words_for_any_counter():
    key = rng.stream_key(SEED, 3, STREAM)
    gen = np.random.default_rng(5)
    c0 = gen.integers(1, 2 ** 62, 40, dtype=np.uint64)
    c1 = gen.integers(0, 2 ** 40, 40, dtype=np.uint64)
    c2 = gen.integers(0, 4, 40, dtype=np.uint64)
    mine = zg.philox_blocks(key, c0, c1, c2)
    for row in range(40):
        numpy_gen = np.random.Philox(key=key, counter=[int(c0[row]) - 1, int(c1[row]),
                                                       int(c2[row]), 0])
        np.testing.assert_array_equal(mine[row], numpy_gen.random_raw(4))


def test_first_words_are_the_uniform_streams_words(reference):
    index = np.array([0, 7, 3, 7, 1000])
    words = rng.ray_words(SEED, 3, STREAM, index, 6)
    uniforms = rng.ray_uniforms(SEED, 3, STREAM, index, 6)
    np.testing.assert_array_equal(((words >> np.uint64(12)).astype(float) + 0.5) * 2.0 ** -52,
                                  uniforms)


# -- the distribution


def test_ks_against_the_normal_cdf(reference):
    z = _normals(250_000).ravel()  # 10^6 NumPy reference draws
    assert len(z) == 1_000_000
    result = stats.kstest(z, "norm")
    assert result.pvalue > 1e-3, result  # 0.0058 for this stream: see the next test


def test_ks_p_values_of_many_streams_are_uniform():
    """One KS p-value is one draw from U(0, 1) if the generator is exact: the p-values of 40
    independent streams of 2.5·10^5 draws must themselves pass a KS test against U(0, 1)."""
    p = [stats.kstest(_normals(62_500, seed=s).ravel(), "norm").pvalue for s in range(40)]
    assert stats.kstest(p, "uniform").pvalue > 0.01, sorted(p)


def _broken_same_bits(words: np.ndarray, key: np.ndarray) -> np.ndarray:
    """Ziggurat with the layer taken from the uniform's own top bits (Doornik 2005's warning)."""
    crossed = (words & ~np.uint64(255)) | (words >> np.uint64(56))
    return zg.normals_from_words(key, crossed, np.ones_like(words), np.zeros_like(words))


def _broken_no_rejection(words: np.ndarray) -> np.ndarray:
    """Ziggurat that accepts every point of its rectangles: no wedge test, no tail."""
    layer = (words & np.uint64(255)).astype(np.intp)
    x = ((words >> np.uint64(12)).astype(float) + 0.5) * 2.0 ** -52 * zg.X_TABLE[layer]
    return np.where((words >> np.uint64(8)) & np.uint64(1), -x, x)


def test_a_broken_generator_fails_the_tests(reference):
    words = rng.ray_words(SEED, 3, STREAM, np.arange(250_000), 4).ravel()
    key = rng.stream_key(SEED, 3, STREAM)
    assert stats.kstest(_broken_same_bits(words, key), "norm").pvalue < 1e-12
    no_rejection = _broken_no_rejection(words)
    assert stats.kstest(no_rejection, "norm").pvalue > 0.01  # too subtle for KS at 10^6 ...
    p4 = 2 * stats.norm.sf(4.0)  # ... but its tail is empty
    count = int((np.abs(no_rejection) > 4.0).sum())
    assert count == 0 and stats.binomtest(count, len(words), p4).pvalue < 1e-12


def test_moments():
    z = _normals(1_000_000).ravel()  # 4·10^6 draws (compiled when numba is installed)
    n = len(z)
    assert abs(z.mean()) < 4 / math.sqrt(n)
    assert abs(z.std() - 1.0) < 2e-3  # "within a fraction of a percent": SE is 3.5e-4
    assert abs(z.std() - 1.0) < 4 / math.sqrt(2 * n)
    assert abs(stats.skew(z)) < 4 * math.sqrt(6 / n)
    assert abs(stats.kurtosis(z)) < 4 * math.sqrt(24 / n)


@pytest.mark.parametrize("k", [3.0, 4.0])
def test_tail_frequencies_by_exact_binomial_test(k):
    z = _normals(1_000_000).ravel()
    p = 2 * stats.norm.sf(k)
    count = int((np.abs(z) > k).sum())
    result = stats.binomtest(count, len(z), p)
    assert result.pvalue > 0.01, (count, len(z) * p, result.pvalue)
    # beyond r = 3.654 the draws come from Marsaglia's tail: that path is exercised
    assert (np.abs(z) > zg.R).sum() > 400


def test_bounded_by_its_max_abs_normal():
    z = _normals(1_000_000)
    assert np.abs(z).max() < rng.max_abs_normal("ziggurat") == zg.MAX_ABS_NORMAL
    assert rng.max_abs_normal("inverse_cdf") == rng.MAX_ABS_NORMAL < zg.MAX_ABS_NORMAL


def test_signs_and_draws_are_independent():
    z = _normals(500_000, 2)
    r = np.corrcoef(z[:, 0], z[:, 1])[0, 1]
    assert abs(r) < 4 / math.sqrt(len(z))
    assert abs(np.mean(z > 0) - 0.5) < 4 * 0.5 / math.sqrt(z.size)


# -- the compiled kernel, chunks, threads


def test_numba_equals_numpy_bit_for_bit(monkeypatch):
    pytest.importorskip("numba", reason="the compiled kernels need the extra 'fast'")
    gen = np.random.default_rng(1)
    # scattered and repeated rays (the NumPy reference draws the whole range between them)
    index = np.concatenate([np.arange(200_000), gen.integers(10 ** 6, 3 * 10 ** 6, 50_000),
                            [5, 5, 0]])
    for draws in (1, 3, 5):
        monkeypatch.setenv("LIDARSIM_KERNELS", "numba")
        compiled = _normals(0, draws, index=index)
        monkeypatch.setenv("LIDARSIM_KERNELS", "numpy")
        reference = _normals(0, draws, index=index)
        np.testing.assert_array_equal(compiled.view(np.uint64), reference.view(np.uint64))
    assert (np.abs(reference) > zg.R).any()  # the tail's logarithms agree too
    # rays 10^12 apart: the reference's words straight from their counters
    far = gen.integers(0, 10 ** 12, 100_000)
    monkeypatch.setenv("LIDARSIM_KERNELS", "numba")
    compiled = _normals(0, 1, index=far)[:, 0]
    key = rng.stream_key(SEED, 3, STREAM)
    c0 = far.astype(np.uint64) + np.uint64(1)
    words = zg.philox_blocks(key, c0, 0, 0)[:, 0]
    reference = zg.normals_from_words(key, words, c0, np.zeros_like(c0))
    np.testing.assert_array_equal(compiled.view(np.uint64), reference.view(np.uint64))


def test_a_rays_numbers_do_not_depend_on_chunks_order_or_threads():
    index = np.arange(300_000)
    whole = _normals(0, 3, index=index)
    perm = np.random.default_rng(2).permutation(len(index))
    np.testing.assert_array_equal(_normals(0, 3, index=index[perm]), whole[perm])
    chunks = np.array_split(index, 7)
    with ThreadPoolExecutor(4) as pool:
        parts = list(pool.map(lambda c: _normals(0, 3, index=c), chunks))
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    # another stream, frame or seed: other numbers
    assert not np.array_equal(_normals(0, 3, index=index[:100], seed=SEED + 1), whole[:100])


# -- the default stream, the setting, the metadata


def test_inverse_cdf_stream_is_unchanged():
    index = np.array([0, 1, 2, 99, 12345])
    default = rng.ray_normals(SEED, 3, STREAM, index, 3)
    np.testing.assert_array_equal(default, ndtri(rng.ray_uniforms(SEED, 3, STREAM, index, 3)))
    np.testing.assert_array_equal(rng.ray_normals(SEED, 3, STREAM, index, 3, "inverse_cdf"),
                                  default)
    # the words behind it are NumPy's Philox stream, counter i·B + b + 1 (independent truth)
    gen = np.random.Philox(key=rng.stream_key(SEED, 3, STREAM), counter=[99, 0, 0, 0])
    word = gen.random_raw(1)[0]
    assert default[3, 0] == ndtri(((int(word) >> 12) + 0.5) * 2.0 ** -52)
    ctx = NoiseContext(sensor=None, seed=SEED, frame=3, stream=STREAM)  # type: ignore[arg-type]
    assert ctx.normal_generator == "inverse_cdf"
    np.testing.assert_array_equal(ctx.normals(index, 3), default)
    with pytest.raises(ValueError, match="ziggurat"):
        rng.ray_normals(SEED, 3, STREAM, index, 3, "box-muller")


def test_setting_names_match_the_generators():
    annotation = Scenario.model_fields["normals"].annotation
    assert typing.get_args(annotation) == rng.NORMAL_GENERATORS
    assert Scenario.model_fields["normals"].default == rng.INVERSE_CDF


def _small_demo(**changes) -> dict:
    data = demo_scenario(duration_s=0.05, detail="coarse", backend="numpy").model_dump(
        mode="json")
    data.update(changes)
    return data


def test_default_scenarios_keep_their_dump_hash_and_points():
    plain = scenario_from_dict(_small_demo())
    explicit = scenario_from_dict(_small_demo(normals="inverse_cdf"))
    assert "normals" not in plain.model_dump() and "normals" not in explicit.model_dump()
    assert plain.config_hash() == explicit.config_hash()
    a, b = Simulation(plain).run_frame(0), Simulation(explicit).run_frame(0)
    assert "normals" not in a.frame.extra
    for name, column in a.columns.items():
        np.testing.assert_array_equal(b[name], column, err_msg=name)


def test_ziggurat_frames_are_named_reproducible_and_normal(monkeypatch, tmp_path):
    data = _small_demo(normals="ziggurat")
    data["noise"] = [{"name": "range", "options": {"sigma_m": 0.05}}]
    zig = scenario_from_dict(data)
    assert zig.model_dump()["normals"] == "ziggurat"
    assert zig.config_hash() != scenario_from_dict(_small_demo()).config_hash()
    monkeypatch.setenv("LIDARSIM_THREADS", "1")
    one = Simulation(zig).run_frame(0, chunk_rays=997)
    monkeypatch.setenv("LIDARSIM_THREADS", "2")
    other = Simulation(zig).run_frame(0)
    assert one.frame.extra["normals"] == "ziggurat"
    one.save(tmp_path / "frame.ply")  # the file says which stream made it
    assert ls.read(tmp_path / "frame.ply").frame.extra["normals"] == "ziggurat"
    for name, column in one.columns.items():
        np.testing.assert_array_equal(other[name], column, err_msg=name)
    error = (one["range"] - one["range_true"]) / 0.05
    assert len(error) > 300
    assert stats.kstest(error, "norm").pvalue > 0.01
    # the errors are the stream's numbers for these rays: the generator really is used
    stream = rng.ray_normals(zig.seed, 0, "noise.0.range", one["ray_index"], 1, "ziggurat")
    np.testing.assert_allclose(error, stream[:, 0], atol=1e-9)


def test_an_unknown_generator_is_one_clear_error():
    with pytest.raises(ConfigError, match="normals"):
        scenario_from_dict(_small_demo(normals="box-muller"))


def test_culling_margin_uses_the_ziggurat_bound():
    if not kernels.enabled():
        pytest.skip("culling runs with the compiled kernels")
    data = _small_demo(normals="ziggurat")
    data["noise"] = [{"name": "angular", "options": {"sigma_deg": 1.5}}, {"name": "range"}]
    sim = Simulation(scenario_from_dict(data))
    assert sim.culler.margin_rad == pytest.approx(
        math.sqrt(2) * zg.MAX_ABS_NORMAL * math.radians(1.5), rel=1e-5)
    culled = sim.run_frame(0)
    sim.culler = None
    every_pulse = sim.run_frame(0)
    for name, column in every_pulse.columns.items():
        np.testing.assert_array_equal(culled[name], column, err_msg=name)
