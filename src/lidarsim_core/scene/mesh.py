"""The triangle mesh of a target, with per-face part labels, and loading from files.

Meshes stay in their body frame for the whole simulation; rays are moved into it instead, so
each backend builds its acceleration structure once per mesh (keyed by :attr:`Mesh.key`).
"""

from __future__ import annotations

import hashlib
import warnings
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from ..base.config_io import check_input_file
from ..base.errors import MeshError
from ..base.limits import LIMITS, check, limit

#: Suffixes trimesh reads that we support explicitly (others trimesh knows are tried too).
#: Largest vertex coordinate accepted (m): beyond it, areas and normals overflow float64 long
#: before a LiDAR could see the part.
MAX_COORDINATE_M = 1e7

MESH_SUFFIXES = (".stl", ".obj", ".ply", ".glb", ".gltf", ".off")


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh with named parts.

    Attributes
    ----------
    vertices
        (V, 3) float64 vertex positions in the body frame (m).
    faces
        (F, 3) int64 vertex indices.
    face_part
        (F,) int32 index into :attr:`part_names` for every face.
    part_names
        Names of the parts (labels written into the point record).
    name
        A human-readable name for messages.
    part_materials
        Per part, the mesh's own material (a material name or a mapping of material fields,
        see :mod:`lidarsim_core.scene.materials`) or None; empty when the mesh carries none.
    """

    vertices: np.ndarray
    faces: np.ndarray
    face_part: np.ndarray
    part_names: tuple[str, ...]
    name: str = "mesh"
    part_materials: tuple[Any, ...] = ()
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_arrays(cls, vertices: np.ndarray, faces: np.ndarray,
                    face_part: np.ndarray | None = None,
                    part_names: tuple[str, ...] | None = None, *, name: str = "mesh",
                    source: str | None = None,
                    part_materials: tuple[Any, ...] = ()) -> "Mesh":
        """Validate arrays and build a mesh (raises :class:`MeshError` naming ``source``)."""
        where = source or name
        vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        faces = np.ascontiguousarray(faces, dtype=np.int64)
        if vertices.ndim != 2 or vertices.shape[1] != 3:
            raise MeshError(f"vertices must be (V, 3), got {vertices.shape}", source=where)
        if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
            raise MeshError("mesh has no triangular faces", source=where)
        if not np.all(np.isfinite(vertices)):
            raise MeshError("mesh has non-finite (NaN or infinite) vertex coordinates", source=where)
        reach = float(np.abs(vertices).max()) if vertices.size else 0.0
        if reach > MAX_COORDINATE_M:
            raise MeshError(f"vertex coordinates reach {reach:.3g} m; meshes must lie within "
                            f"±{MAX_COORDINATE_M:g} m of their origin (check the file's units "
                            "and 'scale')", source=where)
        check("mesh_triangles", len(faces), what="the mesh's triangle count", source=where)
        if faces.min() < 0 or faces.max() >= len(vertices):
            raise MeshError("face indices out of range", source=where)
        if face_part is None:
            face_part = np.zeros(len(faces), dtype=np.int32)
            part_names = part_names or (name,)
        face_part = np.ascontiguousarray(face_part, dtype=np.int32)
        part_names = tuple(part_names or ())
        if face_part.shape != (len(faces),) or (len(face_part) and
                                                 (face_part.min() < 0 or
                                                  face_part.max() >= len(part_names))):
            raise MeshError("face part labels do not match the part names", source=where)
        if part_materials and len(part_materials) != len(part_names):
            raise MeshError("one material per part is needed", source=where)
        mesh = cls(vertices, faces, face_part, part_names, name, tuple(part_materials))
        if not np.any(mesh.face_areas > 0):
            raise MeshError("mesh has only degenerate (zero-area) faces", source=where)
        return mesh

    @cached_property
    def key(self) -> str:
        """Content hash: equal geometry gives equal keys (for acceleration-structure caches)."""
        digest = hashlib.sha1()
        digest.update(self.vertices.tobytes())
        digest.update(self.faces.tobytes())
        return digest.hexdigest()

    @cached_property
    def triangles(self) -> np.ndarray:
        """(F, 3, 3) float64 vertex coordinates of every face."""
        return self.vertices[self.faces]

    @cached_property
    def face_normals(self) -> np.ndarray:
        """(F, 3) unit geometric normals (right-hand rule); zero for degenerate faces."""
        tri = self.triangles
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        norm = np.linalg.norm(normal, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(norm > 0, normal / norm, 0.0)

    @cached_property
    def face_areas(self) -> np.ndarray:
        """(F,) triangle areas (m²)."""
        tri = self.triangles
        return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)

    @cached_property
    def bounds(self) -> np.ndarray:
        """(2, 3) axis-aligned bounding box (min, max)."""
        used = self.vertices[np.unique(self.faces)]
        return np.stack([used.min(axis=0), used.max(axis=0)])

    @property
    def n_faces(self) -> int:
        """Number of triangles."""
        return len(self.faces)

    def to_trimesh(self):
        """A ``trimesh.Trimesh`` copy (imports trimesh)."""
        import trimesh

        return trimesh.Trimesh(self.vertices, self.faces, process=False)


def load_mesh_file(path: str | Path, *, scale: float = 1.0, source: str | None = None,
                   field: str | None = None) -> Mesh:
    """Read any mesh format trimesh reads, with part labels from the format's own grouping.

    Parts (the ``part`` column of every point; ``docs/scenario.md#part-labels``):

    * OBJ: every ``o`` object and ``g`` group, in file order;
    * STL: every ``solid NAME`` ... ``endsolid`` block of an ASCII STL (a binary STL, or an
      ASCII one with a single solid, is one part named after the file);
    * GLB/GLTF: every node with geometry, by node name;
    * PLY: a per-face integer property ``part`` (or ``label``, ``part_id``, ``segment``,
      ``object_id``), named by header lines ``comment part <id> <name>`` where present,
      else ``part_<id>``; without one, one part named after the file;
    * anything else: one part named after the file.

    Pieces with the same name share a label. A part whose geometry carries a colour (an OBJ/MTL ``Kd``, a glTF base colour, defined
    face colours) gets a default material from it
    (:func:`lidarsim_core.scene.materials.material_from_colour`).

    Parameters
    ----------
    path
        The mesh file (STL, OBJ, PLY, GLB/GLTF, OFF, ...).
    scale
        Factor applied to the coordinates (e.g. 0.001 for a CAD file in millimetres).
    source, field
        Where the path came from, for error messages.

    Raises
    ------
    MeshError
        If the file is missing, unreadable, or holds no usable triangles.
    """
    import trimesh

    path = Path(path)
    where = f"{source}: field '{field}': {path}" if source and field else str(path)
    # the bounded reader's checks: devices, FIFOs, link loops, directories, huge files
    check_input_file(path, "mesh file", limit_name="data_bytes", error=MeshError, source=where)
    problem = _truncation(path)
    if problem:
        raise MeshError(problem, source=where)
    suffix = path.suffix.lower()
    # OBJ: one geometry per 'o' object and 'g' group (trimesh merges them by material else)
    options = {"split_objects": True, "split_groups": True} if suffix == ".obj" else {}
    from .references import BoundedResolver  # imports trimesh: loaded with it, lazily

    # referenced files (mtllib, textures, glTF URIs) through the same bounded reader
    resolver = BoundedResolver(path, where)
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")  # overflowing coordinates are refused below
            loaded = trimesh.load(str(path), process=False, resolver=resolver, **options)
    except MeshError:
        raise
    except Exception as exc:  # trimesh raises many types for garbage input
        if resolver.refused:
            raise MeshError(resolver.refused[0], source=where) from None
        raise MeshError(f"cannot read mesh: {type(exc).__name__}: "
                        f"{' '.join(str(exc).split())[:200]}", source=where) from None
    if resolver.refused:  # trimesh loads geometry without a material it could not read
        raise MeshError(resolver.refused[0], source=where)
    parts: list[tuple[str, np.ndarray, np.ndarray, Any]] = []
    if isinstance(loaded, trimesh.Trimesh) and suffix == ".ply":
        parts = _ply_face_parts(path, loaded)
    if parts:
        pass
    elif isinstance(loaded, trimesh.Scene):
        for node in loaded.graph.nodes_geometry:
            transform, geom_name = loaded.graph[node]
            geom = loaded.geometry.get(geom_name)
            if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
                continue
            verts = trimesh.transform_points(np.asarray(geom.vertices, dtype=np.float64), transform)
            parts.append((str(node), verts, np.asarray(geom.faces), _colour_material(geom)))
    elif isinstance(loaded, trimesh.Trimesh):
        parts.append((path.stem, np.asarray(loaded.vertices, dtype=np.float64),
                      np.asarray(loaded.faces), _colour_material(loaded)))
    if not parts or all(len(p[2]) == 0 for p in parts):
        raise MeshError("mesh file contains no triangles", source=where)
    if suffix == ".obj":
        parts = _in_file_order(path, parts)
    return merge_parts(parts, name=path.stem, scale=scale, source=where)


#: Per-face integer properties of a PLY mesh read as part labels, in order of preference.
PLY_PART_PROPERTIES = ("part", "label", "part_id", "segment", "object_id")


def _ply_header_lines(path: Path) -> list[str]:
    lines = []
    with path.open("rb") as stream:
        for raw in stream:
            line = raw.decode("latin-1").strip()
            lines.append(line)
            if line == "end_header" or len(lines) > 10_000:
                break
    return lines


def _ply_face_parts(path: Path, mesh: Any) -> list[tuple[str, np.ndarray, np.ndarray, Any]]:
    """The parts of a PLY mesh with a per-face label property (empty list without one)."""
    raw = (mesh.metadata or {}).get("_ply_raw", {}).get("face", {}).get("data", {})
    # a dict of columns (ASCII PLY) or a structured array (binary PLY)
    fields = raw.dtype.names or () if isinstance(raw, np.ndarray) else tuple(raw)
    key = next((k for k in PLY_PART_PROPERTIES if k in fields), None)
    if key is None:
        return []
    labels = np.asarray(raw[key]).reshape(-1)
    if len(labels) != len(mesh.faces) or not np.issubdtype(labels.dtype, np.integer):
        return []
    names: dict[int, str] = {}
    for line in _ply_header_lines(path):
        words = line.split(maxsplit=3)
        if len(words) == 4 and words[0] == "comment" and words[1] == key and \
                words[2].lstrip("-").isdigit():
            names[int(words[2])] = words[3].strip()
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces)
    material = _colour_material(mesh)
    parts = []
    for value in np.unique(labels):
        used, local = np.unique(faces[labels == value], return_inverse=True)  # its vertices
        parts.append((names.get(int(value), f"part_{int(value)}"), vertices[used],
                      local.reshape(-1, 3), material))
    return parts


def _in_file_order(path: Path, parts: list[tuple]) -> list[tuple]:
    """OBJ parts in the order their ``o``/``g`` lines appear in the file."""
    import re

    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return parts
    order: dict[str, int] = {}
    for match in re.finditer(r"^[og][ \t]+(.+?)[ \t]*$", text, re.M):
        order.setdefault(match.group(1), len(order))
    return sorted(parts, key=lambda p: order.get(p[0], len(order)))


def _truncation(path: Path) -> str | None:
    """Why ``path`` is visibly incomplete (empty, or a binary STL shorter than its header
    says), None otherwise: trimesh would otherwise read what is there and report no or fewer
    triangles."""
    size = path.stat().st_size
    if size == 0:
        return "mesh file is empty"
    if path.suffix.lower() != ".stl" or size < 84:
        return None
    with path.open("rb") as stream:
        head = stream.read(84)
    if head.lstrip()[:5].lower() == b"solid" and b"\0" not in head[:80]:
        return None  # ASCII STL
    count = int.from_bytes(head[80:84], "little")
    expected = 84 + 50 * count
    if size < expected:
        return (f"binary STL is truncated: its header announces {count:,} triangles "
                f"({expected:,} bytes) but the file has {size:,} bytes")
    bound = limit("mesh_triangles")
    if count > bound:  # refused before trimesh allocates them
        return (f"binary STL announces {count:,} triangles, over the limit of {bound:,.0f} "
                f"(set {LIMITS['mesh_triangles'].env} to raise it)")
    from ..base.errors import ConfigError
    from ..base.limits import check_memory

    try:  # a file that holds them (even a sparse one) may still not fit in memory
        check_memory(count * LOAD_BYTES_PER_TRIANGLE,
                     what=f"loading its {count:,} triangles")
    except ConfigError as exc:
        return f"binary STL: {exc.message}"
    return None


#: Peak memory of loading one triangle of a binary STL (trimesh's arrays, the float64 copies,
#: the merged mesh), measured at ~520 bytes on a 10⁶-triangle file.
LOAD_BYTES_PER_TRIANGLE = 520


def _colour_material(geom: Any) -> dict[str, Any] | None:
    """The default material of a trimesh geometry from its colour, None if it has none."""
    from .materials import material_from_colour

    visual = getattr(geom, "visual", None)
    kind = getattr(visual, "kind", None)
    colour = None
    if kind == "texture":
        colour = getattr(getattr(visual, "material", None), "main_color", None)
    elif kind in ("face", "vertex") and getattr(visual, "defined", False):
        colour = np.asarray(visual.face_colors, dtype=np.float64).mean(axis=0)
    if colour is None:
        return None
    return material_from_colour(np.asarray(colour, dtype=np.float64)[:3] / 255.0)


def merge_parts(parts: list[tuple], *, name: str, scale: float = 1.0,
                source: str | None = None) -> Mesh:
    """Concatenate ``(part name, vertices, faces)`` or ``(part name, vertices, faces,
    material)`` pieces into one labelled :class:`Mesh`.

    Pieces with the same name share one label (and the first piece's material).
    """
    names: list[str] = []
    materials: list[Any] = []
    verts, faces, labels = [], [], []
    offset = 0
    for part, v, f, *material in parts:
        if part not in names:
            names.append(part)
            materials.append(material[0] if material else None)
        verts.append(np.asarray(v, dtype=np.float64) * scale)
        faces.append(np.asarray(f, dtype=np.int64) + offset)
        labels.append(np.full(len(f), names.index(part), dtype=np.int32))
        offset += len(v)
    return Mesh.from_arrays(np.concatenate(verts), np.concatenate(faces), np.concatenate(labels),
                            tuple(names), name=name, source=source,
                            part_materials=tuple(materials) if any(
                                m is not None for m in materials) else ())
