"""Tests of the pure-NumPy TriangleBVH against independent references.

References are analytic (plane, axis-aligned box, sphere bounds) or a brute-force
all-triangles Moeller-Trumbore written here in its classic form, independently
of the BVH's precomputed-normal kernel.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

from lidarsim_core.backends._bvh import TriangleBVH

# ----------------------------------------------------------------- references


def brute_force(vertices, faces, origins, directions, t_min=1e-9, t_max=np.inf):
    """Closest hit of every ray against every triangle (classic Moeller-Trumbore).

    Same contract as ``TriangleBVH.intersect``: inclusive barycentric tests with a
    1e-12 tolerance, rays within 1e-12 of parallel miss, degenerate triangles
    never hit, ties go to the lowest face index. Also returns, per ray, the faces that tie
    with the closest one to within rounding.
    """
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    v0, v1, v2 = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    e1, e2 = v1 - v0, v2 - v0
    n = np.cross(e1, e2)
    nlen = np.linalg.norm(n, axis=1)
    usable = nlen > 1e-14 * np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
    dist = np.full(len(origins), np.nan)
    face = np.full(len(origins), -1, dtype=np.int64)
    tied = [np.empty(0, dtype=np.int64)] * len(origins)
    with np.errstate(all="ignore"):
        for i, (o, d) in enumerate(zip(origins, directions)):
            p = np.cross(d, e2)
            det = np.einsum("ij,ij->i", e1, p)
            inv = 1.0 / det
            s = o - v0
            u = np.einsum("ij,ij->i", s, p) * inv
            q = np.cross(s, e1)
            w = (q @ d) * inv
            t = np.einsum("ij,ij->i", e2, q) * inv
            ok = usable & (np.abs(det) > 1e-12 * nlen)
            ok &= (u >= -1e-12) & (w >= -1e-12) & (u + w <= 1 + 1e-12)
            ok &= (t > t_min) & (t <= t_max)
            if ok.any():
                tt = np.where(ok, t, np.inf)
                k = int(np.argmin(tt))  # argmin returns the first, i.e. lowest, index
                dist[i], face[i] = tt[k], k
                # faces at the same distance to within rounding (duplicates, shared edges)
                tied[i] = np.flatnonzero(tt <= tt[k] + 1e-12 * max(1.0, tt[k]))
    return dist, face, tied


def unit(a):
    a = np.asarray(a, dtype=float)
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def random_dirs(rng, n):
    return unit(rng.normal(size=(n, 3)))


def aimed_rays(rng, n, target_radius, distance):
    """Rays from a sphere of radius ``distance`` aimed near the origin."""
    origins = random_dirs(rng, n) * distance
    targets = rng.uniform(-target_radius, target_radius, size=(n, 3))
    return origins, unit(targets - origins)


def slab_box(lo, hi, origins, directions, t_min=1e-9):
    """Analytic first-hit distance of rays with an axis-aligned box surface.

    Returns the distance (NaN on miss) and the hit axis. Rays starting inside
    hit the exit face.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / directions
        t0 = (lo - origins) * inv
        t1 = (hi - origins) * inv
    tn = np.minimum(t0, t1)
    tf = np.maximum(t0, t1)
    t_enter = tn.max(1)
    t_exit = tf.min(1)
    hit = t_enter <= t_exit
    t = np.where(t_enter > t_min, t_enter, t_exit)
    hit &= t > t_min
    axis = np.where(t_enter > t_min, tn.argmax(1), tf.argmin(1))
    return np.where(hit, t, np.nan), axis


# ------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def icosphere():
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=2.0)
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


@pytest.fixture(scope="module")
def cube():
    mesh = trimesh.creation.box(bounds=[[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


def check_against_brute(vertices, faces, origins, directions, bvh=None, **kw):
    if bvh is None:
        bvh = TriangleBVH.build(vertices, faces)
    dist, face, normal = bvh.intersect(origins, directions, **kw)
    ref_dist, ref_face, tied = brute_force(vertices, faces, origins, directions, **kw)
    # a different face is fine only when it ties with the reference's to rounding (the two
    # Möller–Trumbore forms may order duplicated or edge-sharing faces differently by 1 ulp)
    for i in np.flatnonzero(face != ref_face):
        assert face[i] in tied[i], (i, face[i], ref_face[i])
    np.testing.assert_array_equal(face >= 0, ref_face >= 0)
    np.testing.assert_allclose(dist, ref_dist, rtol=0, atol=1e-9, equal_nan=True)
    return dist, face, normal


# ----------------------------------------------------------- analytic checks


def test_plane_matches_analytic():
    rng = np.random.default_rng(1)
    vertices = np.array([[-100, -100, 0], [100, -100, 0], [100, 100, 0], [-100, 100, 0]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    bvh = TriangleBVH.build(vertices, faces)
    origins = np.column_stack([rng.uniform(-50, 50, (500, 2)), rng.uniform(0.01, 300, 500)])
    origins[::2, 2] *= -1  # half from below: backfaces are not culled
    directions = unit(np.column_stack([rng.normal(0, 0.3, (500, 2)), -np.sign(origins[:, 2])]))
    dist, face, normal = bvh.intersect(origins, directions)

    t_ref = -origins[:, 2] / directions[:, 2]
    hit_point = origins + t_ref[:, None] * directions
    inside = np.all(np.abs(hit_point[:, :2]) <= 100, axis=1)
    assert inside.sum() > 400
    np.testing.assert_allclose(dist[inside], t_ref[inside], rtol=0, atol=1e-9)
    assert np.all(np.isnan(dist[~inside])) and np.all(face[~inside] == -1)
    # Geometric normal of a counter-clockwise quad seen from +z, never flipped.
    np.testing.assert_array_equal(normal[inside], np.tile([0.0, 0.0, 1.0], (inside.sum(), 1)))
    below_diagonal = hit_point[:, 0] - hit_point[:, 1]
    assert np.all(face[inside & (below_diagonal > 1e-9)] == 0)
    assert np.all(face[inside & (below_diagonal < -1e-9)] == 1)


def test_box_matches_analytic_from_outside_and_inside(cube):
    vertices, faces = cube
    bvh = TriangleBVH.build(vertices, faces)
    rng = np.random.default_rng(2)
    outside, d_out = aimed_rays(rng, 1500, 0.8, 4.0)
    inside = rng.uniform(0.05, 0.95, size=(500, 3))
    d_in = random_dirs(rng, 500)
    origins = np.vstack([outside + 0.5, inside])
    directions = np.vstack([d_out, d_in])

    dist, face, normal = bvh.intersect(origins, directions)
    t_ref, axis = slab_box(np.zeros(3), np.ones(3), origins, directions)
    np.testing.assert_allclose(dist, t_ref, rtol=0, atol=1e-9, equal_nan=True)
    assert np.isfinite(dist[1500:]).all(), "rays from inside a closed mesh must hit"
    assert np.isfinite(dist[:1500]).mean() > 0.5

    hit = np.isfinite(dist)
    hit_point = origins[hit] + dist[hit, None] * directions[hit]
    # trimesh boxes have outward normals: the normal is +-e_axis by the hit side.
    expected = np.zeros((hit.sum(), 3))
    rows = np.arange(hit.sum())
    ax = axis[hit]
    expected[rows, ax] = np.where(hit_point[rows, ax] > 0.5, 1.0, -1.0)
    np.testing.assert_allclose(normal[hit], expected, atol=1e-15)


def test_icosphere_matches_brute_force(icosphere):
    vertices, faces = icosphere
    rng = np.random.default_rng(3)
    o1, d1 = aimed_rays(rng, 1500, 2.5, 8.0)
    o2 = random_dirs(rng, 300) * rng.uniform(0, 1.8, (300, 1))  # inside the sphere
    d2 = random_dirs(rng, 300)
    origins, directions = np.vstack([o1, o2]), np.vstack([d1, d2])
    dist, face, normal = check_against_brute(vertices, faces, origins, directions)
    assert np.isfinite(dist[1500:]).all()

    # Independent geometric sanity: hits lie between the inscribed and the
    # circumscribed sphere, and normals are the faces' outward unit normals.
    hit = face >= 0
    radius = np.linalg.norm(origins[hit] + dist[hit, None] * directions[hit], axis=1)
    assert radius.max() <= 2.0 + 1e-12 and radius.min() > 1.95
    fn = trimesh.Trimesh(vertices, faces, process=False).face_normals
    np.testing.assert_allclose(normal[hit], fn[face[hit]], atol=1e-12)


@pytest.mark.parametrize("leaf_size", [1, 4, 16])
def test_random_triangle_soup_matches_brute_force(leaf_size):
    rng = np.random.default_rng(10 + leaf_size)
    n = 400
    centers = rng.uniform(-5, 5, (n, 1, 3))
    scales = np.exp(rng.uniform(np.log(0.01), np.log(3.0), (n, 1, 1)))
    vertices = (centers + scales * rng.normal(size=(n, 3, 3))).reshape(-1, 3)
    faces = np.arange(3 * n).reshape(n, 3)
    bvh = TriangleBVH.build(vertices, faces, leaf_size=leaf_size)
    origins = rng.uniform(-8, 8, (1500, 3))
    directions = random_dirs(rng, 1500)
    dist, face, _ = check_against_brute(vertices, faces, origins, directions, bvh=bvh)
    assert (face >= 0).mean() > 0.2


def test_grid_aligned_coincidences_are_exact():
    """Integer meshes, axis/diagonal rays, half-integer origins: many rays hit
    exactly on edges, vertices, coplanar overlaps and duplicate faces.

    Distances must match brute force, and the face must be exactly what the
    BVH's own kernel gives per face (one single-face tree per face) reduced by
    "closest, then lowest index": pruning may never drop an exact tie.
    """
    rng = np.random.default_rng(15)
    axes = unit([[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1],
                 [1, 1, 0], [1, 1, 1], [1, -1, 0], [0, 1, 1], [-1, 1, 1]])
    for _ in range(40):
        vertices = rng.integers(-3, 4, (10, 3)).astype(float)
        faces = rng.integers(0, 10, (15, 3))
        origins = rng.integers(-4, 5, (100, 3)) + rng.choice([0.0, 0.5], (100, 3))
        directions = axes[rng.integers(0, len(axes), 100)]
        bvh = TriangleBVH.build(vertices, faces, leaf_size=int(rng.integers(1, 5)))
        dist, face, _ = bvh.intersect(origins, directions)

        ref_dist, _, _ = brute_force(vertices, faces, origins, directions)
        np.testing.assert_allclose(dist, ref_dist, rtol=0, atol=1e-9, equal_nan=True)
        per_face = np.array(
            [TriangleBVH.build(vertices, faces[[k]]).intersect(origins, directions)[0]
             for k in range(len(faces))]
        )
        per_face = np.where(np.isnan(per_face), np.inf, per_face)
        first_min = np.argmin(per_face, axis=0)  # lowest index among exact ties
        expected = np.where(np.isfinite(per_face.min(0)), first_min, -1)
        np.testing.assert_array_equal(face, expected)


def test_t_min_t_max_window(icosphere):
    vertices, faces = icosphere
    bvh = TriangleBVH.build(vertices, faces)
    rng = np.random.default_rng(4)
    origins, directions = aimed_rays(rng, 400, 1.0, 6.0)
    near, _, _ = bvh.intersect(origins, directions)
    hit = np.isfinite(near)
    # Skipping the front surface yields the back surface, as brute force says.
    check_against_brute(vertices, faces, origins[hit], directions[hit], bvh=bvh,
                        t_min=float(near[hit].max()) + 1e-6)
    # A hit exactly at t_max counts; just below it does not.
    o, d, t = origins[hit][:1], directions[hit][:1], float(near[hit][0])
    assert bvh.intersect(o, d, t_max=t)[0][0] == t
    assert np.isnan(bvh.intersect(o, d, t_max=np.nextafter(t, 0))[0][0])
    # t <= t_min is excluded (the next surface along the ray is returned instead).
    far = bvh.intersect(o, d, t_min=t)[0][0]
    assert far > t + 0.1


# ----------------------------------------------------------------- edge cases


def test_no_rays_returns_empty_arrays(icosphere):
    bvh = TriangleBVH.build(*icosphere)
    dist, face, normal = bvh.intersect(np.zeros((0, 3)), np.zeros((0, 3)))
    assert dist.shape == (0,) and dist.dtype == np.float64
    assert face.shape == (0,) and face.dtype == np.int64
    assert normal.shape == (0, 3) and normal.dtype == np.float64


def test_no_faces_all_miss():
    bvh = TriangleBVH.build(np.zeros((0, 3)), np.zeros((0, 3), dtype=int))
    assert bvh.n_triangles == 0
    dist, face, normal = bvh.intersect(np.zeros((5, 3)), np.tile([0.0, 0.0, 1.0], (5, 1)))
    assert np.isnan(dist).all() and (face == -1).all() and np.isnan(normal).all()


def test_degenerate_triangles_never_hit_and_emit_no_warnings():
    vertices = np.array(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0], [4, 0, 0], [0, 0, 5]], float
    )
    # Collinear, repeated-vertex and point triangles, then one valid face.
    faces = np.array([[0, 3, 4], [0, 0, 1], [5, 5, 5], [3, 4, 5], [0, 1, 2]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        bvh = TriangleBVH.build(vertices, faces)
        origins = np.array([[2.5, 0.0, 1.0], [0.2, 0.2, 1.0], [0.5, 0.0, -1.0], [3.5, 0, 0]])
        directions = np.array([[0, 0, -1.0], [0, 0, -1.0], [0, 0, 1.0], [1.0, 0, 0]])
        dist, face, normal = bvh.intersect(origins, directions)
    assert bvh.n_triangles == 5
    np.testing.assert_array_equal(face, [-1, 4, 4, -1])
    np.testing.assert_allclose(dist[1:3], [1.0, 1.0], atol=1e-15)
    np.testing.assert_array_equal(normal[1], [0.0, 0.0, 1.0])
    assert not np.isfinite(normal[[0, 3]]).any()


def test_all_degenerate_mesh_misses():
    bvh = TriangleBVH.build(np.zeros((3, 3)), np.array([[0, 1, 2]]))
    dist, face, _ = bvh.intersect(np.array([[0, 0, 1.0]]), np.array([[0, 0, -1.0]]))
    assert np.isnan(dist[0]) and face[0] == -1


def test_duplicated_triangles_resolve_to_lowest_index():
    filler = np.random.default_rng(5).uniform(5, 9, (60, 3))  # other faces, elsewhere
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    vertices = np.vstack([filler, tri])
    others = np.arange(60).reshape(20, 3)
    dup = np.array([[60, 61, 62]])
    # 21 identical copies (more than a leaf holds, so they span several leaves),
    # the lowest at index 7 and the rest after all other faces.
    faces = np.vstack([others[:7], dup, others[7:], np.repeat(dup, 20, axis=0)])
    for leaf_size in (1, 2, 8):
        bvh = TriangleBVH.build(vertices, faces, leaf_size=leaf_size)
        o = np.array([[0.2, 0.2, 1.0], [0.2, 0.2, -1.0]])
        d = np.array([[0, 0, -1.0], [0, 0, 1.0]])
        dist, face, _ = bvh.intersect(o, d)
        np.testing.assert_array_equal(face, [7, 7])
        np.testing.assert_array_equal(dist, [1.0, 1.0])


def test_parallel_rays_miss():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    bvh = TriangleBVH.build(vertices, np.array([[0, 1, 2]]))
    origins = np.array([[-1, 0.2, 0.0], [-1, 0.2, 1e-3], [0.2, -1, 0.0], [-1.0, -1.0, 0.0]])
    directions = unit([[1, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    dist, face, _ = bvh.intersect(origins, directions)
    assert np.isnan(dist).all() and (face == -1).all()


def test_rays_lying_in_the_triangle_plane_miss():
    """Oblique in-plane rays: den = d.n is rounding noise, not exactly zero."""
    rng = np.random.default_rng(13)
    for _ in range(50):
        vertices = rng.normal(size=(3, 3))
        bvh = TriangleBVH.build(vertices, np.array([[0, 1, 2]]))
        e1, e2 = vertices[1] - vertices[0], vertices[2] - vertices[0]
        a, c = rng.uniform(-2, -1, (50, 1)), rng.uniform(0.1, 0.4, (50, 1))
        origins = vertices[0] + a * e1 + c * e2  # in the plane, before the triangle
        directions = unit(e1 + rng.uniform(-0.2, 0.2, (50, 1)) * e2)  # through it
        _, face, _ = bvh.intersect(origins, directions)
        assert (face == -1).all()


def test_oblique_rays_at_vertices_and_edges_of_offset_meshes():
    """Hits on box boundaries: single-triangle leaves, corners on every box face."""
    rng = np.random.default_rng(14)
    for _ in range(10):
        sphere = trimesh.creation.icosphere(subdivisions=2, radius=rng.uniform(0.5, 5))
        box = trimesh.creation.box(extents=rng.uniform(0.5, 3, 3))
        for mesh in (sphere, box):
            vertices = mesh.vertices + rng.normal(size=3) * 10
            edges = mesh.edges_unique
            w = rng.uniform(0, 1, (len(edges), 1))
            on_edges = w * vertices[edges[:, 0]] + (1 - w) * vertices[edges[:, 1]]
            targets = np.vstack([vertices, on_edges])
            origins = targets + rng.normal(size=targets.shape) * 20
            bvh = TriangleBVH.build(vertices, mesh.faces, leaf_size=1)
            dist, face, _ = bvh.intersect(origins, unit(targets - origins))
            assert (face >= 0).all(), "ray through a vertex or an edge leaked"
            expected = np.linalg.norm(targets - origins, axis=1)
            # The target is on the surface but may lie behind a nearer one.
            assert np.all(dist <= expected + 1e-9)


def test_ray_inside_closed_mesh_hits_inside_surface(icosphere):
    vertices, faces = icosphere
    bvh = TriangleBVH.build(vertices, faces)
    directions = random_dirs(np.random.default_rng(6), 200)
    dist, face, normal = bvh.intersect(np.zeros((200, 3)), directions)
    assert (face >= 0).all()
    assert np.all((dist > 1.95) & (dist <= 2.0 + 1e-12))
    # Outward geometric normals: facing away from a ray that leaves the mesh.
    assert np.all(np.einsum("ij,ij->i", normal, directions) > 0)


def test_axis_aligned_rays_through_cube_edges_and_corners(cube):
    """Directions with exact zeros, origins on box planes, hits on edges/vertices."""
    vertices, faces = cube
    bvh = TriangleBVH.build(vertices, faces, leaf_size=1)
    origins, directions = [], []
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        for sign in (1.0, -1.0):
            for pb in (0.0, 0.5, 1.0):
                for pc in (0.0, 0.5, 1.0):
                    o = np.zeros(3)
                    o[a] = 0.5 - 3.0 * sign
                    o[b], o[c] = pb, pc
                    d = np.zeros(3)
                    d[a] = sign
                    origins.append(o)
                    directions.append(d)
    origins, directions = np.array(origins), np.array(directions)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dist, face, normal = bvh.intersect(origins, directions)
    # Every ray meets the near face (interior, on its diagonal, an edge or a corner)
    # at distance 2.5, including those running inside the side faces' planes.
    np.testing.assert_array_equal(dist, np.full(len(origins), 2.5))
    assert (face >= 0).all() and np.isfinite(normal).all()


def test_watertight_at_vertices_and_edge_midpoints(icosphere):
    vertices, faces = icosphere
    bvh = TriangleBVH.build(vertices, faces)
    edges = trimesh.Trimesh(vertices, faces, process=False).edges_unique
    targets = np.vstack([vertices, 0.5 * (vertices[edges[:, 0]] + vertices[edges[:, 1]])])
    for origin in (np.zeros(3), np.array([0.3, -0.2, 0.1])):
        directions = unit(targets - origin)
        dist, face, _ = bvh.intersect(np.tile(origin, (len(targets), 1)), directions)
        assert (face >= 0).all(), "a ray through a shared vertex or edge leaked"
        expected = np.linalg.norm(targets - origin, axis=1)
        np.testing.assert_allclose(dist, expected, rtol=0, atol=1e-9)
    # And from outside, aimed at the vertices and edge midpoints.
    origins = targets * 3.0
    dist, face, _ = bvh.intersect(origins, unit(targets - origins))
    assert (face >= 0).all()
    np.testing.assert_allclose(dist, np.linalg.norm(origins - targets, axis=1), atol=1e-9)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_scales_from_millimetres_to_kilometres(cube, scale):
    vertices, faces = cube
    bvh = TriangleBVH.build(vertices * scale, faces)
    rng = np.random.default_rng(7)
    origins, directions = aimed_rays(rng, 400, 0.7 * scale, 5.0 * scale)
    origins += 0.5 * scale
    dist, _, _ = bvh.intersect(origins, directions, t_min=1e-9 * scale)
    t_ref, _ = slab_box(np.zeros(3), np.full(3, scale), origins, directions)
    np.testing.assert_allclose(dist, t_ref, rtol=1e-12, atol=1e-9 * scale, equal_nan=True)
    assert np.isfinite(dist).mean() > 0.5


def test_far_origin_offset(cube):
    """Mesh and sensor both ~1e6 m from the world origin, and a far sensor."""
    vertices, faces = cube
    offset = np.array([1e6, -2e6, 5e5])
    bvh = TriangleBVH.build(vertices + offset, faces)
    rng = np.random.default_rng(8)
    origins, directions = aimed_rays(rng, 300, 0.7, 30.0)
    dist, _, _ = bvh.intersect(origins + 0.5 + offset, directions)
    t_ref, _ = slab_box(np.zeros(3), np.ones(3), origins + 0.5, directions)
    np.testing.assert_allclose(dist, t_ref, rtol=0, atol=1e-9, equal_nan=True)

    # Sensor 1e6 m away from a mesh at the origin: error scales with distance.
    far_o = np.tile([1e6, 0.0, 0.0], (50, 1)) + rng.uniform(-1, 1, (50, 3))
    far_d = unit(rng.uniform(0.1, 0.9, (50, 3)) - far_o)
    dist, _, _ = TriangleBVH.build(vertices, faces).intersect(far_o, far_d)
    t_ref, _ = slab_box(np.zeros(3), np.ones(3), far_o, far_d)
    assert np.isfinite(t_ref).all()
    np.testing.assert_allclose(dist, t_ref, rtol=1e-12)


def test_invalid_rays_miss_and_chunking_is_invisible(icosphere):
    vertices, faces = icosphere
    bvh = TriangleBVH.build(vertices, faces)
    rng = np.random.default_rng(9)
    origins, directions = aimed_rays(rng, 1000, 2.5, 6.0)
    directions[0] = 0.0
    directions[1, 0] = np.nan
    origins[2, 1] = np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        big = bvh.intersect(origins, directions)
    small = bvh.intersect(origins, directions, chunk_size=7)
    for a, b in zip(big, small):
        np.testing.assert_array_equal(a, b)
    assert (big[1][:3] == -1).all()


def test_input_validation(icosphere):
    vertices, faces = icosphere
    with pytest.raises(ValueError):
        TriangleBVH.build(vertices[:, :2], faces)
    with pytest.raises(ValueError):
        TriangleBVH.build(vertices, faces + len(vertices))
    with pytest.raises(ValueError):
        TriangleBVH.build(vertices, faces.astype(float))
    with pytest.raises(ValueError):
        TriangleBVH.build(vertices, faces, leaf_size=0)
    bvh = TriangleBVH.build(vertices, faces)
    with pytest.raises(ValueError):
        bvh.intersect(np.zeros((3, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError):
        bvh.intersect(np.zeros((3, 3)), np.ones((3, 3)), t_min=-1.0)


def test_exponentially_spaced_triangles():
    """Sizes and positions spanning 6 decades: an adversarial input for binning."""
    n = 500
    x = 1.03 ** np.arange(n)
    tri = np.array([[0.0, 0, 0], [0.5, 1, 0], [0.5, 0, 1]])
    vertices = (tri[None] * x[:, None, None] * 0.01 + np.c_[x, 0 * x, 0 * x][:, None]).reshape(-1, 3)
    faces = np.arange(3 * n).reshape(n, 3)
    bvh = TriangleBVH.build(vertices, faces, leaf_size=1)
    rng = np.random.default_rng(11)
    targets = vertices.reshape(n, 3, 3)[rng.integers(0, n, 300)].mean(1)
    origins = targets - [0.0, 0.0, 1.0]
    directions = unit(np.c_[rng.normal(0, 1e-4, 300), np.zeros(300), np.ones(300)])
    dist, face, _ = check_against_brute(vertices, faces, origins, directions, bvh=bvh)
    assert (face >= 0).sum() > 250


def test_depth_guard_falls_back_to_count_halving(monkeypatch):
    import lidarsim_core.backends._bvh as bvh_module

    monkeypatch.setattr(bvh_module, "_SAH_MAX_DEPTH", 2)
    rng = np.random.default_rng(12)
    n = 1000
    vertices = (rng.uniform(-5, 5, (n, 1, 3)) + 0.3 * rng.normal(size=(n, 3, 3))).reshape(-1, 3)
    faces = np.arange(3 * n).reshape(n, 3)
    bvh = TriangleBVH.build(vertices, faces, leaf_size=2)
    assert bvh.depth <= 2 + int(np.ceil(np.log2(n))) + 1
    origins = rng.uniform(-8, 8, (800, 3))
    check_against_brute(vertices, faces, origins, random_dirs(rng, 800), bvh=bvh)


# --------------------------------------------------------- property-based check

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from hypothesis.extra.numpy import arrays  # noqa: E402

_coords = st.floats(-10, 10, allow_nan=False, allow_infinity=False)


@settings(max_examples=40, deadline=None)
@given(
    vertices=arrays(np.float64, (12, 3), elements=_coords),
    faces=arrays(np.int64, st.tuples(st.integers(1, 20), st.just(3)), elements=st.integers(0, 11)),
    origins=arrays(np.float64, (30, 3), elements=_coords),
    seed=st.integers(0, 2**32 - 1),
    leaf_size=st.integers(1, 8),
)
def test_property_small_meshes_match_brute_force(vertices, faces, origins, seed, leaf_size):
    """Arbitrary small meshes, including repeated vertices and duplicate faces."""
    directions = random_dirs(np.random.default_rng(seed), len(origins))
    bvh = TriangleBVH.build(vertices, faces, leaf_size=leaf_size)
    check_against_brute(vertices, faces, origins, directions, bvh=bvh)
