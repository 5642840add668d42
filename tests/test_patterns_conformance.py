"""The shipped pattern conformance suite, run on every catalogue sensor and on pattern variants
that the catalogue does not exercise (other line orders, firing modes, projections, tables)."""

from __future__ import annotations

import numpy as np
import pytest
from patterns_support import build, make_sheet

from lidarsim_core.plugins import get_registry
from lidarsim_core.plugins.resolve import get_sensor, pattern_for
from lidarsim_core.testing.patterns import PatternConformance

CATALOGUE = get_registry().names("sensor")


class TestCatalogueConformance(PatternConformance):
    """Every built-in datasheet's pattern."""

    @pytest.fixture(params=CATALOGUE)
    def pattern(self, request):
        return pattern_for(get_sensor(request.param))


def _variants() -> dict[str, object]:
    rect = dict(fov_type="rectangular", fov_h_deg=30.0, fov_v_deg=20.0, rate=20_000.0)
    return {
        "raster-vertical-unidirectional": lambda: build(make_sheet(
            "raster", {"rows": 7, "columns": 9, "line_axis": "vertical", "bidirectional": False,
                       "line_retrace_s": 1e-4, "frame_retrace_s": 2e-3}, **rect)),
        "raster-steps-frame-rate": lambda: build(make_sheet(
            "raster", {"row_step_deg": 0.7, "column_step_deg": 1.3, "frame_rate_hz": 25},
            fov_v_center_deg=-5.0, **rect)),
        "lissajous-offcentre": lambda: build(make_sheet(
            "lissajous", {"azimuth_hz": 13.5, "elevation_hz": 7.25,
                          "elevation_amplitude_deg": 6.0}, fov_v_center_deg=4.0, **rect)),
        "flash-equiangular": lambda: build(make_sheet(
            "flash", {"rows": 16, "columns": 24, "projection": "equiangular"},
            fov_v_center_deg=3.0, **{**rect, "rate": 16 * 24 * 50.0})),
        "spinning-pairs": lambda: build(make_sheet(
            "spinning", {"elevations_deg": [-10, -5, 0, 5], "firing_order": [3, 1, 0, 2],
                         "lasers_per_firing": 2, "firing_interval_s": 3e-6,
                         "azimuth_offsets_deg": [1, -1, 1, -1], "clockwise": False},
            fov_type="panoramic", fov_h_deg=360, fov_v_deg=20.0, rate=4 / 20e-6)),
        "risley-simultaneous-channels": lambda: build(make_sheet(
            "risley", {"prisms": [{"wedge_deg": 10, "rotor_hz": 50.5},
                                  {"wedge_deg": -9, "rotor_hz": -31.25, "wedge_face": "entrance",
                                   "phase_deg": 40}],
                       "channels": [{"elevation_deg": -1}, {"elevation_deg": 1,
                                                             "azimuth_deg": 0.5}],
                       "channel_firing": "simultaneous"}, fov_h_deg=25.0, rate=50_000.0)),
    }


VARIANTS = _variants()


class TestVariantConformance(PatternConformance):
    """Pattern options the catalogue does not use."""

    @pytest.fixture(params=sorted(VARIANTS))
    def pattern(self, request):
        return VARIANTS[request.param]()


class TestTableConformance(PatternConformance):
    """A Livox scan-mode table, repeated."""

    @pytest.fixture
    def pattern(self, tmp_path):
        t = np.arange(500) / 10_000.0
        az = 20 * np.sin(2 * np.pi * 37 * t)
        zen = 90 - 15 * np.sin(2 * np.pi * 23 * t)
        path = tmp_path / "mode.csv"
        rows = "\n".join(f"{a:.9f},{b:.9f},{c:.9f}" for a, b, c in zip(t, az, zen))
        path.write_text("Time/s,Azimuth/deg,Zenith/deg\n" + rows + "\n")
        return build(make_sheet("table", {"path": str(path)}, fov_type="rectangular",
                                fov_h_deg=40.0, fov_v_deg=30.0))


BROKEN_PATTERNS = '''
import numpy as np
import pytest

from lidarsim_core.patterns.base import RayBatch, ScanPattern
from lidarsim_core.testing.patterns import PatternConformance
from patterns_support import make_sheet

SHEET = make_sheet("rose", fov_h_deg=20.0)


class Unnormalised(ScanPattern):
    name = "unnormalised"

    def rays_for_indices(self, index):
        t = self.time_of_index(index)
        d = np.tile([2.0, 0.0, 0.0], (len(index), 1))
        return RayBatch(index, t, d, np.zeros(len(index), np.int16))


class OutsideFov(ScanPattern):
    name = "outside"

    def rays_for_indices(self, index):
        t = self.time_of_index(index)
        d = np.tile([0.0, 1.0, 0.0], (len(index), 1))
        return RayBatch(index, t, d, np.zeros(len(index), np.int16))


class StatefulTime(ScanPattern):
    """Time depends on call history, so chunking changes the rays."""

    name = "stateful"
    calls = 0

    def rays_for_indices(self, index):
        type(self).calls += 1
        t = self.time_of_index(index) + 1e-3 * (type(self).calls % 2)
        d = np.tile([1.0, 0.0, 0.0], (len(index), 1))
        return RayBatch(index, t, d, np.zeros(len(index), np.int16))


class TestUnnormalised(PatternConformance):
    @pytest.fixture
    def pattern(self):
        return Unnormalised(None, SHEET)


class TestOutside(PatternConformance):
    @pytest.fixture
    def pattern(self):
        return OutsideFov(None, SHEET)


class TestStateful(PatternConformance):
    @pytest.fixture
    def pattern(self):
        return StatefulTime(None, SHEET)
'''


def test_suite_catches_broken_patterns(pytester):
    """The suite must fail exactly the checks a broken pattern violates."""
    import pathlib

    pytester.syspathinsert(str(pathlib.Path(__file__).parent))
    pytester.makepyfile(test_broken=BROKEN_PATTERNS)
    result = pytester.runpytest("-q", "-p", "no:cacheprovider")
    reports = result.reprec.getreports("pytest_runtest_logreport")
    failed = {r.nodeid.split("::", 1)[1] for r in reports if r.failed}
    assert "TestUnnormalised::test_unit_directions" in failed
    assert "TestOutside::test_inside_declared_fov" in failed
    assert "TestOutside::test_unit_directions" not in failed
    assert {"TestStateful::test_chunking_invariance", "TestStateful::test_determinism"} <= failed
