"""Target meshes as files: the exact geometry a simulation scanned, in the target's body frame.

:func:`export_mesh` writes a :class:`~lidarsim_core.scene.mesh.Mesh` with its parts kept apart, in a
format chosen by the suffix:

=======  ==============================================================  ===================
suffix   parts                                                           vertex precision
=======  ==============================================================  ===================
.obj     one ``o <part>`` object per part, each with its ``usemtl``      10 decimals (text)
         material in ``<name>.mtl`` (a distinct diffuse colour per part)
.ply     binary; face property ``part`` (int) indexing the header's      float64 (exact)
         ``comment lidarsim-part <i> "<name>"`` lines
.glb     one node and mesh per part, named after it                      float32 (glTF)
.stl     none (STL has one solid): the whole mesh                         float32 (STL)
=======  ==============================================================  ===================

OBJ, GLB and STL are written with trimesh; PLY directly (trimesh's PLY writer stores float32
vertices and no part names). Files are written atomically.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..base.atomic import atomic_output
from ..base.errors import OutputError
from ..scene.mesh import Mesh

#: Suffixes :func:`export_mesh` writes.
MESH_EXPORT_SUFFIXES = (".obj", ".ply", ".glb", ".stl")
#: Diffuse colours (RGB 0..255) given to parts in turn (Tableau 10).
PALETTE = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
           (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207))


def part_colour(index: int) -> list[int]:
    """RGBA (0..255) of part ``index``: the palette, darker on each further round."""
    shade = 1.0 - 0.2 * ((index // len(PALETTE)) % 4)
    return [int(round(c * shade)) for c in PALETTE[index % len(PALETTE)]] + [255]


def _material_name(part: str) -> str:
    # MTL names are single tokens
    return "_".join(part.split()) or "part"


def part_meshes(mesh: Mesh) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """``(part name, vertices, faces)`` of every part that has faces, vertices re-indexed."""
    out = []
    for index, name in enumerate(mesh.part_names):
        faces = mesh.faces[mesh.face_part == index]
        if not len(faces):
            continue
        used, inverse = np.unique(faces, return_inverse=True)
        out.append((name, mesh.vertices[used], inverse.reshape(-1, 3)))
    return out


def _scene(mesh: Mesh, *, materials: bool) -> Any:
    import trimesh

    scene = trimesh.Scene()
    for i, (name, vertices, faces) in enumerate(part_meshes(mesh)):
        part = trimesh.Trimesh(vertices, faces, process=False)
        if materials:
            part.visual = trimesh.visual.TextureVisuals(
                material=trimesh.visual.material.SimpleMaterial(name=_material_name(name),
                                                                diffuse=part_colour(i)))
        scene.add_geometry(part, geom_name=name, node_name=name)
    return scene


def _obj(mesh: Mesh, path: Path, overwrite: bool) -> None:
    import trimesh

    mtl_name = path.with_suffix(".mtl").name
    text, files = trimesh.exchange.obj.export_obj(
        _scene(mesh, materials=True), include_normals=False, include_texture=True,
        return_texture=True, write_texture=False, mtl_name=mtl_name, digits=10,
        header="lidarsim target mesh, body frame, metres")
    from ..base.atomic import atomic_group

    # every file is complete and on disk before any is renamed: a full disk leaves neither
    # the OBJ nor its MTL (the MTL, then the OBJ)
    names = [path.with_name(name) for name in files] + [path]
    with atomic_group(names, overwrite=overwrite) as streams:
        for stream, data in zip(streams, [*files.values(), text.encode("utf-8")]):
            stream.write(data)


def _ply(mesh: Mesh, path: Path, overwrite: bool) -> None:
    header = ["ply", "format binary_little_endian 1.0",
              "comment lidarsim target mesh, body frame, metres"]
    header += [f"comment lidarsim-part {i} {json.dumps(name, ensure_ascii=True)}"
               for i, name in enumerate(mesh.part_names)]
    header += [f"element vertex {len(mesh.vertices)}", "property double x", "property double y",
               "property double z", f"element face {len(mesh.faces)}",
               "property list uchar int vertex_indices", "property int part", "end_header"]
    faces = np.empty(len(mesh.faces), dtype=[("n", "u1"), ("v", "<i4", (3,)), ("part", "<i4")])
    faces["n"] = 3
    faces["v"] = mesh.faces
    faces["part"] = mesh.face_part
    with atomic_output(path, overwrite=overwrite) as stream:
        stream.write(("\n".join(header) + "\n").encode("ascii"))
        stream.write(np.ascontiguousarray(mesh.vertices, dtype="<f8").tobytes())
        stream.write(faces.tobytes())


def _trimesh_file(mesh: Mesh, path: Path, overwrite: bool, file_type: str) -> None:
    import trimesh

    if file_type == "stl":
        data = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).export(file_type="stl")
    else:
        data = _scene(mesh, materials=True).export(file_type=file_type)
    with atomic_output(path, overwrite=overwrite) as stream:
        stream.write(data if isinstance(data, bytes) else data.encode("utf-8"))


def mesh_output_files(path: str | Path) -> list[Path]:
    """Every file :func:`export_mesh` writes for ``path``: the OBJ and its MTL, or the one
    file (checked as a group before any is written)."""
    path = Path(path)
    if path.suffix.lower() == ".obj":
        return [path.with_suffix(".mtl"), path]
    return [path]


def export_mesh(mesh: Mesh, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write ``mesh`` (body frame, metres) to ``path``; the suffix picks the format.

    Parameters
    ----------
    mesh
        The mesh, e.g. ``Simulation(scenario).targets[0].mesh`` or a target model's
        ``mesh()``.
    path
        ``.obj`` (with ``.mtl`` beside it), ``.ply``, ``.glb`` or ``.stl``.
    overwrite
        Replace existing files.

    Returns
    -------
    Path
        ``path``.
    """
    from ..base.outputs import API_HINT, check_group

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_EXPORT_SUFFIXES:
        raise OutputError(f"no mesh format for suffix '{suffix or '(none)'}'; known: "
                          f"{', '.join(MESH_EXPORT_SUFFIXES)}", source=path)
    # the OBJ and its MTL as a group: both may be written, or neither is
    check_group(mesh_output_files(path), overwrite=overwrite, hint=API_HINT)
    if suffix == ".obj":
        _obj(mesh, path, overwrite)
    elif suffix == ".ply":
        _ply(mesh, path, overwrite)
    else:
        _trimesh_file(mesh, path, overwrite, suffix[1:])
    return path
