"""LAS intensity does not clip: the 16-bit field holds ``round(intensity / s)`` with the file's
scale ``s = max(1, brightest) / 65535`` (VLR ``lidarsim``/4), checked with laspy on the demo
(a quarter of its returns are brighter than reflectivity 1) and on a retro-reflective Envisat
(returns hundreds of times brighter than a white surface)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import lidarsim_core as ls
from lidarsim_core.io.las import UNIT_INTENSITY_SCALE, intensity_scale
from lidarsim_core.plugins.shortcuts import write_cloud
from lidarsim_core.scenario import scenario_from_dict
from lidarsim_core.scenario.load import load_scenario

laspy = pytest.importorskip("laspy")


EXAMPLE = Path(__file__).parents[1] / "examples" / "envisat_mid70.yaml"


def _scene(retro: bool) -> ls.PointCloud:
    """The README's example scenario (Envisat face-on: glints on the solar array), 0.1 s; or
    the coarse demo scene with every part a corner-cube retro-reflector."""
    if not retro:
        scenario = load_scenario(EXAMPLE).with_updates(scan={"duration_s": 0.1},
                                                       backend={"name": "numpy"})
        return ls.Simulation(scenario).run_frame(0)
    data = ls.demo_scenario(duration_s=0.05, backend="numpy", detail="coarse",
                            seed=3).model_dump()
    data["sensor"]["detection"] = {}  # the calibrated link budget: intensity = S R^n / C
    data["targets"][0]["materials"] = {"*": "retroreflector"}
    return ls.Simulation(scenario_from_dict(data)).run_frame(0)


def _scale(las) -> float:
    records = [bytes(v.record_data) for v in las.header.vlrs
               if (v.user_id, v.record_id) == ("lidarsim", 4)]
    assert len(records) == 1
    return json.loads(records[0])["intensity_scale"]


@pytest.mark.parametrize("retro", [False, True], ids=["demo", "retro-reflective"])
def test_las_intensity_keeps_every_return_below_the_top(retro, tmp_path):
    cloud = _scene(retro)
    values = cloud["intensity"].astype(np.float64)
    brightest = values.max()
    # both scenes really hold returns beyond what 0..1 could hold
    assert brightest > (100 if retro else 10) and (values > 1).sum() >= 5
    las = laspy.read(str(write_cloud(cloud, tmp_path / "c.las")))
    scale = _scale(las)
    assert scale == intensity_scale(brightest) == max(1.0, brightest) / 65535
    counts = np.asarray(las.intensity).astype(np.float64)
    # nothing clipped: only the brightest return reads 65535 (ties included)
    assert np.array_equal(counts == 65535, values == brightest)
    # intensity × scale is the float intensity within half a step, 1/131070 of the top
    error = np.abs(counts * scale - values)
    assert error.max() <= scale / 2 * (1 + 1e-9)
    assert error.max() / max(1.0, brightest) <= 1 / 65535
    # the exact value in the extra bytes, and ls.read gives it back
    np.testing.assert_array_equal(las["reflectivity"], cloud["intensity"])
    np.testing.assert_array_equal(ls.read(tmp_path / "c.las")["intensity"], cloud["intensity"])


def test_las_intensity_of_dim_clouds_keeps_65535_as_reflectivity_1(tmp_path):
    cloud = _scene(False)
    dim = ls.PointCloud({**cloud.columns,
                         "intensity": np.linspace(0, 1, len(cloud)).astype(np.float32)},
                        cloud.frame)
    las = laspy.read(str(write_cloud(dim, tmp_path / "c.las")))
    assert _scale(las) == UNIT_INTENSITY_SCALE
    np.testing.assert_array_equal(las.intensity,
                                  np.round(dim["intensity"].astype(np.float64) * 65535))


def test_las_intensity_without_the_exact_copy_uses_the_scale(tmp_path):
    """A reader that has only the standard field (the extra bytes dropped, as a LAS 1.2
    conversion does) gets the intensity back from the scale VLR."""
    from lidarsim_core.io.las import read_las_columns

    cloud = _scene(True)
    path = write_cloud(cloud, tmp_path / "c.las")
    las = laspy.read(str(path))
    stripped = laspy.LasData(laspy.LasHeader(point_format=6, version="1.4"))
    stripped.header.vlrs.extend(v for v in las.header.vlrs if v.user_id == "lidarsim")
    stripped.header.scales, stripped.header.offsets = las.header.scales, las.header.offsets
    for name in ("X", "Y", "Z", "intensity", "gps_time", "return_number",
                 "number_of_returns", "classification"):
        stripped[name] = las[name]
    stripped.write(str(tmp_path / "s.las"))
    columns, _ = read_las_columns(tmp_path / "s.las")
    scale = _scale(las)
    assert np.abs(columns["intensity"] - cloud["intensity"]).max() <= scale / 2 * (1 + 1e-6)


def test_bad_intensity_scale_record_is_named(tmp_path):
    from lidarsim_core.io.las import read_intensity_scale

    for record in (b"{}", b'{"intensity_scale": -1}', b"\xff", b'{"intensity_scale": "x"}'):
        with pytest.raises(ls.ConfigError, match=r"c\.las.*lidarsim/4"):
            read_intensity_scale(record, tmp_path / "c.las")
