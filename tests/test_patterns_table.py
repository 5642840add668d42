"""Table patterns: Livox scan-mode CSV and generic CSV/NPY files, and clear errors on bad files."""

from __future__ import annotations

import numpy as np
import pytest
from patterns_support import build, make_sheet
from typer.testing import CliRunner

from lidarsim_core.base.errors import ConfigError, PatternFileError
from lidarsim_core.cli import app
from lidarsim_core.patterns.geometry import az_el_from_directions
from lidarsim_core.patterns.table_io import read_pattern_table
from lidarsim_core.plugins.resolve import get_sensor, pattern_for
from lidarsim_core.scenario.datasheet import SensorDatasheet

RECT = dict(fov_type="rectangular", fov_h_deg=40.0, fov_v_deg=30.0, rate=10_000.0)


def _write_livox(path, t, az, zen):
    rows = "\n".join(f"{a:.17g},{b:.17g},{c:.17g}" for a, b, c in zip(t, az, zen))
    path.write_text("Time/s,Azimuth/deg,Zenith/deg\n" + rows + "\n")
    return path


def test_livox_scan_mode_file_reproduces_the_mid70_rays(tmp_path):
    """Export the Risley MID-70 in Livox's format, read it back as a table pattern."""
    mid70 = pattern_for(get_sensor("livox-mid70"))
    src = mid70.rays(0.0, 0.01)
    az, el = np.degrees(az_el_from_directions(src.direction))
    path = _write_livox(tmp_path / "mid70.csv", src.t, az, 90.0 - el)
    data = get_sensor("livox-mid70").model_dump()
    data["scan_pattern"] = {"name": "table", "options": {"path": str(path)}}
    table = build(SensorDatasheet.model_validate(data))
    again = table.rays(0.0, 0.01)
    np.testing.assert_allclose(again.direction, src.direction, atol=1e-12)
    np.testing.assert_allclose(again.t, src.t, atol=1e-12)
    # the table repeats: its period is the span plus one step
    assert table.cycle.period_s == pytest.approx(0.01)
    np.testing.assert_allclose(table.rays(0.01, 0.02).direction, src.direction, atol=1e-12)


def test_generic_csv_with_channels_and_any_column_order(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text("channel,elevation_deg,azimuth_deg,time_s\n"
                    "0,1.0,2.0,0.5\n1,-1.0,3.0,0.5\n0,0.0,-4.0,0.6\n")
    table = read_pattern_table(path)
    np.testing.assert_allclose(table.t, [0.0, 0.0, 0.1])  # relative to the first row
    np.testing.assert_allclose(np.degrees(table.azimuth), [2, 3, -4])
    np.testing.assert_array_equal(table.channel, [0, 1, 0])
    pattern = build(make_sheet("table", {"path": str(path)}, **RECT))
    batch = pattern.rays(0.0, 0.4)  # period = span 0.1 s + median step 0.1 s = 0.2 s
    np.testing.assert_allclose(batch.t, [0, 0, 0.1, 0.2, 0.2, 0.3])
    np.testing.assert_array_equal(batch.channel, [0, 1, 0, 0, 1, 0])


@pytest.mark.parametrize("structured", [False, True])
def test_npy_tables(tmp_path, structured):
    t = np.array([0.0, 1e-4, 2e-4])
    az, el, ch = np.array([1.0, 2.0, 3.0]), np.array([-1.0, 0.0, 1.0]), np.array([0, 1, 2])
    if structured:
        arr = np.zeros(3, dtype=[("t_s", "f8"), ("azimuth_deg", "f8"), ("elevation_deg", "f8"),
                                 ("channel", "i4")])
        arr["t_s"], arr["azimuth_deg"], arr["elevation_deg"], arr["channel"] = t, az, el, ch
    else:
        arr = np.stack([t, az, el, ch], axis=1)
    np.save(tmp_path / "p.npy", arr)
    pattern = build(make_sheet("table", {"path": str(tmp_path / "p.npy")}, **RECT))
    batch = pattern.rays(0.0, 3e-4)
    got_az, got_el = np.degrees(az_el_from_directions(batch.direction))
    np.testing.assert_allclose(got_az, az, atol=1e-12)
    np.testing.assert_allclose(got_el, el, atol=1e-12)
    np.testing.assert_array_equal(batch.channel, ch)


LIVOX_HEADER = "Time/s,Azimuth/deg,Zenith/deg\n"


@pytest.mark.parametrize("name, text, message", [
    ("wrong_columns.csv", "time,x,y\n0,1,2\n", "unknown column 'time'"),
    ("missing.csv", "t_s,azimuth_deg\n0,1\n", "missing column(s) elevation_deg"),
    ("non_numeric.csv", LIVOX_HEADER + "0,1,90\n0.1,abc,90\n", "line 3: 'abc' is not a number"),
    ("empty.csv", "", "the file is empty"),
    ("header_only.csv", LIVOX_HEADER, "no data rows"),
    ("ragged.csv", LIVOX_HEADER + "0,1\n", "line 2 has 2 fields, expected 3"),
    ("zenith_range.csv", LIVOX_HEADER + "0,1,90\n0.1,1,181\n", "181 is outside [0, 180]"),
    ("elevation_range.csv", "t_s,azimuth_deg,elevation_deg\n0,0,95\n", "95 is outside [-90, 90]"),
    ("nan.csv", "t_s,azimuth_deg,elevation_deg\n0,nan,1\n", "is not finite"),
    ("backwards.csv", "t_s,azimuth_deg,elevation_deg\n0,0,0\n1,0,0\n0.5,0,0\n",
     "line 4: time 0.5 s is before"),
    ("bad_channel.csv", "t_s,azimuth_deg,elevation_deg,channel\n0,0,0,1.5\n",
     "channel 1.5 is not an integer"),
    ("outside_fov.csv", "t_s,azimuth_deg,elevation_deg\n0,0,0\n1e-4,25,0\n",
     "row 1 (azimuth 25°, elevation 0°) is outside the datasheet's FOV"),
])
def test_bad_pattern_files_give_a_clear_error(tmp_path, name, text, message):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(PatternFileError) as info:
        build(make_sheet("table", {"path": str(path)}, **RECT))
    assert message in str(info.value)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("arr, message", [
    (np.zeros((0, 3)), "no rows"),
    (np.zeros((4, 2)), "expected (N, 3) or (N, 4)"),
    (np.array([["0", "1", "2"]]), "not numeric"),
])
def test_bad_npy_files(tmp_path, arr, message):
    np.save(tmp_path / "bad.npy", arr)
    with pytest.raises(PatternFileError, match=message.replace("(", r"\(").replace(")", r"\)")):
        read_pattern_table(tmp_path / "bad.npy")


def test_missing_file_and_short_period(tmp_path):
    with pytest.raises(PatternFileError, match="pattern file not found"):
        read_pattern_table(tmp_path / "nope.csv")
    path = _write_livox(tmp_path / "ok.csv", [0.0, 0.5], [0.0, 1.0], [90.0, 91.0])
    with pytest.raises(PatternFileError, match="must exceed the table's time span"):
        build(make_sheet("table", {"path": str(path), "period_s": 0.5}, **RECT))
    with pytest.raises(ConfigError, match="unknown key"):
        build(make_sheet("table", {"path": str(path), "colour": "red"}, **RECT))


def test_cli_reports_a_bad_table_in_one_line(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text(LIVOX_HEADER + "0,1,90\n0.1,oops,90\n")
    sheet = make_sheet("table", {"path": str(bad)}, name="vendor-x", **RECT)
    sheet_file = tmp_path / "vendor-x.yaml"
    sheet_file.write_text(sheet.model_dump_json())  # JSON is valid YAML
    import lidarsim_core.cli.patterns  # noqa: F401  (registers the command)

    result = CliRunner().invoke(app, ["coverage", str(sheet_file), "--time", "0.1"])
    assert result.exit_code == 2
    lines = [ln for ln in result.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "line 3: 'oops' is not a number" in lines[0]
    assert str(bad) in lines[0]
