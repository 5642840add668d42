"""The Open3D baselines against the issue's criteria (figures printed with ``-s``):

* ``icp`` tracks a noise-free 20-frame tumbling-Envisat sequence within 5 mm / 0.1°, and the
  same sequence with the datasheet's errors within 2 cm / 0.5°;
* ``fpfh_ransac_icp`` acquires the pose (within 5 cm / 2° after ICP) with no initial pose on
  at least 90 % of frames of static Envisat views at random attitudes.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

pytest.importorskip("open3d", reason="the 'eval' extra (open3d) is not installed here",
                    exc_type=ImportError)

from lidarsim_core.dataset import generate_dataset  # noqa: E402
from lidarsim_core.evaluate import evaluate_dataset  # noqa: E402

# Envisat tumbling at its 2013 rate (2.67 °/s, flat spin, examples/scenarios/
# envisat_tumbling_hold.yaml), seen from a chaser holding 16 m away off the V-bar and looking
# at it, so that the bus, the array and the antenna all show (a face-on view of a few flat
# faces leaves ICP free to slide along them). 20 frames of 0.1 s at 10 Hz, motion per ray.
TUMBLING = {
    "seed": 2013,
    "sensor": {"datasheet": "livox-mid70-rose",
               "trajectory": {"kind": "hcw", "orbit": {"altitude_km": 780},
                              "position_m": [6, 14, 5],
                              "segments": [{"type": "hold", "duration_s": 600}],
                              "attitude": {"mode": "look_at", "point_m": [0, 0, 0],
                                           "up": [0, 0, 1]}}},
    "targets": [{"name": "envisat", "mesh": {"model": "envisat", "options": {"detail": "medium"}},
                 "trajectory": {"kind": "tumbling", "position_m": [0, 0, 0],
                                "centre_of_mass_m": [0, 0, 0], "euler_deg": [-90, 0, -90],
                                "symmetry_axis": [0, 1, 0], "angular_momentum_axis": [0, 0, -1],
                                "spin_rate_deg_s": 2.67, "orbit": {"altitude_km": 780}}}],
    "scan": {"duration_s": 0.1, "frame_rate_hz": 10, "frames": 20, "motion": "per_ray"},
}


def _errors(out: Path) -> tuple[np.ndarray, np.ndarray, list[str]]:
    with open(out / "metrics.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    status = [r["status"] for r in rows]
    t = np.array([float(r["translation_error_m"] or "nan") for r in rows])
    r = np.array([float(r["rotation_error_deg"] or "nan") for r in rows])
    return t, r, status


def _dataset(root: Path, scene: dict) -> Path:
    path = root / "scene.yaml"
    path.write_text(yaml.safe_dump(scene, sort_keys=False))
    generate_dataset(path, root / "ds", quiet=True)
    return root / "ds"


@pytest.mark.slow
@pytest.mark.parametrize("noise, max_t_m, max_r_deg", [
    ("none", 0.005, 0.1), ("datasheet", 0.02, 0.5)])
def test_icp_tracks_tumbling_envisat(tmp_path, noise, max_t_m, max_r_deg):
    scene = dict(TUMBLING, **({"noise": []} if noise == "none" else {}))
    ds = _dataset(tmp_path, scene)
    result = evaluate_dataset(ds, tmp_path / "ev", "icp")
    t, r, status = _errors(tmp_path / "ev")
    print(f"\nicp, {noise} errors, {result.summary['overall']['frames']} frames: "
          f"translation max {t.max() * 1e3:.2f} mm (median {np.median(t) * 1e3:.2f}), "
          f"rotation max {r.max():.3f}° (median {np.median(r):.3f})")
    assert status == ["ok"] * 20
    assert t.max() < max_t_m and r.max() < max_r_deg
    # the first frame started 2° / 10 cm off (the default perturbation) and converged
    config = json.loads((tmp_path / "ev" / "evaluation.json").read_text())
    assert config["options"]["initial_rotation_error_deg"] == 2.0


@pytest.mark.slow
def test_fpfh_ransac_icp_acquires_from_random_attitudes(tmp_path):
    """Ten static views of Envisat 18 m ahead at uniformly random attitudes, one frame each
    (sequences of a dataset file), with the datasheet's errors: no initial pose is given."""
    scene = {"seed": 7, "sensor": {"datasheet": "livox-mid70-rose",
                                   "pose": {"position_m": [0, 0, 0]}},
             "targets": [{"name": "envisat",
                          "mesh": {"model": "envisat", "options": {"detail": "medium"}},
                          "pose": {"position_m": [18, 0, 0], "euler_deg": [0, 0, 0]}}],
             "scan": {"duration_s": 0.2, "motion": "frozen"}}
    (tmp_path / "static.yaml").write_text(yaml.safe_dump(scene, sort_keys=False))
    attitudes = Rotation.random(10, random_state=42).as_euler("xyz", degrees=True)
    plan = {"sequences": [{"scenario": "static.yaml", "name": f"att{i}",
                           "set": {"targets.0.pose.euler_deg": [round(float(v), 3) for v in e]}}
                          for i, e in enumerate(attitudes)]}
    (tmp_path / "views.yaml").write_text(yaml.safe_dump(plan, sort_keys=False))
    generate_dataset(tmp_path / "views.yaml", tmp_path / "ds", quiet=True)
    evaluate_dataset(tmp_path / "ds", tmp_path / "ev", "fpfh_ransac_icp")
    t, r, status = _errors(tmp_path / "ev")
    acquired = (t < 0.05) & (r < 2.0)
    print(f"\nfpfh_ransac_icp: acquired {acquired.sum()}/10; translation errors (mm) "
          f"{np.round(t * 1e3, 1).tolist()}, rotation errors (deg) {np.round(r, 2).tolist()}")
    assert acquired.mean() >= 0.9
