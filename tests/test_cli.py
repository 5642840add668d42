"""The command line: demo, simulate, listings, schemas, and one-line errors with exit code 2."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from helpers import CLI_SCENARIO as GOOD_SCENARIO


def run_cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", "COLUMNS": "200"}
    return subprocess.run([sys.executable, "-m", "lidarsim_core", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def write_yaml(path: Path, data) -> Path:
    path.write_text(yaml.safe_dump(data) if not isinstance(data, str) else data)
    return path


def test_demo_writes_clouds_with_and_without_errors(tmp_path):
    out = tmp_path / "demo"
    res = run_cli("demo", "--out", str(out), "--duration", "0.2", "--backend", "numpy")
    assert res.returncode == 0, res.stderr
    names = {p.name for p in out.iterdir()}
    assert {"envisat_mid70_with_errors.ply", "envisat_mid70_without_errors.ply",
            "envisat_mid70_with_errors.npz", "scenario.yaml"} <= names
    assert "with errors" in res.stdout and "rays/s" in res.stdout
    noisy = np.load(out / "envisat_mid70_with_errors.npz")
    clean = np.load(out / "envisat_mid70_without_errors.npz")
    assert len(noisy["x"]) > 1000 and len(clean["x"]) > 1000
    assert np.std(noisy["range"] - noisy["range_true"]) > 0.01
    np.testing.assert_array_equal(clean["range"], clean["range_true"])
    # the scenario the demo wrote reproduces its noisy cloud
    res2 = run_cli("simulate", str(out / "scenario.yaml"), "--out", str(tmp_path / "again.npz"))
    assert res2.returncode == 0, res2.stderr
    again = np.load(tmp_path / "again.npz")
    np.testing.assert_array_equal(again["x"], noisy["x"])


def test_simulate_writes_ply_readable_by_plyfile(tmp_path):
    plyfile = pytest.importorskip("plyfile")
    scen = write_yaml(tmp_path / "s.yaml", GOOD_SCENARIO)
    res = run_cli("simulate", str(scen), "--out", str(tmp_path / "c.ply"))
    assert res.returncode == 0, res.stderr
    ply = plyfile.PlyData.read(str(tmp_path / "c.ply"))
    vertex = ply["vertex"]
    assert vertex.count > 100
    names = {p.name for p in vertex.properties}
    assert {"x", "y", "z", "x_true", "range", "timestamp", "part", "incidence_angle",
            "ray_index"} <= names
    frame = json.loads("".join(c.split(" ", 1)[1] for c in ply.comments
                               if c.startswith("lidarsim-frame ")))
    assert frame["sensor"] == "livox-mid70-rose" and frame["seed"] == 1
    r = np.sqrt(vertex["x"] ** 2 + vertex["y"] ** 2 + vertex["z"] ** 2)
    np.testing.assert_allclose(r, vertex["range"], rtol=1e-12)


def test_refuses_to_overwrite_without_flag(tmp_path):
    scen = write_yaml(tmp_path / "s.yaml", GOOD_SCENARIO)
    target = tmp_path / "c.npz"
    target.write_bytes(b"keep me")
    res = run_cli("simulate", str(scen), "--out", str(target))
    assert res.returncode == 2 and "exists" in res.stderr
    assert target.read_bytes() == b"keep me"
    assert run_cli("simulate", str(scen), "--out", str(target), "--overwrite").returncode == 0
    assert np.load(target)["x"].size > 0


def _bad(tmp_path: Path, name: str, text_or_data) -> Path:
    return write_yaml(tmp_path / name, text_or_data)


def _with(path: list[str], value) -> dict:
    data = json.loads(json.dumps(GOOD_SCENARIO))
    node = data
    for key in path[:-1]:
        node = node[int(key)] if isinstance(node, list) else node[key]
    node[path[-1]] = value
    return data


BAD_CASES = {
    "malformed_yaml": ("sensor: [unclosed\n", ["malformed YAML", "line"]),
    "unknown_key": (_with(["scan", "durration_s"], 1.0), ["scan.durration_s", "unknown key"]),
    "negative_precision": (_with(["sensor", "datasheet"], {
        "name": "x", "manufacturer": "m", "model": "m", "sources": [{"title": "t"}],
        "fov_type": "circular", "fov_h_deg": 30, "fov_v_deg": 30, "range_max_m": 100,
        "range_precision_m": -0.02, "angular_precision_deg": 0.1, "point_rate_hz": 1000,
        "scan_pattern": {"name": "rose"}}), ["sensor.datasheet.range_precision_m"]),
    "missing_mesh": (_with(["targets", "0", "mesh"], {"path": "nope/envisat.stl"}),
                     ["targets.0.mesh.path", "not found"]),
    "unknown_backend": (_with(["backend"], "optix"), ["backend.name", "unknown ray backend",
                                                      "numpy"]),
    "unknown_pattern": (_with(["sensor", "datasheet"], {
        "name": "x", "manufacturer": "m", "model": "m", "sources": [{"title": "t"}],
        "fov_type": "circular", "fov_h_deg": 30, "fov_v_deg": 30, "range_max_m": 100,
        "range_precision_m": 0.02, "angular_precision_deg": 0.1, "point_rate_hz": 1000,
        "scan_pattern": {"name": "tulip"}}), ["scan_pattern.name", "unknown scan pattern",
                                               "rose"]),
    "unknown_sensor": (_with(["sensor", "datasheet"], "livox-mid7"), ["sensor.datasheet",
                                                                      "did you mean"]),
    "zero_duration": (_with(["scan", "duration_s"], 0), ["scan.duration_s"]),
    "bad_quaternion": (_with(["targets", "0", "pose"], {"quaternion_xyzw": [0, 0, 0, 0]}),
                       ["targets.0.pose", "zero norm"]),
    "unknown_noise": (_with(["noise"], ["angular", "shot"]), ["noise.1.name"]),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_input_gives_one_line_exit_2_and_no_file(tmp_path, case):
    content, expected = BAD_CASES[case]
    scen = _bad(tmp_path, f"{case}.yaml", content)
    out = tmp_path / "out.ply"
    res = run_cli("simulate", str(scen), "--out", str(out))
    assert res.returncode == 2, res.stderr
    lines = [line for line in res.stderr.strip().splitlines() if line.strip()]
    assert len(lines) == 1, res.stderr
    assert "Traceback" not in res.stderr
    assert f"{case}.yaml" in lines[0]
    for fragment in expected:
        assert fragment in lines[0], lines[0]
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == [scen.name]


def test_debug_flag_shows_the_traceback(tmp_path):
    scen = _bad(tmp_path, "bad.yaml", _with(["backend"], "optix"))
    res = run_cli("--debug", "simulate", str(scen), "--out", str(tmp_path / "o.ply"))
    assert res.returncode != 0 and "Traceback" in res.stderr


def test_missing_scenario_and_unknown_format(tmp_path):
    res = run_cli("simulate", str(tmp_path / "none.yaml"), "--out", str(tmp_path / "o.ply"))
    assert res.returncode == 2 and "none.yaml" in res.stderr and "not found" in res.stderr
    scen = write_yaml(tmp_path / "s.yaml", GOOD_SCENARIO)
    res = run_cli("simulate", str(scen), "--out", str(tmp_path / "o.xyz"))
    assert res.returncode == 2 and "no exporter for suffix '.xyz'" in res.stderr


def test_sensors_plugins_and_schema_listings():
    res = run_cli("sensors", "--json")
    assert res.returncode == 0, res.stderr
    sensors = {s["name"]: s for s in json.loads(res.stdout)}
    mid70 = sensors["livox-mid70-rose"]
    assert mid70["fov_h_deg"] == 70.4 and mid70["point_rate_hz"] == 100000
    assert "built-in" in mid70["provider"] and mid70["sources"]
    res = run_cli("plugins", "--json")
    rows = json.loads(res.stdout)
    kinds = {(r["kind"], r["name"]) for r in rows}
    assert {("ray_backend", "numpy"), ("ray_backend", "embree"), ("scan_pattern", "rose"),
            ("noise_model", "angular"), ("noise_model", "range"), ("exporter", "ply"),
            ("target_model", "envisat")} <= kinds
    schema = json.loads(run_cli("schema", "sensor").stdout)
    assert "range_precision_m" in schema["properties"]
    assert "range_precision_m" in schema["required"]
    scenario_schema = json.loads(run_cli("schema", "scenario").stdout)
    assert "targets" in scenario_schema["properties"]
    assert run_cli("sensors").returncode == 0


def test_a_long_command_freezes_what_its_own_process_made(tmp_path, monkeypatch):
    """``lidarsim dataset`` (and ``bag``) move the objects of the imports and the loaded
    kernels out of the cyclic garbage collector's sight before the frames (a full collection
    walked them all: 35-140 ms, two or three times in 1,000 frames), but only as the
    ``lidarsim`` process itself: an app called from Python leaves its caller's process as it
    is."""
    import gc

    from lidarsim_core import kernels
    from lidarsim_core.cli import progress
    from lidarsim_core.cli.app import STATE

    monkeypatch.setattr(kernels, "warm_up", lambda display=None: True)
    monkeypatch.setattr(progress, "warm_kernels", lambda: None)
    monkeypatch.setitem(STATE, "own_process", False)
    gc.unfreeze()
    try:
        progress.prepare_long_run()
        assert gc.get_freeze_count() == 0
        monkeypatch.setitem(STATE, "own_process", True)
        progress.prepare_long_run()
        assert gc.get_freeze_count() > 10_000
    finally:
        gc.unfreeze()
    scen = write_yaml(tmp_path / "s.yaml", GOOD_SCENARIO)
    code = ("import atexit, gc, sys; atexit.register(lambda: print('frozen', "
            "gc.get_freeze_count())); sys.argv[0] = 'lidarsim'; "
            "from lidarsim_core.cli.main import main; main()")  # as the console script
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", "LIDARSIM_KERNELS": "numpy"}
    res = subprocess.run([sys.executable, "-c", code, "dataset", str(scen), "--out",
                          str(tmp_path / "ds"), "--frames", "2", "-q"], env=env,
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert int(res.stdout.split("frozen")[-1]) > 10_000
    assert len(list((tmp_path / "ds").rglob("*.ply"))) == 2
    # called with its arguments (a caller's process): nothing frozen
    code = code.replace("sys.argv[0] = 'lidarsim'; ", "").replace("main()", "main(sys.argv[1:])")
    res = subprocess.run([sys.executable, "-c", code, "dataset", str(scen), "--out",
                          str(tmp_path / "ds2"), "--frames", "2", "-q"], env=env,
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert int(res.stdout.split("frozen")[-1]) == 0
