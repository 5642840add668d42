"""Part labels from every mesh format's own grouping: OBJ objects and groups, the solids of an
ASCII STL, GLB nodes, PLY per-face labels; and the simulated points carry them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

NAMES = ["bus", "panel_left", "panel_right", "antenna"]


def _boxes() -> list:
    """Four unit boxes 3 m apart along +Y (independent geometry for every format)."""
    import trimesh

    boxes = []
    for k in range(len(NAMES)):
        box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
        box.apply_translation((0.0, 3.0 * k - 4.5, 0.0))
        boxes.append(box)
    return boxes


def _obj(path: Path, keyword: str) -> Path:
    lines, offset = [], 1
    for name, box in zip(NAMES, _boxes()):
        lines.append(f"{keyword} {name}")
        lines += ["v %.6f %.6f %.6f" % tuple(v) for v in box.vertices]
        lines += ["f %d %d %d" % tuple(f + offset) for f in box.faces]
        offset += len(box.vertices)
    path.write_text("\n".join(lines) + "\n")
    return path


def _ascii_stl(path: Path, names: list[str]) -> Path:
    out = []
    for name, box in zip(names, _boxes()):
        out.append(f"solid {name}")
        for tri, normal in zip(box.triangles, box.face_normals):
            out += ["  facet normal %f %f %f" % tuple(normal), "    outer loop"]
            out += ["      vertex %f %f %f" % tuple(v) for v in tri]
            out += ["    endloop", "  endfacet"]
        out.append(f"endsolid {name}")
    path.write_text("\n".join(out) + "\n")
    return path


@pytest.mark.parametrize("keyword", ["o", "g"])
def test_obj_with_four_objects_gives_four_parts_in_file_order(tmp_path, keyword):
    from lidarsim_core.scene.mesh import load_mesh_file

    mesh = load_mesh_file(_obj(tmp_path / "sat.obj", keyword))
    assert mesh.part_names == tuple(NAMES)
    assert np.bincount(mesh.face_part).tolist() == [12, 12, 12, 12]
    # each part is the box it was written as: its centre is where that box was put
    for k in range(4):
        centre = mesh.vertices[mesh.faces[mesh.face_part == k]].reshape(-1, 3).mean(axis=0)
        np.testing.assert_allclose(centre, [0.0, 3.0 * k - 4.5, 0.0], atol=1e-6)


def test_two_solid_ascii_stl_gives_two_named_parts(tmp_path):
    from lidarsim_core.scene.mesh import load_mesh_file

    mesh = load_mesh_file(_ascii_stl(tmp_path / "sat.stl", ["bus", "panel_right"]))
    assert mesh.part_names == ("bus", "panel_right")
    assert np.bincount(mesh.face_part).tolist() == [12, 12]


def test_glb_nodes_give_parts(tmp_path):
    import trimesh

    from lidarsim_core.scene.mesh import load_mesh_file

    scene = trimesh.Scene()
    for name, box in zip(NAMES, _boxes()):
        scene.add_geometry(box, node_name=name, geom_name=f"{name}_geometry")
    scene.export(tmp_path / "sat.glb")
    mesh = load_mesh_file(tmp_path / "sat.glb")
    assert sorted(mesh.part_names) == sorted(NAMES)


def test_ply_per_face_labels_give_named_parts(tmp_path):
    from plyfile import PlyData, PlyElement

    from lidarsim_core.scene.mesh import load_mesh_file

    boxes = _boxes()[:3]
    vertices = np.concatenate([b.vertices for b in boxes])
    faces = np.concatenate([b.faces + 8 * i for i, b in enumerate(boxes)])
    labels = np.repeat([7, 3, 7], 12)  # two boxes share a label; ids need not be dense
    vert = np.array([tuple(v) for v in vertices], dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    face = np.array([(list(f), lab) for f, lab in zip(faces, labels)],
                    dtype=[("vertex_indices", "i4", (3,)), ("part", "i4")])
    PlyData([PlyElement.describe(vert, "vertex"), PlyElement.describe(face, "face")],
            comments=["part 3 panel_right", "part 7 bus"]).write(str(tmp_path / "sat.ply"))
    mesh = load_mesh_file(tmp_path / "sat.ply")
    assert mesh.part_names == ("panel_right", "bus")
    assert np.bincount(mesh.face_part).tolist() == [12, 24]
    # without the naming comments the ids name the parts
    PlyData([PlyElement.describe(vert, "vertex"), PlyElement.describe(face, "face")]).write(
        str(tmp_path / "bare.ply"))
    assert load_mesh_file(tmp_path / "bare.ply").part_names == ("part_3", "part_7")


def test_simulated_points_carry_the_obj_parts(tmp_path):
    from lidarsim_core.pipeline import simulate
    from lidarsim_core.scenario import scenario_from_dict

    obj = _obj(tmp_path / "sat.obj", "o")
    scenario = scenario_from_dict({
        "seed": 1, "sensor": {"datasheet": "livox-mid70-rose"},
        "targets": [{"name": "sat", "mesh": {"path": str(obj)},
                     "pose": {"position_m": [8.0, 0.0, 0.0]}}],
        "scan": {"duration_s": 0.2}, "backend": "numpy", "noise": []})
    cloud = simulate(scenario)
    assert cloud.frame.part_names == [f"sat/{n}" for n in NAMES]
    labels = cloud.part_labels()
    assert set(labels) == {f"sat/{n}" for n in NAMES}
    # every point lies on the box of the part it is labelled with (|y - centre| <= 0.5 m)
    centres = {f"sat/{n}": 3.0 * k - 4.5 for k, n in enumerate(NAMES)}
    y = cloud["y_true"]
    assert all(abs(yy - centres[lab]) <= 0.5 + 1e-6 for yy, lab in zip(y, labels))
