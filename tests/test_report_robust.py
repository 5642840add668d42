"""Report figures robust to any mesh: Fig. 11's flat patch is one planar facet (a box-shaped
user satellite gives a no-error spread below 1 mm), colour-bar ticks are round, runs are read
in every format that keeps the frame metadata."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("pyvista")  # the report package needs the viz extra


def _box_run(directory: Path, *, fmt: str = "npz", duration: float = 0.2) -> Path:
    """A user satellite: a 2 m cube bus (from an STL file) and two thin panels, 12 m away,
    turned so that three faces of the bus face the sensor."""
    import trimesh

    from lidarsim_core.pipeline import simulate
    from lidarsim_core.scenario import load_scenario

    directory.mkdir(parents=True, exist_ok=True)
    bus = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    panels = [trimesh.creation.box(extents=(0.05, 3.0, 1.5)) for _ in range(2)]
    panels[0].apply_translation((0.0, -2.6, 0.0))
    panels[1].apply_translation((0.0, 2.6, 0.0))
    trimesh.util.concatenate([bus, *panels]).export(directory / "sat.stl")
    scenario = {"seed": 3, "sensor": {"datasheet": "livox-mid70-rose"},
                "targets": [{"name": "sat", "mesh": {"path": "sat.stl"},
                             "pose": {"position_m": [12.0, 0.0, 0.0],
                                      "euler_deg": [0.0, 20.0, 40.0]}}],
                "scan": {"duration_s": duration}, "backend": "numpy"}
    (directory / "scenario.yaml").write_text(yaml.safe_dump(scenario))
    simulate(load_scenario(directory / "scenario.yaml")).save(directory / f"cloud.{fmt}")
    return directory


def test_fig11_patch_on_a_box_satellite_is_one_plane(tmp_path):
    from lidarsim_core.report.run import load_run
    from lidarsim_core.report.scene import patch_views, plane_ids

    run = load_run(_box_run(tmp_path / "run"))
    views, radius = patch_views(run)
    assert views["clean"].spread_mm < 1.0  # the no-error cloud lies on the plane
    # the range error (σ 20 mm along the ray) shows off the plane, foreshortened by incidence
    assert 5.0 < views["noisy"].spread_mm < 25.0
    assert len(views["clean"].local) > 300 and radius > 0.3
    # the bus shows several planes; the two clouds name them alike
    clean, noisy = plane_ids([run.clean, run.noisy], run.simulation.targets)
    assert len(np.unique(clean[clean >= 0])) >= 3
    common = np.intersect1d(run.clean["ray_index"], run.noisy["ray_index"])
    same_face = [r for r in common
                 if run.clean["face_index"][run.clean["ray_index"] == r][0] ==
                 run.noisy["face_index"][run.noisy["ray_index"] == r][0]]
    assert len(same_face) > 100
    c_ids = {int(r): int(clean[run.clean["ray_index"] == r][0]) for r in same_face[:100]}
    n_ids = {int(r): int(noisy[run.noisy["ray_index"] == r][0]) for r in same_face[:100]}
    assert c_ids == n_ids


def test_plane_ids_group_faces_by_plane_not_by_part():
    from lidarsim_core.records.pointcloud import POINT_FIELDS, FrameInfo, PointCloud
    from lidarsim_core.report.scene import plane_ids
    from lidarsim_core.scene.mesh import Mesh

    # two coplanar triangles (z = 0) and one at z = 1, all in one part
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 1], [1, 0, 1],
                         [0, 1, 1]], dtype=float)
    faces = np.array([[0, 1, 2], [1, 3, 2], [4, 5, 6]])
    mesh = Mesh.from_arrays(vertices, faces)

    class Target:
        pass

    target = Target()
    target.mesh = mesh
    n = 4
    columns = {k: np.zeros(n, dtype=v) for k, v in POINT_FIELDS.items()}
    columns["face_index"] = np.array([0, 1, 2, 0])
    columns["target"] = np.array([0, 0, 0, -1])  # the last: a false alarm
    info = FrameInfo(0, 0.0, 1.0, "s", 0, "", "numpy", [], "per_ray", ["t"], ["t/p"], 4,
                     {}, {}, [], [], [])
    (ids,) = plane_ids([PointCloud(columns, info)], [target])
    assert ids[0] == ids[1] != ids[2] and ids[3] == -1


def test_colour_bar_ticks_are_round():
    from lidarsim_core.report.plotting import nice_ticks

    assert nice_ticks(25.65, 35.7) == (25, 40, 4, "%.0f")
    lo, hi, labels, fmt = nice_ticks(0.0012, 0.0093)
    assert (lo, hi, labels, fmt) == (0.0, 0.01, 6, "%.3f")
    for lo, hi in ((3.3, 7.9), (-0.42, 0.37), (1e3, 2.5e4)):
        a, b, n, fmt = nice_ticks(lo, hi)
        assert a <= lo and b >= hi and 2 <= n <= 7
        ticks = np.linspace(a, b, n)
        assert all(float(fmt % t) == pytest.approx(t, abs=1e-9) for t in ticks)  # exact labels


@pytest.mark.parametrize("fmt", ["pcd", "npz"])
def test_report_reads_runs_in_other_formats(tmp_path, fmt):
    from lidarsim_core.report.run import load_run

    run = load_run(_box_run(tmp_path / "run", fmt=fmt, duration=0.05))
    assert run.files == {"with errors": tmp_path / "run" / f"cloud.{fmt}"}
    assert len(run.noisy) > 100 and run.simulated == ["without errors"]


def test_the_most_precise_copy_of_a_frame_is_used(tmp_path):
    from lidarsim_core.pipeline import simulate
    from lidarsim_core.report.run import load_run
    from lidarsim_core.scenario import load_scenario

    directory = _box_run(tmp_path / "run", fmt="pcd", duration=0.05)
    simulate(load_scenario(directory / "scenario.yaml")).save(directory / "cloud.npz")
    assert load_run(directory).files["with errors"].suffix == ".npz"
