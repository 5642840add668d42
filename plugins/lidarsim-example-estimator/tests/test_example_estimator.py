"""The example estimator plugin: found through its entry point, scored by the harness, and its
tracker converges from a nearby start on a simulated Envisat frame."""

from __future__ import annotations

import csv
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from lidarsim_core.scenario import demo_scenario
from lidarsim_core.evaluate import FrameInput, PoseEstimate, TargetModelData, pose_errors
from lidarsim_core.pipeline import Simulation
from lidarsim_example_estimator import plugin


def test_entry_point_registers_the_estimator():
    code = ("from lidarsim_core.plugins import get_registry; "
            "e = get_registry().entry('pose_estimator', 'example-tracker'); print(e.provider)")
    env = {k: v for k, v in os.environ.items() if k != "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD"}
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("lidarsim-example-estimator 0.1.0")


@pytest.fixture(scope="module")
def frame():
    sim = Simulation(demo_scenario(duration_s=0.3, noise=False, detail="coarse",
                                   backend="numpy"))
    cloud = sim.run_frame(0)
    rec = cloud.frame.targets_in_sensor[0]
    truth = PoseEstimate(np.asarray(rec["quaternion_xyzw"]), np.asarray(rec["translation_m"]))
    model = TargetModelData("envisat", sim.targets[0].mesh)
    return cloud, model, truth


def test_tracker_converges_from_a_nearby_start(frame):
    cloud, model, truth = frame
    start = PoseEstimate.from_rotation(Rotation.from_euler("z", 2, degrees=True) * truth.rotation,
                                       truth.translation_m + [0.1, -0.05, 0.0])
    estimator_cls = next(iter(_registered()))
    estimator = estimator_cls.from_config({"model_points": 60_000})
    result = estimator.estimate(FrameInput("s", 0, 0.0, 0.3, cloud.columns, model, start))
    errors = pose_errors(result.quaternion_xyzw, result.translation_m, truth.quaternion_xyzw,
                         truth.translation_m)
    start_errors = pose_errors(start.quaternion_xyzw, start.translation_m,
                               truth.quaternion_xyzw, truth.translation_m)
    assert result.success
    assert errors["rotation_error_deg"] < 0.5 < start_errors["rotation_error_deg"]
    assert errors["translation_error_m"] < 0.05 < start_errors["translation_error_m"]


def _registered():
    found = []
    plugin.lidarsim_register_pose_estimators(found.append)
    return found


def test_the_wrapped_function_runs_under_lidarsim_evaluate(tmp_path):
    from lidarsim_core.dataset import generate_dataset
    from lidarsim_core.evaluate import evaluate_dataset
    from lidarsim_core.plugins import build_plugin_manager, build_registry

    generate_dataset(demo_scenario(duration_s=0.2, noise=True, detail="coarse",
                                   backend="numpy"), tmp_path / "ds", quiet=True)
    manager = build_plugin_manager()
    if not manager.has_plugin("example_estimator"):
        manager.register_plugin(plugin, "example_estimator", "test")
    result = evaluate_dataset(tmp_path / "ds", tmp_path / "ev", "example-tracker",
                              {"model_points": 20_000}, registry=build_registry(manager))
    with open(tmp_path / "ev" / "metrics.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert result.frames_total == 1 and len(rows) == 1
    assert rows[0]["status"] in ("ok", "failed")  # a principal-axes start may not converge
    assert float(rows[0]["runtime_s"]) > 0
