"""Mesh files that are complete load, whatever their STL flavour; incomplete ones are named."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from lidarsim_core.base.errors import MeshError
from lidarsim_core.scene.mesh import load_mesh_file


def _box() -> trimesh.Trimesh:
    return trimesh.creation.box(extents=(1.0, 2.0, 3.0))


def test_ascii_stl_loads(tmp_path):
    path = tmp_path / "box.stl"
    path.write_text(trimesh.exchange.stl.export_stl_ascii(_box()))
    mesh = load_mesh_file(path)
    assert mesh.n_faces == 12
    np.testing.assert_allclose(mesh.bounds, [[-0.5, -1, -1.5], [0.5, 1, 1.5]])


def test_binary_stl_whose_header_starts_with_solid_loads(tmp_path):
    data = bytearray(trimesh.exchange.stl.export_stl(_box()))
    data[:80] = b"solid exported by a CAD tool".ljust(80, b" ")
    path = tmp_path / "box.stl"
    path.write_bytes(bytes(data))
    assert load_mesh_file(path).n_faces == 12


def test_truncated_binary_stl_is_named_with_both_sizes(tmp_path):
    data = trimesh.exchange.stl.export_stl(_box())
    path = tmp_path / "box.stl"
    path.write_bytes(data[:-20])
    with pytest.raises(MeshError, match=r"box\.stl.*truncated.*12 triangles \(684 bytes\) but "
                                        r"the file has 664 bytes"):
        load_mesh_file(path)


def test_directory_and_empty_file_are_named(tmp_path):
    with pytest.raises(MeshError, match="is a directory, not a mesh file"):
        load_mesh_file(tmp_path)
    (tmp_path / "empty.obj").write_text("")
    with pytest.raises(MeshError, match="empty.obj: mesh file is empty"):
        load_mesh_file(tmp_path / "empty.obj")
