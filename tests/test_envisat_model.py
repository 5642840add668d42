"""Tests for the parametric Envisat model (lidarsim_core.models.envisat)."""

from __future__ import annotations

import time

import numpy as np
import pytest
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from lidarsim_core.models.envisat import (
    DETAIL_LEVELS,
    ENVISAT_PARTS,
    MAX_TESSELLATION_FACTOR,
    SOLAR_ARRAY_LENGTH_M,
    SOLAR_ARRAY_WIDTH_M,
    build_envisat,
    resolve_detail,
)

LEVELS = ("coarse", "medium", "fine")

# Documented triangle-count ranges per named level (build_envisat docstring).
TRIANGLE_RANGES = {
    "coarse": (200, 1_000),
    "medium": (5_000, 20_000),
    "fine": (80_000, 130_000),
}

# ESA's published in-orbit envelope of Envisat is 26 m x 10 m x 5 m. In the
# model frame the long axis (bus plus boom plus solar array) is X, the array's
# sideways offset plus the ASAR is Y, and nadir instruments plus the zenith
# Ka-band mast are Z. The model is an approximation, so allow 10 %.
PUBLISHED_ENVELOPE_M = np.array([26.0, 10.0, 5.0])
ENVELOPE_TOLERANCE = 0.10


@pytest.fixture(scope="module", params=LEVELS)
def model(request):
    """(level, vertices, faces, face_part, names) for each named level."""
    vertices, faces, face_part, names = build_envisat(request.param)
    return request.param, vertices, faces, face_part, names


def _part_mesh(vertices, faces, face_part, index) -> trimesh.Trimesh:
    """One part as a standalone mesh, with only its own vertices."""
    mesh = trimesh.Trimesh(vertices, faces[face_part == index], process=False)
    mesh.remove_unreferenced_vertices()
    return mesh


def _bodies(mesh: trimesh.Trimesh) -> list[np.ndarray]:
    """Face indices of each vertex-connected body of ``mesh``."""
    faces = mesh.faces
    n_vertices = len(mesh.vertices)
    # Link each face's vertices in a chain; components are then the bodies.
    rows = np.concatenate([faces[:, 0], faces[:, 1]])
    cols = np.concatenate([faces[:, 1], faces[:, 2]])
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_vertices, n_vertices))
    _, labels = connected_components(graph, directed=False)
    face_labels = labels[faces[:, 0]]
    return [np.flatnonzero(face_labels == label) for label in np.unique(face_labels)]


def test_output_types_and_shapes(model):
    _, vertices, faces, face_part, names = model
    assert vertices.dtype == np.float64 and vertices.ndim == 2 and vertices.shape[1] == 3
    assert faces.dtype == np.int64 and faces.ndim == 2 and faces.shape[1] == 3
    assert face_part.dtype == np.int32 and face_part.shape == (len(faces),)
    assert names == ENVISAT_PARTS
    assert faces.min() >= 0 and faces.max() < len(vertices)
    assert np.isfinite(vertices).all()


def test_every_part_present_and_labels_in_range(model):
    _, _, _, face_part, names = model
    assert face_part.min() >= 0 and face_part.max() < len(names)
    counts = np.bincount(face_part, minlength=len(names))
    assert (counts > 0).all(), dict(zip(names, counts))
    # Faces are grouped by part, in part order.
    assert (np.diff(face_part) >= 0).all()


def test_part_names_unique_and_include_capture_target():
    assert len(set(ENVISAT_PARTS)) == len(ENVISAT_PARTS)
    for name in ("bus", "solar_array", "solar_array_boom", "asar_antenna", "adapter_ring"):
        assert name in ENVISAT_PARTS


def test_triangle_count_in_documented_range(model):
    level, _, faces, _, _ = model
    low, high = TRIANGLE_RANGES[level]
    assert low <= len(faces) <= high


def test_bounding_box_matches_published_envelope(model):
    _, vertices, _, _, _ = model
    extents = vertices.max(axis=0) - vertices.min(axis=0)
    np.testing.assert_allclose(extents, PUBLISHED_ENVELOPE_M, rtol=ENVELOPE_TOLERANCE)


def test_every_part_is_a_closed_outward_solid(model):
    _, vertices, faces, face_part, names = model
    for index, name in enumerate(names):
        mesh = _part_mesh(vertices, faces, face_part, index)
        assert mesh.is_watertight, name
        assert mesh.is_winding_consistent, name
        # Each body separately encloses positive volume, so normals point out
        # of every body (a whole-part check could hide one inverted body).
        for body_faces in _bodies(mesh):
            body = trimesh.Trimesh(mesh.vertices, mesh.faces[body_faces], process=False)
            assert body.is_watertight, name
            assert body.volume > 0.0, name


def test_no_degenerate_faces(model):
    _, vertices, faces, _, _ = model
    assert (faces[:, 0] != faces[:, 1]).all()
    assert (faces[:, 1] != faces[:, 2]).all()
    assert (faces[:, 0] != faces[:, 2]).all()
    tri = vertices[faces]
    areas = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    assert areas.min() > 1e-6


def test_vertices_merged_within_parts_and_not_shared(model):
    _, vertices, faces, face_part, names = model
    # Every vertex is used, and by exactly one part.
    owner = np.full(len(vertices), -1)
    for index in range(len(names)):
        used = np.unique(faces[face_part == index])
        assert (owner[used] == -1).all(), names[index]
        owner[used] = index
        # No two vertices of a part at the same position.
        assert len(np.unique(vertices[used], axis=0)) == len(used), names[index]
    assert (owner >= 0).all()


def test_build_is_deterministic():
    for level in LEVELS:
        first = build_envisat(level)
        second = build_envisat(level)
        for a, b in zip(first[:3], second[:3]):
            assert a.dtype == b.dtype
            assert np.array_equal(a, b)
        assert first[3] == second[3]


def test_solar_array_area_is_both_sides_of_the_panel(model):
    _, vertices, faces, face_part, names = model
    mesh = _part_mesh(vertices, faces, face_part, names.index("solar_array"))
    expected = 2.0 * SOLAR_ARRAY_LENGTH_M * SOLAR_ARRAY_WIDTH_M
    assert expected == pytest.approx(2.0 * 14.0 * 5.0)
    # The thin edges add ~1.6 % on top of the two faces.
    assert mesh.area == pytest.approx(expected, rel=0.03)


def test_layout_matches_documented_frame():
    vertices, faces, face_part, names = build_envisat("coarse")

    def bounds(name):
        used = np.unique(faces[face_part == names.index(name)])
        return vertices[used].min(axis=0), vertices[used].max(axis=0)

    bus_lo, bus_hi = bounds("bus")
    np.testing.assert_allclose(0.5 * (bus_lo + bus_hi), 0.0, atol=1e-12)

    # Solar array beyond the +X end, offset toward +Y.
    array_lo, array_hi = bounds("solar_array")
    assert array_lo[0] > bus_hi[0] and array_lo[1] > bus_hi[1]

    # Adapter ring: ~1.2 m diameter, on the bus axis, at the +X end.
    ring_lo, ring_hi = bounds("adapter_ring")
    np.testing.assert_allclose(0.5 * (ring_lo + ring_hi)[1:], 0.0, atol=1e-9)
    assert ring_hi[0] > bus_hi[0] > ring_lo[0]
    assert 1.1 < ring_hi[1] - ring_lo[1] < 1.4

    # ASAR on -Y; nadir instruments on +Z; Ka-band antenna on the zenith side.
    assert bounds("asar_antenna")[1][1] < bus_lo[1]
    for name in ("meris", "aatsr", "ra2_antenna"):
        assert bounds(name)[1][2] > bus_hi[2], name
    assert bounds("ka_antenna")[1][2] < bus_lo[2]


def _nearest_hits(vertices, faces, origins, direction):
    """Möller-Trumbore: per ray, sorted hit distances and the hit face ids."""
    tri = vertices[faces]
    edge1 = tri[:, 1] - tri[:, 0]
    edge2 = tri[:, 2] - tri[:, 0]
    p = np.cross(direction, edge2)
    det = np.einsum("ij,ij->i", edge1, p)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origins[:, None, :] - tri[None, :, 0]
    u = np.einsum("rfj,fj->rf", s, p) * inv
    q = np.cross(s, edge1[None])
    v = (q @ direction) * inv
    t = np.einsum("rfj,fj->rf", q, edge2) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return np.where(hit, t, np.inf)


def test_no_coplanar_overlap_between_parts():
    """The first surface a ray meets is never shared by two parts.

    Coincident coplanar faces of different parts would make the returned part
    label depend on the ray caster's tie-breaking (z-fighting).
    """
    vertices, faces, face_part, _ = build_envisat("coarse")
    lo, hi = vertices.min(axis=0) - 1.0, vertices.max(axis=0) + 1.0
    rng = np.random.default_rng(1)
    directions = [np.eye(3)[k] * sign for k in range(3) for sign in (1.0, -1.0)]
    directions += list(rng.normal(size=(6, 3)))
    for direction in directions:
        direction = direction / np.linalg.norm(direction)
        # Origins spread over a plane behind the model, facing the direction.
        centre = 0.5 * (lo + hi) - direction * np.linalg.norm(hi - lo)
        helper = np.eye(3)[np.argmin(np.abs(direction))]
        e1 = np.cross(direction, helper)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(direction, e1)
        a, b = np.meshgrid(np.linspace(-15, 15, 61), np.linspace(-15, 15, 61))
        origins = centre + a.reshape(-1, 1) * e1 + b.reshape(-1, 1) * e2
        t = _nearest_hits(vertices, faces, origins, direction)
        hit_rays = np.isfinite(t.min(axis=1))
        t = t[hit_rays]
        first = t.min(axis=1, keepdims=True)
        # Faces hit within 1 mm of the first hit, from more than one part.
        near = t <= first + 1e-3
        for row in near:
            parts = np.unique(face_part[row])
            assert len(parts) == 1, parts


def test_named_levels_are_integer_factors():
    for name, settings in DETAIL_LEVELS.items():
        assert resolve_detail(settings.factor) == settings, name
        by_name = build_envisat(name)
        by_factor = build_envisat(settings.factor)
        assert all(np.array_equal(a, b) for a, b in zip(by_name[:3], by_factor[:3]))


def test_integer_factor_refines_monotonically():
    counts = [len(build_envisat(k)[1]) for k in range(0, 6)]
    assert counts == sorted(counts) and len(set(counts)) == len(counts)
    assert len(build_envisat(np.int64(2))[1]) == counts[2]


@pytest.mark.parametrize("bad", ["ultra", "", -1, MAX_TESSELLATION_FACTOR + 1])
def test_invalid_detail_value_rejected(bad):
    with pytest.raises(ValueError):
        build_envisat(bad)


@pytest.mark.parametrize("bad", [2.0, None, True])
def test_invalid_detail_type_rejected(bad):
    with pytest.raises(TypeError):
        build_envisat(bad)


def test_fine_build_is_fast():
    build_envisat("fine")  # warm imports and caches
    start = time.perf_counter()
    build_envisat("fine")
    # Typically well under 0.1 s; the bound only catches pathological slowdowns.
    assert time.perf_counter() - start < 5.0
