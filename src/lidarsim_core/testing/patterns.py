"""The scan-pattern conformance suite: one pytest class every pattern must pass.

A pattern author runs it on their pattern with a few lines in their own test-suite::

    from lidarsim_core.testing.patterns import PatternConformance

    class TestMyPattern(PatternConformance):
        sensor = "my-sensor"            # a catalogue name, a datasheet file or a SensorDatasheet
        pattern_options = {"b": 5}      # optional overrides of the datasheet's pattern options
        duration_s = 0.05               # optional: scan time the checks use

or overrides the ``pattern`` fixture to return any :class:`~lidarsim_core.patterns.base.ScanPattern`
(parametrise it to run the suite on several sensors). The checks:

* directions are finite unit vectors, all inside the datasheet FOV;
* ray ``k`` has index ``k``; times are finite, inside the requested interval, non-decreasing
  with the index, equal to :meth:`time_of_index`, and non-decreasing per channel (emitter);
* the number of rays in an interval matches the pattern's mean rate (``mean_rate_hz`` if the
  pattern defines it, else the datasheet point rate) to within one firing cycle, and that rate
  never exceeds the datasheet's ``point_rate_hz``;
* channels are int16 and non-negative;
* generating an interval at once or in arbitrary pieces gives identical rays, and so does a
  fresh instance (determinism), and so do arbitrary index subsets (pure function of the index).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pytest

from ..patterns.base import RayBatch, ScanPattern

#: Tolerance on unit length and FOV checks (rad).
TOL = 1e-9


def _mean_rate(pattern: ScanPattern) -> float:
    return float(getattr(pattern, "mean_rate_hz", pattern.rate_hz))


def _cycle_size(pattern: ScanPattern) -> int:
    return int(getattr(pattern, "rays_per_cycle", 1))


def _same(a: RayBatch, b: RayBatch) -> None:
    np.testing.assert_array_equal(a.index, b.index)
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.direction, b.direction)
    np.testing.assert_array_equal(a.channel, b.channel)


def _concat(parts: list[RayBatch]) -> RayBatch:
    return RayBatch(np.concatenate([p.index for p in parts]), np.concatenate([p.t for p in parts]),
                    np.concatenate([p.direction for p in parts]),
                    np.concatenate([p.channel for p in parts]))


class PatternConformance:
    """Subclass with ``sensor`` (and optionally ``pattern_options``), or override ``pattern``."""

    #: Catalogue name, datasheet path, or :class:`~lidarsim_core.scenario.datasheet.SensorDatasheet`.
    sensor: ClassVar[Any] = None
    #: Overrides of the datasheet's ``scan_pattern.options``.
    pattern_options: ClassVar[dict[str, Any]] = {}
    #: Scan time (s) used by the checks; it is stretched to cover at least two firing cycles.
    duration_s: ClassVar[float] = 0.02
    #: Start of the checked interval (s); a non-zero start also exercises late indices.
    start_s: ClassVar[float] = 1.2345

    @pytest.fixture
    def pattern(self) -> ScanPattern:
        """The pattern under test (override to test an unregistered or parametrised pattern)."""
        from ..plugins.resolve import get_sensor, pattern_for
        from ..scenario.datasheet import SensorDatasheet

        if self.sensor is None:
            pytest.skip("set `sensor` or override the `pattern` fixture")
        sheet = self.sensor if isinstance(self.sensor, SensorDatasheet) else \
            get_sensor(self.sensor)
        return pattern_for(sheet, dict(self.pattern_options))

    def interval(self, pattern: ScanPattern) -> tuple[float, float]:
        """The checked interval: at least ``duration_s`` and two firing cycles long."""
        cycles = 2.0 * _cycle_size(pattern) / _mean_rate(pattern)
        return self.start_s, self.start_s + max(self.duration_s, cycles)

    @pytest.fixture
    def batch(self, pattern: ScanPattern) -> RayBatch:
        """Every ray of :meth:`interval`, generated at once."""
        return pattern.rays(*self.interval(pattern))

    # ---- geometry ------------------------------------------------------------------------
    def test_emits_rays(self, batch: RayBatch) -> None:
        assert len(batch) > 0, "the pattern emitted no ray in the checked interval"

    def test_unit_directions(self, batch: RayBatch) -> None:
        assert batch.direction.dtype == np.float64 and batch.direction.shape == (len(batch), 3)
        assert np.all(np.isfinite(batch.direction)), "non-finite direction"
        norms = np.linalg.norm(batch.direction, axis=1)
        worst = int(np.argmax(np.abs(norms - 1)))
        assert abs(norms[worst] - 1) < TOL, f"ray {batch.index[worst]} has length {norms[worst]!r}"

    def test_inside_declared_fov(self, pattern: ScanPattern, batch: RayBatch) -> None:
        inside = pattern.inside_fov(batch.direction, TOL)
        bad = np.flatnonzero(~inside)
        assert len(bad) == 0, (f"{len(bad)} rays outside the datasheet FOV, e.g. ray "
                               f"{batch.index[bad[0]]} direction {batch.direction[bad[0]]}")

    # ---- timing --------------------------------------------------------------------------
    def test_indices_contiguous(self, pattern: ScanPattern, batch: RayBatch) -> None:
        k0, k1 = pattern.index_range(*self.interval(pattern))
        np.testing.assert_array_equal(batch.index, np.arange(k0, k1))
        assert batch.index.dtype == np.int64

    def test_times_in_interval_and_ordered(self, pattern: ScanPattern, batch: RayBatch) -> None:
        t0, t1 = self.interval(pattern)
        assert batch.t.dtype == np.float64 and np.all(np.isfinite(batch.t))
        assert batch.t.min() >= t0 - 1e-12 and batch.t.max() < t1, "time outside the interval"
        assert np.all(np.diff(batch.t) >= 0), "times decrease with the ray index"
        np.testing.assert_array_equal(batch.t, pattern.time_of_index(batch.index))

    def test_monotonic_per_channel(self, batch: RayBatch) -> None:
        for ch in np.unique(batch.channel):
            t = batch.t[batch.channel == ch]
            assert np.all(np.diff(t) >= 0), f"channel {ch}: times go backwards"

    def test_rate_matches_datasheet(self, pattern: ScanPattern) -> None:
        rate = _mean_rate(pattern)
        assert rate <= pattern.sensor.point_rate_hz * (1 + 1e-3), \
            f"mean rate {rate:.6g}/s exceeds the datasheet point rate"
        t0, t1 = self.interval(pattern)
        k0, k1 = pattern.index_range(t0, t1)
        expected = rate * (t1 - t0)
        assert abs((k1 - k0) - expected) <= _cycle_size(pattern) + 1, \
            f"{k1 - k0} rays in {t1 - t0:g} s, expected {expected:.1f} at {rate:.6g}/s"

    def test_channels(self, batch: RayBatch) -> None:
        assert batch.channel.dtype == np.int16 and batch.channel.shape == (len(batch),)
        assert batch.channel.min() >= 0

    # ---- purity --------------------------------------------------------------------------
    def test_chunking_invariance(self, pattern: ScanPattern, batch: RayBatch) -> None:
        t0, t1 = self.interval(pattern)
        cuts = np.sort(np.random.default_rng(7).uniform(t0, t1, 5))
        edges = [t0, *cuts.tolist(), t1]
        _same(_concat([pattern.rays(a, b) for a, b in zip(edges[:-1], edges[1:])]), batch)

    def test_index_subsets(self, pattern: ScanPattern, batch: RayBatch) -> None:
        pick = np.random.default_rng(11).permutation(len(batch))[: max(1, len(batch) // 3)]
        part = pattern.rays_for_indices(batch.index[pick])
        _same(part, RayBatch(batch.index[pick], batch.t[pick], batch.direction[pick],
                             batch.channel[pick]))

    def test_determinism(self, pattern: ScanPattern, batch: RayBatch) -> None:
        fresh = type(pattern)(pattern.options, pattern.sensor)
        _same(fresh.rays(*self.interval(pattern)), batch)

    def test_empty_interval(self, pattern: ScanPattern) -> None:
        t0, _ = self.interval(pattern)
        assert len(pattern.rays(t0, t0)) == 0
