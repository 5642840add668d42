"""Canonical ray-casting scenes with exact expected answers, and a brute-force reference caster.

Every :class:`RayCase` holds a mesh, rays and, for each ray, the answer worked out from the
geometry the case was built from (not from any ray caster): the distance to the first surface
point (NaN when the ray must miss) and the set of faces that may be reported there (several
when the point lies on a shared edge or corner, or on duplicated triangles).

The cases rely on two facts of elementary geometry:

* a ray that reaches a point of a *convex* polyhedron's surface through a face it enters
  (direction against that face's outward normal) meets the solid first at that point;
* a ray starting inside an axis-aligned box leaves it at ``min_i max((lo_i - o_i) / d_i,
  (hi_i - o_i) / d_i)``.

:func:`reference_intersect` is a direct float64 Möller–Trumbore test of every ray against every
triangle (no acceleration structure): an independent truth for larger scenes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.mesh import Mesh
from .meshes import BOX_SIDES, box_mesh, icosphere_mesh, plate_mesh, unit


@dataclass(frozen=True)
class RayCase:
    """A mesh, rays through it and the exact answer for every ray.

    Attributes
    ----------
    name
        Short description used in assertion messages.
    mesh
        The scene.
    origins, directions
        (N, 3) float64 ray origins and unit directions (mesh frame).
    distance
        (N,) expected distance to the first hit; NaN where the ray must miss.
    faces
        For each ray, the faces that may be reported (empty for a miss).
    """

    name: str
    mesh: Mesh
    origins: np.ndarray
    directions: np.ndarray
    distance: np.ndarray
    faces: tuple[frozenset[int], ...]

    def __len__(self) -> int:
        return len(self.origins)




def mesh_scale(mesh: Mesh) -> float:
    """Largest absolute coordinate or extent of the mesh (m), a length scale for tolerances."""
    lo, hi = mesh.bounds
    return float(max(np.abs(lo).max(), np.abs(hi).max(), (hi - lo).max()))


def faces_at(mesh: Mesh, points: np.ndarray, tol: float) -> tuple[frozenset[int], ...]:
    """For each point, the non-degenerate faces whose closed triangle contains it.

    A face contains a point when the point is within ``tol`` (m) of the face's plane and no more
    than ``tol`` outside any of its three edges (signed in-plane distances).
    """
    tri = mesh.triangles
    normal = mesh.face_normals
    usable = mesh.face_areas > 0
    result = []
    for p in np.atleast_2d(points):
        rel = p - tri[:, 0]
        inside = usable & (np.abs(np.einsum("ij,ij->i", rel, normal)) <= tol)
        for k in range(3):
            a, b = tri[:, k], tri[:, (k + 1) % 3]
            inward = np.cross(normal, b - a)  # points into the triangle (right-hand winding)
            length = np.linalg.norm(inward, axis=1)
            with np.errstate(invalid="ignore", divide="ignore"):
                signed = np.einsum("ij,ij->i", p - a, inward) / length
            inside &= signed >= -tol
        result.append(frozenset(np.flatnonzero(inside).tolist()))
    return tuple(result)


def _case(name: str, mesh: Mesh, origins: np.ndarray, directions: np.ndarray,
          distance: np.ndarray, faces: tuple[frozenset[int], ...] | None = None) -> RayCase:
    origins = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    directions = unit(np.asarray(directions, dtype=np.float64).reshape(-1, 3))
    distance = np.asarray(distance, dtype=np.float64).reshape(-1)
    if faces is None:
        hit = np.isfinite(distance)
        points = origins + np.nan_to_num(distance)[:, None] * directions
        tol = 1e-9 * max(mesh_scale(mesh), float(np.abs(origins).max(initial=0.0)))
        found = faces_at(mesh, points[hit], tol)
        faces_list = [frozenset()] * len(distance)
        for i, f in zip(np.flatnonzero(hit), found):
            faces_list[i] = f
        faces = tuple(faces_list)
    for i, (d, f) in enumerate(zip(distance, faces)):
        if np.isfinite(d) != bool(f):
            raise AssertionError(f"{name}: ray {i}: expected point lies on no face (case bug)")
    return RayCase(name, mesh, origins, directions, distance, faces)








def _box_exit(lo: np.ndarray, hi: np.ndarray, origins: np.ndarray,
              directions: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        t_lo = (lo - origins) / directions
        t_hi = (hi - origins) / directions
    return np.min(np.maximum(t_lo, t_hi), axis=1)


def _rays_to_points(points: np.ndarray, directions: np.ndarray,
                    back: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    directions = unit(directions)
    back = np.broadcast_to(np.asarray(back, dtype=np.float64), (len(points),))
    return points - back[:, None] * directions, directions, back.copy()


def _box_surface_points(rng: np.random.Generator, lo: np.ndarray, hi: np.ndarray,
                        per_side: int) -> tuple[np.ndarray, np.ndarray]:
    """Random points on every side of a box and directions entering the box there."""
    points, dirs = [], []
    for axis, sign in BOX_SIDES:
        p = lo + rng.uniform(0.02, 0.98, (per_side, 3)) * (hi - lo)
        p[:, axis] = hi[axis] if sign > 0 else lo[axis]
        d = rng.normal(size=(per_side, 3))
        d[:, axis] = -sign * (np.abs(d[:, axis]) + 0.3)  # against the outward normal
        points.append(p)
        dirs.append(d)
    return np.concatenate(points), np.concatenate(dirs)


# ---- the canonical cases -----------------------------------------------------------------
def plane_normal_incidence() -> RayCase:
    """A 2 m square plate at x = 2 hit head-on from both sides (normal ±X)."""
    mesh = plate_mesh((2.0, 0.0, 0.0), 1.0, axis=0)
    grid = np.linspace(-0.9, 0.9, 7)
    y, z = [a.ravel() for a in np.meshgrid(grid, grid)]
    front = np.column_stack([np.zeros_like(y), y, z])
    back = np.column_stack([np.full_like(y, 5.0), y, z])
    origins = np.concatenate([front, back])
    dirs = np.concatenate([np.tile([1.0, 0, 0], (len(y), 1)), np.tile([-1.0, 0, 0], (len(y), 1))])
    return _case("plane at normal incidence", mesh, origins, dirs,
                 np.concatenate([np.full(len(y), 2.0), np.full(len(y), 3.0)]))


def plane_grazing_incidence() -> RayCase:
    """Rays meeting a 200 m plate at 30° down to 0.001° from its plane."""
    mesh = plate_mesh((0.0, 0.0, 0.0), 100.0, axis=2)
    angles = np.radians([30.0, 5.0, 1.0, 0.1, 0.01, 0.001])
    height = np.array([1.0, 1.0, 0.5, 0.1, 0.01, 0.001])
    az = np.radians(np.arange(len(angles)) * 47.0 + 10.0)
    cos_a, sin_a = np.cos(angles), np.sin(angles)
    dirs = np.column_stack([cos_a * np.cos(az), cos_a * np.sin(az), -sin_a])
    origins = np.column_stack([np.full_like(az, 3.0), np.full_like(az, -7.0), height])
    return _case("plane at grazing incidence", mesh, origins, dirs, height / sin_a)


def sphere_from_outside(rng: np.random.Generator | None = None) -> RayCase:
    """Rays from 2–50 radii away aimed at face centroids of a 1280-face icosphere."""
    rng = rng or np.random.default_rng(11)
    mesh = icosphere_mesh(1.5, 3)
    n = 200
    origins = unit(rng.normal(size=(n, 3))) * rng.uniform(3.0, 75.0, (n, 1))
    centroid = mesh.triangles.mean(axis=1)
    faces, dists = [], []
    for o in origins:
        front = np.flatnonzero(np.einsum("ij,ij->i", centroid - o, mesh.face_normals) < -1e-3)
        f = int(rng.choice(front))
        faces.append(frozenset([f]))
        dists.append(np.linalg.norm(centroid[f] - o))
    dirs = centroid[[min(f) for f in faces]] - origins
    # far-side rays of the same origins that pass outside the circumsphere must miss
    miss_dir = unit(np.cross(origins, rng.normal(size=(n, 3))))
    return _case("sphere from outside", mesh, np.concatenate([origins, origins]),
                 np.concatenate([dirs, miss_dir]),
                 np.concatenate([dists, np.full(n, np.nan)]),
                 tuple(faces) + (frozenset(),) * n)


def sphere_from_inside() -> RayCase:
    """Rays from the centre of an icosphere to every face centroid (back faces are hit)."""
    mesh = icosphere_mesh(2.0, 2)
    centroid = mesh.triangles.mean(axis=1)
    return _case("sphere from inside", mesh, np.zeros_like(centroid), centroid,
                 np.linalg.norm(centroid, axis=1),
                 tuple(frozenset([i]) for i in range(len(centroid))))


_BOX_LO = np.array([-1.0, -0.5, 0.0])
_BOX_HI = np.array([2.0, 0.7, 3.0])


def box_faces() -> RayCase:
    """A closed box entered through random points of all six sides."""
    rng = np.random.default_rng(21)
    origins, dirs, dist = _rays_to_points(*_box_surface_points(rng, _BOX_LO, _BOX_HI, 20), 4.0)
    return _case("box hit on faces", box_mesh(_BOX_LO, _BOX_HI), origins, dirs, dist)


def box_edges() -> RayCase:
    """Rays entering a closed box exactly through its 12 edges and 6 face diagonals."""
    rng = np.random.default_rng(22)
    mesh = box_mesh(_BOX_LO, _BOX_HI)
    points, dirs = [], []
    for a in range(3):
        b, c = [x for x in range(3) if x != a]
        for sb in (-1.0, 1.0):
            for sc in (-1.0, 1.0):
                for t in (0.13, 0.5, 0.91):
                    p = np.zeros(3)
                    p[b] = _BOX_HI[b] if sb > 0 else _BOX_LO[b]
                    p[c] = _BOX_HI[c] if sc > 0 else _BOX_LO[c]
                    p[a] = _BOX_LO[a] + t * (_BOX_HI[a] - _BOX_LO[a])
                    d = np.zeros(3)
                    d[b], d[c] = -sb * rng.uniform(0.3, 1.0), -sc * rng.uniform(0.3, 1.0)
                    d[a] = rng.uniform(-0.5, 0.5)
                    points.append(p)
                    dirs.append(d)
    # the diagonal shared by the two triangles of every side
    for s, (axis, sign) in enumerate(BOX_SIDES):
        shared = np.intersect1d(mesh.faces[2 * s], mesh.faces[2 * s + 1])
        a, b = mesh.vertices[shared]
        for t in (0.27, 0.5, 0.8):
            d = rng.normal(size=3)
            d[axis] = -sign * (abs(d[axis]) + 0.5)
            points.append(a + t * (b - a))
            dirs.append(d)
    origins, dirs, dist = _rays_to_points(np.array(points), np.array(dirs), 3.0)
    return _case("box hit on edges", mesh, origins, dirs, dist)


def box_corners() -> RayCase:
    """Rays entering a closed box exactly through each of its 8 corners."""
    rng = np.random.default_rng(23)
    mesh = box_mesh(_BOX_LO, _BOX_HI)
    points, dirs = [], []
    for corner in mesh.vertices:
        outward = np.where(corner == _BOX_HI, 1.0, -1.0)
        for _ in range(3):
            points.append(corner)
            dirs.append(-outward * rng.uniform(0.4, 1.0, 3))
    origins, dirs, dist = _rays_to_points(np.array(points), np.array(dirs), 2.5)
    return _case("box hit on corners", mesh, origins, dirs, dist)


def thin_plate_edge_on() -> RayCase:
    """A zero-thickness plate seen edge-on (rays in its plane miss, rays crossing it at
    1e-4 rad hit) and a 1 mm thick closed plate hit on its rim."""
    sheet = plate_mesh((0.0, 0.0, 0.0), 0.5, axis=2)
    thin = box_mesh([-0.5, 2.5, -5e-4], [0.5, 3.5, 5e-4], name="thin box")
    ys = np.linspace(-0.4, 0.4, 9)
    # zero-thickness: coplanar rays (miss) and rays descending at 1e-4 rad from h = 2e-5 m
    alpha = 1e-4
    o_in = np.column_stack([np.full_like(ys, -2.0), ys, np.zeros_like(ys)])
    d_in = np.tile([1.0, 0.0, 0.0], (len(ys), 1))
    o_x = np.column_stack([np.full_like(ys, -0.3), ys, np.full_like(ys, 2e-5)])
    d_x = np.tile([np.cos(alpha), 0.0, -np.sin(alpha)], (len(ys), 1))
    mesh_sheet = _case("thin plate edge-on (zero thickness)", sheet,
                       np.concatenate([o_in, o_x]), np.concatenate([d_in, d_x]),
                       np.concatenate([np.full(len(ys), np.nan),
                                       np.full(len(ys), 2e-5 / np.sin(alpha))]))
    # 1 mm plate: rays along +X at heights inside the rim hit the x = -0.5 side
    zs = np.linspace(-4e-4, 4e-4, 9)
    o_rim = np.column_stack([np.full_like(zs, -3.0), ys + 3.0, zs])
    rim = _case("thin plate edge-on (1 mm rim)", thin, o_rim, np.tile([1.0, 0.0, 0.0], (9, 1)),
                np.full(9, 2.5))
    return _combine("thin plate edge-on", [mesh_sheet, rim])


def inside_closed_mesh() -> RayCase:
    """Rays starting inside a closed box, in random directions (back faces are hit)."""
    rng = np.random.default_rng(31)
    mesh = box_mesh(_BOX_LO, _BOX_HI)
    origins = _BOX_LO + rng.uniform(0.1, 0.9, (150, 3)) * (_BOX_HI - _BOX_LO)
    dirs = unit(rng.normal(size=(150, 3)))
    return _case("rays starting inside a closed mesh", mesh, origins, dirs,
                 _box_exit(_BOX_LO, _BOX_HI, origins, dirs))


def rays_parallel_to_faces() -> RayCase:
    """Rays parallel to a box's top: above it they miss, below it they hit a side face."""
    mesh = box_mesh(_BOX_LO, _BOX_HI)
    ys = np.linspace(-0.4, 0.6, 6)
    above = np.column_stack([np.full(6, -3.0), ys, np.full(6, 3.0 + 1e-3)])
    below = np.column_stack([np.full(6, -3.0), ys, np.full(6, 3.0 - 1e-3)])
    beside = np.column_stack([np.full(6, 4.0), np.full(6, 0.7 + 1e-3), np.linspace(0.2, 2.8, 6)])
    dirs = np.concatenate([np.tile([1.0, 0, 0], (12, 1)), np.tile([-1.0, 0, 0], (6, 1))])
    return _case("rays parallel to a face", mesh, np.concatenate([above, below, beside]), dirs,
                 np.concatenate([np.full(6, np.nan), np.full(6, 2.0), np.full(6, np.nan)]))


def degenerate_and_duplicate_triangles() -> RayCase:
    """A plate behind zero-area slivers, with its triangles duplicated and one reversed.

    Faces 0–1: the plate at z = 0; 2: a collinear sliver across the rays' path at z = 1;
    3: a triangle with a repeated vertex at z = 1; 4–5: exact duplicates of 0–1 (same vertex
    indices); 6: a copy of face 0 on separate, equal vertices with reversed winding.
    """
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0],  # plate
                  [-1, 0, 1], [0, 0, 1], [1, 0, 1],  # collinear sliver
                  [-1, -1, 0], [1, -1, 0], [1, 1, 0]], dtype=float)  # copy of face 0's corners
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 5, 5], [0, 1, 2], [0, 2, 3], [7, 9, 8]])
    mesh = Mesh.from_arrays(v, f, name="degenerate and duplicated")
    xs = np.linspace(-0.8, 0.8, 9)
    origins = np.column_stack([xs, np.zeros_like(xs), np.full_like(xs, 2.0)])
    diag = np.column_stack([np.linspace(-0.7, 0.8, 5), np.linspace(-0.9, 0.6, 5), np.full(5, 2.0)])
    origins = np.concatenate([origins, diag])
    dirs = np.tile([0.0, 0.0, -1.0], (len(origins), 1))
    return _case("degenerate and duplicated triangles", mesh, origins, dirs,
                 np.full(len(origins), 2.0))


def open_mesh() -> RayCase:
    """A box without its top (not watertight): rays through the opening hit inner walls."""
    rng = np.random.default_rng(41)
    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([2.0, 1.0, 1.0])
    mesh = box_mesh(lo, hi, name="open box", open_sides=(5,))
    # straight down through the opening: inner side of the bottom
    xy = rng.uniform(0.1, 0.9, (20, 2)) * [2.0, 1.0]
    down_o = np.column_stack([xy, np.full(20, 3.0)])
    down_d = np.tile([0.0, 0.0, -1.0], (20, 1))
    # slanted through the opening: the inner wall the line meets first
    slant_o = np.column_stack([xy, np.full(20, 1.5)])
    slant_d = unit(np.column_stack([0.3 * rng.normal(size=(20, 2)), np.full(20, -0.4)]))
    t_top = (1.0 - slant_o[:, 2]) / slant_d[:, 2]
    entry = slant_o + t_top[:, None] * slant_d
    inside = np.all((entry[:, :2] > 0.02) & (entry[:, :2] < [1.98, 0.98]), axis=1)
    slant_o, slant_d, entry = slant_o[inside], slant_d[inside], entry[inside]
    slant_t = t_top[inside] + _box_exit(lo, hi, entry, slant_d)
    # from inside, up through the opening: miss
    up_o = np.column_stack([xy, np.full(20, 0.5)])
    up_d = np.tile([0.0, 0.0, 1.0], (20, 1))
    return _case("mesh that is not watertight", mesh,
                 np.concatenate([down_o, slant_o, up_o]), np.concatenate([down_d, slant_d, up_d]),
                 np.concatenate([np.full(20, 3.0), slant_t, np.full(20, np.nan)]))


def closest_of_stacked_plates() -> RayCase:
    """Five parallel plates listed far-to-near: the nearest one along each ray is reported."""
    xs = [5.0, 1.0, 4.0, 2.0, 3.0]
    verts, faces = [], []
    for i, x in enumerate(xs):
        plate = plate_mesh((x, 0.0, 0.0), 1.0, axis=0)
        verts.append(plate.vertices)
        faces.append(plate.faces + 4 * i)
    mesh = Mesh.from_arrays(np.concatenate(verts), np.concatenate(faces), name="stacked plates")
    yz = np.linspace(-0.8, 0.8, 5)
    starts = [(0.0, 1.0, 1.0), (3.5, 1.0, 0.5), (2.0, 1.0, 1.0), (6.0, -1.0, 1.0),
              (4.5, -1.0, 0.5)]
    origins, dirs, dist = [], [], []
    for x0, sign, d in starts:
        for y in yz:
            origins.append((x0, y, -y / 2))
            dirs.append((sign, 0.0, 0.0))
            dist.append(d)
    return _case("closest of stacked plates", mesh, np.array(origins), np.array(dirs),
                 np.array(dist))


def origins_on_surfaces(epsilon: float) -> RayCase:
    """Rays starting on a plate or within ``epsilon / 2`` of it: that hit is ignored and the
    plate 1 m behind is found; a hit 10 ``epsilon`` away still counts."""
    top = plate_mesh((0.0, 0.0, 0.0), 1.0, axis=2)
    bottom = plate_mesh((0.0, 0.0, -1.0), 1.0, axis=2)
    mesh = Mesh.from_arrays(np.concatenate([top.vertices, bottom.vertices]),
                            np.concatenate([top.faces, bottom.faces + 4]), name="two plates")
    xy = np.array([[0.3, 0.2], [-0.4, 0.1], [0.05, -0.6]])
    d = unit(np.array([[0.1, 0.05, -1.0], [-0.2, 0.0, -1.0], [0.0, 0.0, -1.0]]))
    dist_bottom = lambda h: (h + 1.0) / -d[:, 2]  # noqa: E731
    origins, dirs, dists = [], [], []
    for h in (0.0, epsilon / 2):
        origins.append(np.column_stack([xy, np.full(3, h)]))
        dirs.append(d)
        dists.append(dist_bottom(h))
    origins.append(np.column_stack([xy, np.full(3, 10 * epsilon)]))
    dirs.append(d)
    dists.append(10 * epsilon / -d[:, 2])
    return _case("origins on surfaces (epsilon)", mesh, np.concatenate(origins),
                 np.concatenate(dirs), np.concatenate(dists))


def scaled_box(size: float, distance: float, *, center: tuple[float, float, float] =
               (0.0, 0.0, 0.0), name: str) -> RayCase:
    """A box of edge ~``size`` m centred at ``center``, entered from ``distance`` m away,
    plus rays from inside it."""
    rng = np.random.default_rng(int(abs(np.log10(size) * 100 + np.log10(distance) * 7)))
    c = np.asarray(center, dtype=np.float64)
    lo = c - size * np.array([0.5, 0.35, 0.25])
    hi = c + size * np.array([0.5, 0.35, 0.25])
    mesh = box_mesh(lo, hi, name=name)
    points, dirs = _box_surface_points(rng, lo, hi, 10)
    origins, dirs, dist = _rays_to_points(points, dirs, distance)
    inside_o = lo + rng.uniform(0.1, 0.9, (30, 3)) * (hi - lo)
    inside_d = unit(rng.normal(size=(30, 3)))
    return _case(name, mesh, np.concatenate([origins, inside_o]), np.concatenate([dirs, inside_d]),
                 np.concatenate([dist, _box_exit(lo, hi, inside_o, inside_d)]))


def small_scene() -> RayCase:
    """A 2 mm box seen from 1 m."""
    return scaled_box(2e-3, 1.0, name="millimetre box")


def small_scene_far_origins() -> RayCase:
    """A 2 mm box seen from 10 km."""
    return scaled_box(2e-3, 1e4, name="millimetre box from 10 km")


def large_scene() -> RayCase:
    """A 2 km box seen from 20 km."""
    return scaled_box(2e3, 2e4, name="kilometre box from 20 km")


def far_from_coordinate_origin() -> RayCase:
    """A 1 m box whose vertices lie ~500 km from the coordinate origin, seen from 30 m."""
    return scaled_box(1.0, 30.0, center=(4e5, -3e5, 2e5), name="box 500 km from the origin")


def all_miss() -> RayCase:
    """Rays that point away from, or pass beside, a sphere: every one misses."""
    rng = np.random.default_rng(51)
    mesh = icosphere_mesh(1.0, 2)
    origins = unit(rng.normal(size=(100, 3))) * rng.uniform(1.5, 20.0, (100, 1))
    away = unit(origins + 0.3 * rng.normal(size=(100, 3)) * np.linalg.norm(origins, axis=1,
                                                                            keepdims=True) / 20)
    beside = np.tile([0.0, 0.0, 1.0], (20, 1))
    o_beside = np.column_stack([np.linspace(1.05, 3.0, 20), np.zeros(20), np.full(20, -5.0)])
    return _case("rays that all miss", mesh, np.concatenate([origins, o_beside]),
                 np.concatenate([away, beside]), np.full(120, np.nan),
                 (frozenset(),) * 120)


def _combine(name: str, cases: list[RayCase]) -> RayCase:
    """Several cases' meshes and rays merged into one scene (faces renumbered)."""
    verts, faces, offset_v, offset_f = [], [], 0, 0
    sets: list[frozenset[int]] = []
    for case in cases:
        verts.append(case.mesh.vertices)
        faces.append(case.mesh.faces + offset_v)
        sets += [frozenset(f + offset_f for f in s) for s in case.faces]
        offset_v += len(case.mesh.vertices)
        offset_f += case.mesh.n_faces
    mesh = Mesh.from_arrays(np.concatenate(verts), np.concatenate(faces), name=name)
    merged = RayCase(name, mesh, np.concatenate([c.origins for c in cases]),
                     np.concatenate([c.directions for c in cases]),
                     np.concatenate([c.distance for c in cases]), tuple(sets))
    return merged


def canonical_cases(epsilon: float = 1e-6) -> dict[str, RayCase]:
    """Every canonical case, by identifier."""
    builders = {
        "plane_normal": plane_normal_incidence, "plane_grazing": plane_grazing_incidence,
        "sphere_outside": sphere_from_outside, "sphere_inside": sphere_from_inside,
        "box_faces": box_faces, "box_edges": box_edges, "box_corners": box_corners,
        "thin_plate": thin_plate_edge_on, "inside_closed": inside_closed_mesh,
        "parallel": rays_parallel_to_faces, "degenerate_duplicate":
            degenerate_and_duplicate_triangles,
        "open_mesh": open_mesh, "closest": closest_of_stacked_plates,
        "small": small_scene, "small_far": small_scene_far_origins, "large": large_scene,
        "far_coordinates": far_from_coordinate_origin, "all_miss": all_miss,
    }
    cases = {key: build() for key, build in builders.items()}
    cases["epsilon"] = origins_on_surfaces(epsilon)
    return cases






def distance_to_triangle_edges(mesh: Mesh, face: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance (m) from each point to the nearest of the three edges of ``face``."""
    tri = mesh.triangles[face]
    best = np.full(len(face), np.inf)
    for k in range(3):
        a, b = tri[:, k], tri[:, (k + 1) % 3]
        ab = b - a
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.clip(np.einsum("ij,ij->i", points - a, ab) / np.einsum("ij,ij->i", ab, ab),
                        0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(points - (a + s[:, None] * ab), axis=1))
    return best
