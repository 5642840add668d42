"""``lidarsim mesh``: the exported file is the geometry the simulation scanned.

Independent check: Open3D loads the exported mesh (in a subprocess, as any Open3D reader) and
its RaycastingScene casts the simulated rays, moved into the body frame with the ground-truth
pose. Embree works in float32, so the hit triangle it reports is then intersected in float64
(Möller–Trumbore) to compare with the noiseless points to 1e-6 m.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import lidarsim_core as ls
from lidarsim_core.scenario import demo_target_pose

needs_open3d = pytest.mark.skipif(importlib.util.find_spec("open3d") is None,
                                  reason="open3d is not installed (extra 'test')")

_CAST = textwrap.dedent("""
    import sys, numpy as np, open3d as o3d
    mesh_path, rays_path, out = sys.argv[1:4]
    legacy = o3d.io.read_triangle_mesh(mesh_path)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(legacy))
    rays = np.load(rays_path).astype(np.float32)
    hit = scene.cast_rays(o3d.core.Tensor(rays))
    np.savez(out, t_hit=hit["t_hit"].numpy(), prim=hit["primitive_ids"].numpy(),
             vertices=np.asarray(legacy.vertices), triangles=np.asarray(legacy.triangles))
""")


def _run_cli(*args: str):
    """The CLI in-process (the subprocess start-up is what the other CLI tests cover)."""
    from typer.testing import CliRunner

    import lidarsim_core.cli.mesh  # noqa: F401  (registers the command)
    from lidarsim_core.cli import app

    result = CliRunner().invoke(app, list(args), env={"COLUMNS": "200"})
    result.returncode, result.stderr_text = result.exit_code, result.output
    return result


def _scenario_file(tmp_path: Path, detail: str = "coarse") -> Path:
    data = {"seed": 5, "sensor": {"datasheet": "livox-mid70-rose"},
            "targets": [{"name": "envisat", "mesh": {"model": "envisat",
                                                      "options": {"detail": detail}},
                         "pose": demo_target_pose()}],
            "scan": {"duration_s": 0.05}, "backend": {"name": "numpy"}, "noise": []}
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _body_rays(cloud: ls.PointCloud) -> tuple[np.ndarray, np.ndarray]:
    """Rays from the sensor to each noiseless point, in the target's body frame, and the
    points in that frame (sensor static over the frame: one pose)."""
    pose = cloud.frame.targets_in_sensor[0]
    rotation = Rotation.from_quat(pose["quaternion_xyzw"])
    t = np.asarray(pose["translation_m"])
    points = rotation.inv().apply(cloud.xyz_true - t)
    origin = rotation.inv().apply(-t)
    directions = points - origin
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return np.column_stack([np.broadcast_to(origin, points.shape), directions]), points


def _intersect(origins, directions, triangles) -> np.ndarray:
    """Float64 Möller–Trumbore distances of each ray to its triangle (NaN if parallel)."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    e1, e2 = b - a, c - a
    p = np.cross(directions, e2)
    det = np.einsum("ij,ij->i", e1, p)
    s = origins - a
    q = np.cross(s, e1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.einsum("ij,ij->i", e2, q) / det


def _check_mesh_reproduces_points(mesh_file: Path, cloud: ls.PointCloud, tmp_path: Path):
    rays, points = _body_rays(cloud)
    np.save(tmp_path / "rays.npy", rays)
    out = tmp_path / "hits.npz"
    proc = subprocess.run([sys.executable, "-c", _CAST, str(mesh_file), str(tmp_path / "rays.npy"),
                           str(out)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-800:]
    with np.load(out) as hits:
        t_hit, prim = hits["t_hit"], hits["prim"]
        triangles = hits["vertices"][hits["triangles"]]
    assert np.all(np.isfinite(t_hit)), "a simulated ray misses the exported mesh"
    distance = np.linalg.norm(points - rays[:, :3], axis=1)
    assert np.abs(t_hit - distance).max() < 1e-4  # Embree's float32 hit
    exact = _intersect(rays[:, :3], rays[:, 3:], triangles[prim])
    hit_points = rays[:, :3] + exact[:, None] * rays[:, 3:]
    error = np.linalg.norm(hit_points - points, axis=1)
    assert error.max() < 1e-6, error.max()
    return error.max()


@needs_open3d
def test_model_name_form_reproduces_the_noiseless_points(tmp_path):
    scenario = _scenario_file(tmp_path)
    res = _run_cli("mesh", "envisat", "--option", "detail=coarse", "--out",
                   str(tmp_path / "envisat.obj"))
    assert res.returncode == 0, res.stderr_text
    assert (tmp_path / "envisat.mtl").is_file()
    cloud = ls.Simulation(ls.load_scenario(scenario)).run_frame(0)
    assert len(cloud) > 200
    _check_mesh_reproduces_points(tmp_path / "envisat.obj", cloud, tmp_path)


@needs_open3d
@pytest.mark.parametrize("suffix", [".obj", ".ply"])
def test_scenario_form_reproduces_the_noiseless_points(tmp_path, suffix):
    scenario = _scenario_file(tmp_path)
    res = _run_cli("mesh", str(scenario), "--out", str(tmp_path / f"mesh_{{target}}{suffix}"))
    assert res.returncode == 0, res.stderr_text
    cloud = ls.Simulation(ls.load_scenario(scenario)).run_frame(0)
    _check_mesh_reproduces_points(tmp_path / f"mesh_envisat{suffix}", cloud, tmp_path)


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".glb"])
def test_parts_are_named_objects(tmp_path, suffix):
    from lidarsim_core.io.meshfile import export_mesh

    model = ls.get_registry().get("target_model", "envisat").from_config({"detail": "coarse"})
    mesh = model.mesh()
    path = export_mesh(mesh, tmp_path / f"e{suffix}")
    if suffix == ".ply":
        plyfile = pytest.importorskip("plyfile")
        ply = plyfile.PlyData.read(str(path))
        np.testing.assert_array_equal(ply["face"]["part"], mesh.face_part)
        np.testing.assert_array_equal(np.column_stack([ply["vertex"][a] for a in "xyz"]),
                                      mesh.vertices)
        return
    if suffix == ".obj":  # read from the text: one ``o`` object and material per part
        objects, faces, current = [], {}, None
        for line in path.read_text().splitlines():
            if line.startswith("o "):
                current = line[2:]
                objects.append(current)
            elif line.startswith("usemtl "):
                assert line[7:] == current
            elif line.startswith("f "):
                faces[current] = faces.get(current, 0) + 1
        assert objects == list(mesh.part_names)
        assert faces == {n: int(np.sum(mesh.face_part == i))
                         for i, n in enumerate(mesh.part_names)}
        mtl = path.with_suffix(".mtl").read_text()
        assert all(f"newmtl {n}" in mtl for n in mesh.part_names)
        return
    import trimesh

    scene = trimesh.load(str(path), force="scene")
    assert set(scene.geometry) == set(mesh.part_names)
    assert sum(len(g.faces) for g in scene.geometry.values()) == mesh.n_faces


def test_bad_requests_fail_cleanly(tmp_path):
    res = _run_cli("mesh", "enviset", "--out", str(tmp_path / "a.obj"))
    assert res.returncode == 2 and "did you mean 'envisat'" in res.stderr_text
    res = _run_cli("mesh", "envisat", "--out", str(tmp_path / "a.xyz"))
    assert res.returncode == 2 and "no mesh format for suffix '.xyz'" in res.stderr_text
    scenario = tmp_path / "two.yaml"
    scenario.write_text((Path(__file__).parents[1] / "examples" / "scenarios" /
                         "two_targets.yaml").read_text())
    res = _run_cli("mesh", str(scenario), "--out", str(tmp_path / "a.obj"))
    assert res.returncode == 2 and "'{target}'" in res.stderr_text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["two.yaml"]
