"""``lidarsim view --screenshot``: a real picture for PLY, PCD, LAS, NPZ and a run directory
(with the target mesh drawn at its ground-truth pose)."""

from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path

import numpy as np
import pytest

import lidarsim_core as ls

pytestmark = pytest.mark.skipif(importlib.util.find_spec("pyvista") is None,
                                reason="the viz extra is not installed")
SCENARIO = Path(__file__).parents[1] / "examples" / "envisat_mid70.yaml"


def _cli(*args: str):
    from typer.testing import CliRunner

    import lidarsim_core.cli.view  # noqa: F401  (registers the command)
    from lidarsim_core.cli import app

    return CliRunner().invoke(app, list(args))


def _ink(path: Path) -> int:
    """Pixels that are not the white background."""
    from PIL import Image

    image = np.asarray(Image.open(path).convert("RGB"), dtype=np.int64)
    return int(np.sum(np.abs(image - 255).sum(axis=2) > 30))


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """A run directory: its scenario (0.1 s) and the frame as PLY, PCD, LAS and NPZ."""
    pytest.importorskip("laspy")
    from lidarsim_core.report.render import rendering_backend

    rendering_backend()  # fails, naming what to install, when no OpenGL renders here
    root = tmp_path_factory.mktemp("view") / "run"
    root.mkdir()
    text = SCENARIO.read_text().replace("duration_s: 1.0 ", "duration_s: 0.1 ")
    (root / "scenario.yaml").write_text(text)
    cloud = ls.simulate(ls.load_scenario(root / "scenario.yaml"))
    assert len(cloud) > 200
    for fmt in ("ply", "pcd", "las", "npz"):
        cloud.save(root / f"cloud.{fmt}")
    return root


@pytest.mark.parametrize("fmt, colour", [("ply", "part"), ("pcd", "intensity"),
                                         ("las", "range"), ("npz", "time")])
def test_screenshot_of_each_format_is_a_real_picture(run_dir, tmp_path, fmt, colour):
    out = tmp_path / f"{fmt}.png"
    res = _cli("view", str(run_dir / f"cloud.{fmt}"), "--color-by", colour,
               "--screenshot", str(out))
    assert res.exit_code == 0, res.output
    assert _ink(out) > 300


def test_run_directory_adds_the_target_mesh(run_dir, tmp_path):
    alone = tmp_path / "alone.png"
    assert _cli("view", str(run_dir / "cloud.npz"), "--screenshot", str(alone)).exit_code == 0
    out = tmp_path / "run.png"
    res = _cli("view", str(run_dir), "--screenshot", str(out))
    assert res.exit_code == 0, res.output
    assert "1 target mesh" in res.output
    # same camera (fitted to the points): the translucent Envisat covers far more pixels
    assert _ink(out) > 2 * _ink(alone)


def test_view_errors_are_one_line(run_dir, tmp_path):
    res = _cli("view", str(run_dir / "cloud.ply"), "--color-by", "colour",
               "--screenshot", str(tmp_path / "a.png"))
    assert res.exit_code == 2 and "colour" in res.output
    empty = tmp_path / "empty"
    empty.mkdir()
    res = _cli("view", str(empty), "--screenshot", str(tmp_path / "b.png"))
    assert res.exit_code == 2 and "no point cloud written by lidarsim" in res.output
    shutil.rmtree(empty)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_a_dataset_folder_opens_with_its_mesh_at_the_true_pose(tmp_path):
    """``lidarsim view DATASET``: the clouds of ``frames/`` and the mesh at the frame's
    ground-truth pose (every noiseless point lies on the posed mesh), framed on the target."""
    from lidarsim_core.cli.view import _cloud_folder, _clouds_of_run, _extent, _meshes
    from lidarsim_core.dataset import generate_dataset

    scenario = tmp_path / "hold.yaml"
    scenario.write_text((Path(__file__).parents[1] / "examples" / "scenarios" /
                         "envisat_tumbling_hold.yaml").read_text())
    out = tmp_path / "ds"
    generate_dataset(scenario, out, frames=2, quiet=True)
    assert _cloud_folder(out) == out / "frames"
    (path, cloud), = _clouds_of_run(out, 1)
    assert path.name == "frame_000001.ply" and len(cloud) > 50
    (poly,) = _meshes(out, cloud)
    o3d = pytest.importorskip("open3d")
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.asarray(poly.points), o3d.core.float32),
                        o3d.core.Tensor(poly.faces.reshape(-1, 4)[:, 1:], o3d.core.uint32))
    distance = scene.compute_distance(o3d.core.Tensor(cloud.xyz_true, o3d.core.float32))
    # the mesh is posed at frame start; the target tumbles during the frame, so the points
    # emitted first lie on it and later ones drift off it by the motion (cm in 0.1 s)
    distance = distance.numpy()
    first = np.argsort(cloud["timestamp"])[:max(10, len(cloud) // 20)]
    assert np.median(distance[first]) < 1e-4 and distance.max() < 0.05
    low, high = _extent([cloud.xyz], [poly])
    assert np.all(low > -1e-9 + np.minimum(cloud.xyz.min(axis=0), np.array(poly.bounds)[::2]))
    assert np.linalg.norm(low) > 5  # the sensor at the origin is not in the framed box
    shot = tmp_path / "v" / "ds.png"
    res = _cli("view", str(out), "--screenshot", str(shot))
    assert res.exit_code == 0, res.output
    assert _ink(shot) > 5000


def test_two_clouds_of_a_run_are_drawn_in_different_colours(run_dir, tmp_path):
    """The first cloud is coloured by --color-by, the second in one solid colour: the
    picture has that colour's pixels only when the second cloud is there."""
    from PIL import Image

    both = tmp_path / "both"
    both.mkdir()
    text = (run_dir / "scenario.yaml").read_text()
    (both / "scenario.yaml").write_text(text)
    scenario = ls.load_scenario(both / "scenario.yaml")
    ls.simulate(scenario).save(both / "with_errors.npz")
    ls.simulate(scenario.with_updates(noise=[])).save(both / "without_errors.npz")
    shot = tmp_path / "both.png"
    res = _cli("view", str(both), "--color-by", "range", "--screenshot", str(shot))
    assert res.exit_code == 0, res.output

    def magenta(path):  # the second cloud's colour; the turbo colour map has no magenta
        image = np.asarray(Image.open(path).convert("RGB"), dtype=np.int64)
        return int(np.sum((image[..., 0] > 180) & (image[..., 1] < 90) & (image[..., 2] > 180)))

    (both / "without_errors.npz").unlink()
    (both / "without_errors.npz.json").unlink()
    single = tmp_path / "single.png"
    res = _cli("view", str(both), "--color-by", "range", "--screenshot", str(single))
    assert res.exit_code == 0, res.output
    assert magenta(single) == 0 and magenta(shot) > 500


def test_a_long_target_seen_broadside_stays_in_the_view():
    """The camera fit keeps every corner of a long body inside a square panel (Fig. 12b of a
    flash run cut the bus at the right edge)."""
    import pyvista as pv

    from lidarsim_core.report.plotting import look, oblique_view
    from lidarsim_core.report.render import new_plotter, rendering_backend

    rendering_backend()
    plotter = new_plotter(shape=(1, 2), window_size=(1800, 900))
    plotter.subplot(0, 1)
    box = pv.Box(bounds=(29.0, 31.0, -20.0, 6.0, -1.0, 1.0))  # 26 m across the view
    plotter.add_mesh(box)
    centre = np.array([30.0, -7.0, 0.0])
    look(plotter, centre, oblique_view(centre), np.array([0.0, 0.0, 1.0]), zoom=1.05)
    renderer, camera = plotter.renderer, plotter.camera
    matrix = camera.GetCompositeProjectionTransformMatrix(renderer.GetTiledAspectRatio(), -1, 1)
    m = np.array([[matrix.GetElement(i, j) for j in range(4)] for i in range(4)])
    corners = np.c_[np.asarray(box.points), np.ones(len(box.points))] @ m.T
    ndc = corners[:, :2] / corners[:, 3:4]
    plotter.close()
    assert np.abs(ndc).max() <= 0.98  # inside the panel, with a margin
    assert np.abs(ndc).max() > 0.5  # and still filling it
