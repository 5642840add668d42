"""The ctypes binding to embreex's Embree 4 library (lidarsim_core.backends.embree4) and the
kernels that call it (lidarsim_core.kernels.embree_cast): the library is found in embreex's
installation, its ray/hit layout is checked against its version and refused where it does
not match, and the faces found are embreex's own, bit for bit, on rays that miss, graze
silhouettes, pass through vertices and edges, and start inside the mesh; the Embree backend
gives the same bits through the binding as through embreex."""

from __future__ import annotations

import dataclasses
import gc
import importlib.metadata
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("embreex", reason="the Embree binding loads the library embreex installs")

from lidarsim_core import kernels  # noqa: E402
from lidarsim_core.backends import embree4  # noqa: E402
from lidarsim_core.base.errors import BackendError  # noqa: E402
from lidarsim_core.testing.meshes import box_mesh, icosphere_mesh, unit  # noqa: E402

needs_numba = pytest.mark.skipif(not kernels.numba_importable(),
                                 reason="the compiled casts need numba (extra 'fast')")


def _embreex_faces(triangles: np.ndarray, origins: np.ndarray, directions: np.ndarray,
                   **scene_kwargs) -> np.ndarray:
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene(**scene_kwargs)
    TriangleMesh(scene, triangles)
    return scene.run(np.ascontiguousarray(origins, np.float32),
                     np.ascontiguousarray(directions, np.float32))


def _hard_rays(mesh, n: int, seed: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """Rays through vertices and edge midpoints, tangent to the circumscribed sphere (grazing
    the silhouette), from inside, and in random directions (mostly misses)."""
    rng = np.random.default_rng(seed)
    v, f = mesh.vertices, mesh.faces
    scale = float(np.abs(v).max())
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    k = n // 5
    origins = rng.normal(size=(5 * k, 3)) * 3 * scale
    targets = np.empty_like(origins)
    targets[:k] = v[rng.integers(0, len(v), k)]  # through a vertex
    e = edges[rng.integers(0, len(edges), k)]
    targets[k:2 * k] = (v[e[:, 0]] + v[e[:, 1]]) / 2  # through an edge's midpoint
    # tangent to the sphere through a vertex: direction perpendicular to the radius there
    p = v[rng.integers(0, len(v), k)]
    side = unit(np.cross(p, rng.normal(size=(k, 3))))
    origins[2 * k:3 * k] = p - 3 * scale * side
    targets[2 * k:3 * k] = p
    origins[3 * k:4 * k] *= 0.05 / 3  # from inside the mesh
    targets[3 * k:4 * k] = rng.normal(size=(k, 3)) * scale
    targets[4 * k:] = origins[4 * k:] + rng.normal(size=(k, 3))  # anywhere: mostly misses
    return origins, unit(targets - origins)


def test_the_library_is_embreexs_and_its_layout_matches_its_version():
    library = embree4.load()
    dist = importlib.metadata.distribution("embreex")
    assert library.path.is_file() and "embree4" in library.path.name
    assert library.path.resolve().is_relative_to(Path(str(dist.locate_file(""))).resolve())
    assert library.version[0] == 4 and library.version[1] in embree4.KNOWN_LAYOUTS
    # Embree's headers: RTCRay is 12 words; RTCHit is Ng, u, v, primID, geomID, instID[L]
    # (and instPrimID[L] from 4.3), both aligned to 16 bytes: 80 or 96 bytes with one level
    assert library.layout.nbytes(1) == (96 if library.version[1] >= 3 else 80)
    assert library.layout.nbytes(8) == 8 * library.layout.fields * 4
    assert library.intersect[1] and len(set(library.intersect.values())) == 4
    assert embree4.load() is library  # loaded once per process


def test_a_wrong_layout_is_refused_before_anything_is_cast():
    library = embree4.load()
    wrong = embree4.RayHitLayout(library.layout.instance_levels,
                                 not library.layout.instance_array)
    with pytest.raises(BackendError, match=rf"{wrong.nbytes(1)}-byte RTCRayHit.*cannot be called"):
        embree4._probe_layout(dataclasses.replace(library, layout=wrong))


def test_an_unknown_version_is_refused(monkeypatch):
    library = embree4.load()
    monkeypatch.setattr(embree4, "KNOWN_LAYOUTS",
                        {k: v for k, v in embree4.KNOWN_LAYOUTS.items() if k != library.version[1]})
    embree4._load_cached.cache_clear()
    try:
        with pytest.raises(BackendError, match=rf"version {library.version_text}; its ray/hit"):
            embree4.load()
        ok, why = embree4.available()
        assert not ok and "known for Embree" in why
    finally:
        embree4._load_cached.cache_clear()
        monkeypatch.undo()
    assert embree4.load().version == library.version


def test_a_missing_embreex_is_a_clear_error(monkeypatch):
    def missing(name):
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "distribution", missing)
    with pytest.raises(BackendError, match="embreex is not installed"):
        embree4.library_path()


def test_a_scene_is_released_when_collected():
    library = embree4.load()
    scene = library.new_scene(box_mesh([-1, -1, -1], [1, 1, 1]).triangles.astype(np.float32))
    finalizer = scene._finalizer
    assert finalizer.alive
    del scene
    gc.collect()
    assert not finalizer.alive


def test_bad_triangles_are_refused():
    library = embree4.load()
    with pytest.raises(ValueError, match=r"\(F, 3, 3\)"):
        library.new_scene(np.zeros((4, 3), np.float32))
    with pytest.raises(BackendError, match="1 to"):
        library.new_scene(np.zeros((0, 3, 3), np.float32))


@needs_numba
def test_hits_are_analytic_on_a_plate():
    """Rays through a square plate hit the triangle they cross, rays beside it miss."""
    library = embree4.load()
    quad = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    scene = library.new_scene(quad[[[0, 1, 2], [0, 2, 3]]])
    rng = np.random.default_rng(3)
    xy = rng.uniform(-2, 2, size=(4000, 2))
    xy = xy[np.abs(np.abs(xy) - 1).min(axis=1) > 1e-3]  # away from the plate's rim
    xy = xy[np.abs(xy[:, 0] - xy[:, 1]) > 1e-3]  # and from the diagonal between its faces
    origins = np.column_stack([xy, np.full(len(xy), -5.0)])
    directions = np.tile([0.0, 0.0, 1.0], (len(xy), 1))
    inside = np.all(np.abs(xy) < 1, axis=1)
    expected = np.where(inside, np.where(xy[:, 0] > xy[:, 1], 0, 1), -1)
    for width in embree4.PACKET_WIDTHS:
        assert np.array_equal(scene.faces(origins, directions, width), expected)


@needs_numba
@pytest.mark.parametrize("mesh", [icosphere_mesh(2.0, 3), box_mesh([-1, -2, -0.5], [1, 2, 0.5])],
                         ids=["icosphere", "box"])
def test_faces_equal_embreexs_on_hard_rays(mesh):
    triangles = np.ascontiguousarray(mesh.triangles, np.float32)
    origins, directions = _hard_rays(mesh, 50_000)
    reference = _embreex_faces(triangles, origins, directions)
    hit = reference >= 0
    assert 0.2 < hit.mean() < 0.9  # hits and misses both well represented
    scene = embree4.load().new_scene(triangles)
    for width in embree4.PACKET_WIDTHS:
        assert np.array_equal(scene.faces(origins, directions, width), reference), width
    # the scene flags follow embreex's: its non-robust scene differs on these rays, and so
    # does the binding's in the same rays
    plain = _embreex_faces(triangles, origins, directions, robust=False)
    assert np.array_equal(embree4.load().new_scene(triangles, robust=False)
                          .faces(origins, directions), plain)


@needs_numba
def test_threads_share_a_scene():
    mesh = icosphere_mesh(1.0, 3)
    scene = embree4.load().new_scene(mesh.triangles.astype(np.float32))
    origins, directions = _hard_rays(mesh, 20_000, seed=11)
    alone = scene.faces(origins, directions, 8)
    with ThreadPoolExecutor(4) as pool:
        parts = list(pool.map(lambda w: scene.faces(origins, directions, w), [8, 1, 16, 4] * 2))
    assert all(np.array_equal(p, alone) for p in parts)


@needs_numba
@pytest.mark.parametrize("threads", [1, 3])
def test_the_backend_gives_embreexs_bits_through_the_binding(threads, monkeypatch):
    from lidarsim_core.backends.embree_backend import EmbreeBackend, binding_status

    monkeypatch.setenv("LIDARSIM_KERNELS", "auto")
    assert binding_status() == (True, "")
    # a mesh far from its body origin: the shift and refinement in float64 are exercised
    offset = np.array([250.0, -40.0, 9.0])
    sphere = icosphere_mesh(3.0, 3)
    mesh = type(sphere).from_arrays(sphere.vertices + offset, sphere.faces)
    origins, directions = _hard_rays(sphere, 40_000, seed=5)
    origins = origins + offset
    backend = EmbreeBackend(EmbreeBackend.Options(threads=threads, chunk_rays=4096))
    compiled = backend.prepare(mesh)
    assert compiled.compiled is not None
    via_embreex = dataclasses.replace(compiled, compiled=None,
                                      scene=_embreex_scene(compiled.scene))
    a = backend.intersect(compiled, origins, directions)
    b = backend.intersect(via_embreex, origins, directions)
    assert 0.2 < a.hit.mean() < 0.9
    monkeypatch.setenv("LIDARSIM_KERNELS", "numpy")  # the NumPy reference around embreex
    c = backend.intersect(via_embreex, origins, directions)
    for other in (b, c):
        for x, y in ((a.face, other.face), (a.distance, other.distance),
                     (a.normal, other.normal)):
            assert x.tobytes() == y.tobytes()


def _embreex_scene(binding_scene):
    """embreex's scene of the same float32 triangles the binding's scene holds."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, np.ascontiguousarray(binding_scene._vertices[:, :3].reshape(-1, 3, 3)))
    return scene


@needs_numba
def test_without_the_binding_the_backend_casts_through_embreex(monkeypatch):
    from lidarsim_core.backends import embree_backend
    from lidarsim_core.backends.embree_backend import EmbreeBackend

    monkeypatch.setenv("LIDARSIM_KERNELS", "auto")
    mesh = icosphere_mesh(1.0, 2)
    origins, directions = _hard_rays(mesh, 5_000, seed=2)
    backend = EmbreeBackend()
    through_binding = backend.intersect(backend.prepare(mesh), origins, directions)

    def refuse():
        raise BackendError("the Embree library x is version 4.9.0; its ray/hit layout is known "
                           "for Embree 4.0 only")

    monkeypatch.setattr(embree4, "load", refuse)
    ok, why = embree_backend.binding_status()
    assert not ok and "version 4.9.0" in why
    prepared = backend.prepare(mesh)
    assert prepared.compiled is None and type(prepared.scene).__module__.startswith("embreex")
    through_embreex = backend.intersect(prepared, origins, directions)
    assert through_binding.face.tobytes() == through_embreex.face.tobytes()
    assert through_binding.distance.tobytes() == through_embreex.distance.tobytes()


@needs_numba
def test_a_mesh_prepared_with_the_kernels_off_is_prepared_again_with_them_on(monkeypatch):
    """The prepared meshes are cached per backend class: one prepared through embreex while
    LIDARSIM_KERNELS=numpy is not the one the compiled loop gets once the kernels are on."""
    from lidarsim_core.backends.embree_backend import EmbreeBackend

    mesh = icosphere_mesh(2.5, 2)
    backend = EmbreeBackend()
    monkeypatch.setenv("LIDARSIM_KERNELS", "numpy")
    assert backend.prepared(mesh).compiled is None
    assert backend.compiled_cast(mesh) is None
    monkeypatch.setenv("LIDARSIM_KERNELS", "auto")
    assert backend.prepared(mesh).compiled is not None
    assert backend.compiled_cast(mesh) is not None
