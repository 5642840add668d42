"""Messages that help: a misspelled key names the key it resembles, a list of the wrong length
says how many values it needs, a mesh in millimetres gets a warning that suggests ``scale``."""

from __future__ import annotations

import copy
import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
import yaml

BASE = {
    "seed": 1,
    "sensor": {"datasheet": "livox-mid70-rose", "pose": {"position_m": [0, 0, 0]}},
    "targets": [{"name": "sat", "mesh": {"model": "envisat", "options": {"detail": "coarse"}},
                 "pose": {"position_m": [30, 0, 0]}}],
    "scan": {"duration_s": 0.02},
    "backend": "numpy",
}


def _message(data: dict) -> str:
    from lidarsim_core.base.errors import ConfigError
    from lidarsim_core.scenario import scenario_from_dict

    with pytest.raises(ConfigError) as info:
        scenario_from_dict(data, source="scene.yaml")
    assert "\n" not in str(info.value)
    return str(info.value)


def test_misspelled_top_level_key_suggests_the_right_one():
    data = copy.deepcopy(BASE)
    data["targts"] = data.pop("targets")
    assert _message(data) == ("scene.yaml: field 'targts': unknown key 'targts' "
                              "(did you mean 'targets'?)")


def test_wrong_unit_suffix_suggests_the_right_one():
    data = copy.deepcopy(BASE)
    data["targets"][0]["pose"] = {"position_mm": [30000, 0, 0]}
    assert _message(data) == ("scene.yaml: field 'targets.0.pose.position_mm': unknown key "
                              "'position_mm' (did you mean 'position_m'?)")


def test_misspelled_nested_key_suggests_and_unknown_key_lists_the_known_ones():
    data = copy.deepcopy(BASE)
    data["scan"] = {"duraton_s": 1.0}
    assert "unknown key 'duraton_s' (did you mean 'duration_s'?)" in _message(data)
    data["scan"] = {"duration_s": 1.0, "zzz": 1}
    message = _message(data)
    assert "field 'scan.zzz': unknown key 'zzz'; known keys: duration_s, " in message


@pytest.mark.parametrize("values, got", [([30, 20], 2), ([30, 20, 10, 5], 4), ([30], 1)])
def test_euler_angles_of_the_wrong_length_say_how_many_are_needed(values, got):
    data = copy.deepcopy(BASE)
    data["targets"][0]["pose"]["euler_deg"] = values
    assert _message(data) == (f"scene.yaml: field 'targets.0.pose.euler_deg': needs 3 values, "
                              f"got {got}")


def test_component_option_typo_suggests_the_option():
    from lidarsim_core.base.errors import ConfigError
    from lidarsim_core.pipeline import Simulation
    from lidarsim_core.scenario import scenario_from_dict

    data = copy.deepcopy(BASE)
    data["targets"][0]["mesh"]["options"] = {"detial": "coarse"}
    with pytest.raises(ConfigError, match=r"unknown key 'detial' \(did you mean 'detail'\?\)"):
        Simulation(scenario_from_dict(data))


# ---- a mesh in the wrong unit ----------------------------------------------------------------
def _box_stl(path: Path, extents_m: tuple[float, float, float]) -> Path:
    import trimesh

    trimesh.creation.box(extents=extents_m).export(path)
    return path


def _scene_with_mesh(tmp_path: Path, extents, scale: float | None = None) -> Path:
    mesh = {"path": str(_box_stl(tmp_path / "satellite.stl", extents))}
    if scale is not None:
        mesh["scale"] = scale
    data = copy.deepcopy(BASE)
    data["targets"][0]["mesh"] = mesh
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_a_mesh_in_millimetres_warns_and_suggests_scale(tmp_path):
    from lidarsim_core.pipeline import Simulation
    from lidarsim_core.pipeline.units import UnitsWarning
    from lidarsim_core.scenario import load_scenario

    scene = _scene_with_mesh(tmp_path, (8000.0, 3000.0, 3000.0))  # an 8 m bus, in mm
    with pytest.warns(UnitsWarning) as record:
        Simulation(load_scenario(scene))
    (message,) = [str(w.message) for w in record]
    assert "target 'sat' is 8,000 m across, larger than any spacecraft" in message
    assert "and the sensor is inside it" in message  # the box spans ±4 km around x = 30 m
    assert "add 'scale: 0.001' to targets.0.mesh" in message

    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", "COLUMNS": "80"}
    res = subprocess.run([sys.executable, "-m", "lidarsim_core", "simulate", str(scene),
                          "--out", str(tmp_path / "c.npz")], env=env, capture_output=True,
                         text=True, timeout=300)
    warning_lines = [ln for ln in res.stderr.splitlines() if ln.startswith("warning:")]
    assert len(warning_lines) == 1 and "scale: 0.001" in warning_lines[0], res.stderr


def test_the_same_mesh_scaled_to_metres_gives_no_warning(tmp_path):
    from lidarsim_core.pipeline import Simulation
    from lidarsim_core.scenario import load_scenario

    scene = _scene_with_mesh(tmp_path, (8000.0, 3000.0, 3000.0), scale=0.001)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim = Simulation(load_scenario(scene))
    assert len(sim.run_frame(0)) > 0


def test_sensor_inside_a_file_mesh_warns_even_when_its_size_is_plausible(tmp_path):
    from lidarsim_core.pipeline import Simulation
    from lidarsim_core.pipeline.units import UnitsWarning
    from lidarsim_core.scenario import load_scenario

    scene = _scene_with_mesh(tmp_path, (100.0, 100.0, 100.0))  # 100 m: the sensor is inside
    with pytest.warns(UnitsWarning, match="sensor is inside the bounding box of target 'sat'"):
        Simulation(load_scenario(scene))
