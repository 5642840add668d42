"""Small meshes with known geometry for the backend conformance cases: boxes, plates, spheres."""

from __future__ import annotations

import numpy as np

from ..scene.mesh import Mesh

#: Sides of an axis-aligned box in face order: side ``s`` owns faces ``2s`` and ``2s + 1``.
BOX_SIDES: tuple[tuple[int, float], ...] = ((0, -1.0), (0, 1.0), (1, -1.0), (1, 1.0),
                                            (2, -1.0), (2, 1.0))


def unit(vectors: np.ndarray) -> np.ndarray:
    """Rows of ``vectors`` scaled to unit length."""
    vectors = np.asarray(vectors, dtype=np.float64)
    return vectors / np.linalg.norm(vectors, axis=-1, keepdims=True)


# ---- meshes -----------------------------------------------------------------------------
def box_mesh(lo: np.ndarray, hi: np.ndarray, *, name: str = "box",
             open_sides: tuple[int, ...] = ()) -> Mesh:
    """Axis-aligned box, outward normals; side ``s`` of :data:`BOX_SIDES` is faces 2s, 2s+1.

    ``open_sides`` lists sides left out (an open, not watertight box); the face numbering of
    the remaining sides then closes up.
    """
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    corners = np.array([[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]]
                        for k in (0, 1) for j in (0, 1) for i in (0, 1)])
    faces = []
    for s, (axis, sign) in enumerate(BOX_SIDES):
        if s in open_sides:
            continue
        u, v = [a for a in range(3) if a != axis]
        bit = 1 if sign > 0 else 0

        def corner(bu: int, bv: int, _axis=axis, _u=u, _v=v, _bit=bit) -> int:
            bits = [0, 0, 0]
            bits[_axis], bits[_u], bits[_v] = _bit, bu, bv
            return bits[0] + 2 * bits[1] + 4 * bits[2]

        quad = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)]
        for tri in ([quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]):
            n = np.cross(corners[tri[1]] - corners[tri[0]], corners[tri[2]] - corners[tri[0]])
            if n[axis] * sign < 0:
                tri = [tri[0], tri[2], tri[1]]
            faces.append(tri)
    return Mesh.from_arrays(corners, np.array(faces), name=name)


def plate_mesh(center: tuple[float, float, float], half: float, axis: int = 2, *,
               name: str = "plate") -> Mesh:
    """Zero-thickness square of half-size ``half`` normal to ``axis`` (two triangles)."""
    u, v = [a for a in range(3) if a != axis]
    quad = np.zeros((4, 3))
    for i, (su, sv) in enumerate(((-1, -1), (1, -1), (1, 1), (-1, 1))):
        quad[i, u], quad[i, v] = su * half, sv * half
    return Mesh.from_arrays(quad + np.asarray(center, dtype=np.float64),
                            np.array([[0, 1, 2], [0, 2, 3]]), name=name)


def icosphere_mesh(radius: float, subdivisions: int = 3) -> Mesh:
    """Icosphere of the given circumradius centred on the origin (outward normals)."""
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return Mesh.from_arrays(np.asarray(sphere.vertices), np.asarray(sphere.faces),
                            name="icosphere")
