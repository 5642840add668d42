"""Body-frame ground truth (``scan.body_frame_truth``): every noiseless point expressed in its
target's body frame lies on the mesh ``lidarsim mesh`` exports, for a static and a tumbling
target, checked with trimesh's closest-point query on the exported file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

import lidarsim_core as ls
from lidarsim_core.io.meshfile import export_mesh

EXAMPLE = Path(__file__).parents[1] / "examples" / "scenarios" / "envisat_tumbling_hold.yaml"


def _on_mesh_distance(cloud: ls.PointCloud, mesh_file: Path) -> np.ndarray:
    """Distance of each (x_body, y_body, z_body) to the face it hit, in the exported file."""
    import trimesh

    loaded = trimesh.load(str(mesh_file), process=False, force="mesh")
    points = np.column_stack([cloud["x_body"], cloud["y_body"], cloud["z_body"]])
    triangles = np.asarray(loaded.vertices)[np.asarray(loaded.faces)[cloud["face_index"]]]
    closest = trimesh.triangles.closest_point(triangles, points)
    return np.linalg.norm(closest - points, axis=1)


def _tumbling(tmp_path: Path, **scan) -> ls.Scenario:
    data = yaml.safe_load(EXAMPLE.read_text())
    data["targets"][0]["mesh"]["options"]["detail"] = "coarse"
    for key in ("frame_rate_hz", "sequence_duration_s"):
        data["scan"].pop(key, None)
    data["scan"].update(scan)
    data["noise"] = [{"name": "angular"}, {"name": "range"}]
    path = tmp_path / "tumbling.yaml"
    path.write_text(yaml.safe_dump(data))
    return ls.load_scenario(path)


@pytest.mark.parametrize("motion", ["per_ray", "frozen"])
def test_body_frame_points_lie_on_the_exported_mesh_of_a_tumbling_target(tmp_path, motion):
    scenario = _tumbling(tmp_path, body_frame_truth=True, motion=motion, frames=12,
                         frame_period_s=1.0)
    sim = ls.Simulation(scenario)
    mesh_file = export_mesh(sim.targets[0].mesh, tmp_path / "envisat.ply")
    clouds = [sim.run_frame(f) for f in (0, 11)]
    for cloud in clouds:
        assert len(cloud) > 100 and cloud["x_body"].dtype == np.float64
        assert _on_mesh_distance(cloud, mesh_file).max() < 1e-9
    # the target turned ~29° between the frames: the same body point is elsewhere in the
    # sensor frame, so the columns are not just a fixed transform of x_true
    first, last = (c.frame.targets_in_sensor[0]["quaternion_xyzw"] for c in clouds)
    assert abs(np.dot(first, last)) < 0.99
    if motion == "per_ray":  # within a frame each point has its own pose
        cloud = clouds[0]
        pose = cloud.frame.targets_in_sensor[0]
        from scipy.spatial.transform import Rotation

        at_start = Rotation.from_quat(pose["quaternion_xyzw"]).apply(
            np.column_stack([cloud["x_body"], cloud["y_body"], cloud["z_body"]])) + \
            pose["translation_m"]
        drift = np.linalg.norm(at_start - cloud.xyz_true, axis=1)
        assert drift.max() > 1e-4  # the tip moves ~1 m/s: points late in the frame differ


def test_body_frame_columns_are_off_by_default_and_reach_every_format(tmp_path):
    scenario = ls.demo_scenario(duration_s=0.02, backend="numpy", detail="coarse", seed=3)
    assert "x_body" not in ls.simulate(scenario).columns
    cloud = ls.simulate(scenario.with_updates(scan={**scenario.scan.model_dump(),
                                                    "body_frame_truth": True}))
    mesh_file = export_mesh(ls.Simulation(scenario).targets[0].mesh, tmp_path / "m.ply")
    assert _on_mesh_distance(cloud, mesh_file).max() < 1e-9
    for fmt in ("ply", "npz", "csv", "pcd"):
        back = ls.read(cloud.save(tmp_path / f"c.{fmt}"))
        for name in ("x_body", "y_body", "z_body"):
            np.testing.assert_array_equal(back[name], cloud[name], err_msg=f"{fmt} {name}")
