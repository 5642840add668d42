"""FOV coverage and point density, and the `lidarsim pattern` / `lidarsim coverage` commands."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from patterns_support import build, make_sheet
from typer.testing import CliRunner

import lidarsim_core.cli.patterns  # noqa: F401  (registers the commands on the app)
from lidarsim_core.cli import app
from lidarsim_core.patterns.fov import fov_coverage
from lidarsim_core.plugins.resolve import get_sensor, pattern_for

#: The MID-70 (Risley) coverage on 0.5° cells stated in docs/patterns.md and docs/sensors.md.
MID70_DOCUMENTED = {0.1: 0.194, 0.5: 0.686, 1.0: 0.924}


@pytest.fixture(scope="module")
def mid70():
    return pattern_for(get_sensor("livox-mid70"))


@pytest.mark.parametrize("seconds", sorted(MID70_DOCUMENTED))
def test_mid70_coverage_matches_the_documented_figures(mid70, seconds):
    report = fov_coverage(mid70, seconds, 0.5)
    assert report.coverage == pytest.approx(MID70_DOCUMENTED[seconds], abs=0.0015)
    assert report.rays == round(100_000 * seconds)


def test_coverage_grows_with_integration_time(mid70):
    values = [fov_coverage(mid70, s, 0.5).coverage for s in (0.05, 0.1, 0.2, 0.4)]
    assert values == sorted(values) and values[0] < values[-1]


def test_circular_fov_cells_add_up_to_the_cone_solid_angle(mid70):
    report = fov_coverage(mid70, 0.01, 0.5)
    cone = 2 * math.pi * (1 - math.cos(math.radians(35.2))) * (180 / math.pi) ** 2
    assert sum(b.solid_angle_deg2 for b in report.density) == pytest.approx(cone, rel=0.01)
    assert sum(b.points for b in report.density) == report.rays


def test_vlp16_rings_cover_16_of_61_cell_rows():
    """16 rings, each swept all round (0.2° steps < 0.5° cells), on 61 rows of 0.5° cells."""
    report = fov_coverage(pattern_for(get_sensor("velodyne-vlp16")), 0.1, 0.5)
    assert report.cells_in_fov == 720 * 61
    assert report.coverage == pytest.approx(16 / 61, abs=1e-12)


def test_raster_finer_than_the_cells_covers_everything():
    sheet = make_sheet("raster", {"row_step_deg": 0.4, "column_step_deg": 0.4},
                       fov_type="rectangular", fov_h_deg=10.0, fov_v_deg=8.0, rate=10_000.0)
    pattern = build(sheet)
    period = pattern.cycle.period_s
    assert fov_coverage(pattern, period, 0.5).coverage == 1.0
    # half a frame (top rows only) covers about half the FOV
    assert fov_coverage(pattern, period / 2, 0.5).coverage == pytest.approx(0.5, abs=0.08)


def test_uniform_density_of_a_flash_array():
    """An equiangular flash array has nearly the same density at every off-axis angle."""
    sheet = make_sheet("flash", {"rows": 200, "columns": 200, "projection": "equiangular"},
                       fov_type="rectangular", fov_h_deg=10.0, fov_v_deg=10.0, rate=40_000.0)
    report = fov_coverage(build(sheet), 1.0, 0.25, bin_deg=1.0)
    inner = [b.points_per_deg2 for b in report.density if b.off_axis_hi_deg <= 4]
    assert np.allclose(inner, 400.0, rtol=0.05)  # 200 × 200 pixels over 10° × 10°


def test_cli_coverage_json(tmp_path):
    result = CliRunner().invoke(app, ["coverage", "livox-mid70", "--time", "0.1", "--cell-deg",
                                      "0.5", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["coverage"] == pytest.approx(MID70_DOCUMENTED[0.1], abs=0.0015)
    assert data["cells_in_fov"] > 0 and data["density"]


def test_cli_pattern_export(tmp_path):
    out = tmp_path / "rays.npz"
    result = CliRunner().invoke(app, ["pattern", "velodyne-vlp16", "--duration", "0.001",
                                      "--out", str(out)])
    assert result.exit_code == 0, result.output
    with np.load(out) as data:
        t, d, ch = data["t"], data["direction"], data["channel"]
    expected = pattern_for(get_sensor("velodyne-vlp16")).rays(0.0, 0.001)
    np.testing.assert_array_equal(t, expected.t)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    np.testing.assert_array_equal(ch, expected.channel)
    again = CliRunner().invoke(app, ["pattern", "velodyne-vlp16", "--duration", "0.001",
                                     "--out", str(out)])
    assert again.exit_code == 2 and "exists" in again.output


@pytest.mark.parametrize("args, message", [
    (["coverage", "no-such-sensor", "--time", "1"], "unknown sensor 'no-such-sensor'"),
    (["coverage", "livox-mid70", "--time", "0"], "--time must be > 0"),
    (["pattern", "livox-mid70", "--duration", "1", "--out", "x.ply"], "written as .npz"),
    (["coverage", "livox-mid70", "--time", "1", "--option", "refractive_index=0.5"],
     "scan_pattern.options.refractive_index"),
])
def test_cli_user_errors_exit_2(args, message):
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2
    assert message in result.output
