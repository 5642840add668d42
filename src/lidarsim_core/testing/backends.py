"""The ray-backend conformance suite: one pytest class every backend must pass.

A backend author runs it on their backend with a few lines in their own test-suite::

    from lidarsim_core.testing.backends import BackendConformance

    class TestMyBackend(BackendConformance):
        backend_name = "mine"                 # as registered through lidarsim_register_ray_backends
        backend_options = {"threads": 2}      # optional

(or set ``backend_class = MyBackend`` to test a class that is not registered). The suite checks
the contract of :mod:`lidarsim_core.backends.base` on canonical scenes whose answers are
computed from their geometry (:mod:`lidarsim_core.testing.ray_cases`): closest hit beyond
epsilon, distances within the backend's stated
:attr:`~lidarsim_core.backends.base.RayBackend.distance_rtol`, face indices and unflipped geometric normals, plane/sphere/box (faces, edges, corners), grazing
and parallel rays, thin plates, rays from inside, degenerate and duplicated triangles, open
meshes, millimetre to kilometre scenes with far origins, empty ray sets and rays that all miss.
On the Envisat model it compares the backend with a brute-force float64 caster and with every
other available registered backend: hit/miss and faces must agree except for rays within the
backends' stated edge tolerance of a triangle edge, and distances within their precision.

A backend whose :meth:`~lidarsim_core.backends.base.RayBackend.is_available` says no is skipped,
with the reason it gives.
"""

from __future__ import annotations

import functools
from typing import Any, ClassVar

import numpy as np
import pytest

from ..backends.base import Hits, RayBackend
from ..scene.mesh import Mesh
from .ray_cases import RayCase, canonical_cases, distance_to_triangle_edges, mesh_scale
from .reference import reference_intersect, satellite_rays

#: Identifiers of the canonical cases run by :meth:`BackendConformance.test_canonical_scene`.
CASE_IDS: tuple[str, ...] = (
    "plane_normal", "plane_grazing", "sphere_outside", "sphere_inside", "box_faces",
    "box_edges", "box_corners", "thin_plate", "inside_closed", "parallel",
    "degenerate_duplicate", "open_mesh", "closest", "epsilon", "small", "small_far", "large",
    "far_coordinates", "all_miss",
)

_SHOWN = 6  # offending rays listed in a failure message


@functools.lru_cache(maxsize=1)
def satellite_mesh() -> Mesh:
    """The built-in Envisat model at medium detail (~10k triangles)."""
    from ..plugins.manager import get_registry

    model = get_registry().get("target_model", "envisat")
    return model.from_config({"detail": "medium"}).mesh()


@functools.lru_cache(maxsize=4)
def _cases(epsilon: float) -> dict[str, RayCase]:
    return canonical_cases(epsilon)


@functools.lru_cache(maxsize=4)
def _reference(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, Hits]:
    mesh = satellite_mesh()
    origins, directions = satellite_rays(mesh, n, seed)
    return origins, directions, reference_intersect(mesh, origins, directions)


def _epsilon(backend: RayBackend) -> float:
    return float(getattr(backend.options, "epsilon_m", 1e-6))


def check_contract(hits: Hits, mesh: Mesh, n: int, epsilon: float) -> None:
    """Assert the form of a backend's answer: shapes, dtypes, miss/hit consistency, distances
    beyond ``epsilon`` and unit geometric normals equal to the hit faces' normals."""
    assert isinstance(hits, Hits), f"backend returned {type(hits).__name__}, not Hits"
    assert hits.distance.shape == (n,) and hits.distance.dtype == np.float64, \
        f"distance must be ({n},) float64, got {hits.distance.shape} {hits.distance.dtype}"
    assert hits.face.shape == (n,) and hits.face.dtype == np.int64, \
        f"face must be ({n},) int64, got {hits.face.shape} {hits.face.dtype}"
    assert hits.normal.shape == (n, 3) and hits.normal.dtype == np.float64, \
        f"normal must be ({n}, 3) float64, got {hits.normal.shape} {hits.normal.dtype}"
    hit = hits.face >= 0
    assert np.all(hits.face < mesh.n_faces), "face index beyond the mesh's faces"
    assert np.all(hits.face >= -1), "a miss must be face -1"
    assert np.all(np.isnan(hits.distance[~hit])), "a miss must have distance NaN"
    assert np.all(np.isnan(hits.normal[~hit])), "a miss must have normal NaN"
    assert np.all(np.isfinite(hits.distance[hit])), "a hit must have a finite distance"
    assert np.all(hits.distance[hit] > epsilon), f"hits must lie beyond epsilon = {epsilon} m"
    assert np.all(mesh.face_areas[hits.face[hit]] > 0), "a degenerate (zero-area) face was hit"
    np.testing.assert_allclose(hits.normal[hit], mesh.face_normals[hits.face[hit]], rtol=0,
                               atol=1e-12, err_msg="normal must be the hit face's geometric "
                                                   "normal (right-hand rule, not flipped)")


def check_case(backend: RayBackend, case: RayCase) -> None:
    """Cast a canonical case and assert the exact answer within the backend's precision."""
    hits = backend.cast(case.mesh, case.origins, case.directions)
    check_contract(hits, case.mesh, len(case), _epsilon(backend))
    expected_hit = np.isfinite(case.distance)
    scale = np.maximum.reduce([np.abs(case.origins).max(axis=1),
                               np.full(len(case), mesh_scale(case.mesh)),
                               np.nan_to_num(case.distance)])
    tol = backend.distance_rtol * scale
    problems = []
    for i in range(len(case)):
        got_d, got_f = hits.distance[i], int(hits.face[i])
        want_d, want_f = case.distance[i], sorted(case.faces[i])
        if expected_hit[i] != (got_f >= 0):
            what = f"hit face {got_f} at {got_d!r} m" if got_f >= 0 else "missed"
            want = f"a hit at {want_d!r} m on faces {want_f}" if want_f else "a miss"
            problems.append(f"ray {i}: {what}; expected {want}")
        elif got_f >= 0 and abs(got_d - want_d) > tol[i]:
            problems.append(f"ray {i}: distance {got_d!r} m, expected {want_d!r} m "
                            f"(error {got_d - want_d:.3g} m > {tol[i]:.3g} m)")
        elif got_f >= 0 and got_f not in case.faces[i]:
            problems.append(f"ray {i}: hit face {got_f}, expected one of {want_f}")
    if problems:
        shown = "\n  ".join(problems[:_SHOWN])
        more = f"\n  ... and {len(problems) - _SHOWN} more" if len(problems) > _SHOWN else ""
        pytest.fail(f"{case.name}: {len(problems)} of {len(case)} rays wrong "
                    f"({type(backend).__name__}):\n  {shown}{more}", pytrace=False)


def compare_hits(mesh: Mesh, origins: np.ndarray, directions: np.ndarray, a: Hits, b: Hits,
                 distance_rtol: float, edge_tolerance_rel: float) -> tuple[list[str], int]:
    """Differences between two answers for the same rays that tolerances do not explain.

    Hit/miss and face may differ only where the nearer reported hit point lies within
    ``edge_tolerance_rel * mesh_scale(mesh)`` of an edge of its face; distances of two hits must
    agree within ``distance_rtol`` of the largest length involved (two different faces at the
    same distance are a shared edge or duplicated faces, and agree).

    Returns
    -------
    problems, tolerated
        Descriptions of the unexplained differences, and how many differences the edge
        tolerance explained.
    """
    edge_tol = edge_tolerance_rel * mesh_scale(mesh)
    scale = np.maximum(np.abs(origins).max(axis=1), mesh_scale(mesh))
    both = a.hit & b.hit
    d_tol = distance_rtol * np.maximum(scale, np.fmax(a.distance, b.distance))
    same_distance = both & (np.abs(a.distance - b.distance) <= d_tol)
    differ = (a.hit != b.hit) | (both & ~same_distance)
    # the nearer reported hit of each differing ray, and its distance to its face's edges
    near_a = a.hit & (~b.hit | (a.distance < b.distance))
    face = np.where(near_a, a.face, b.face)
    dist = np.where(near_a, a.distance, b.distance)
    idx = np.flatnonzero(differ)
    points = origins[idx] + dist[idx, None] * directions[idx]
    edge = distance_to_triangle_edges(mesh, face[idx], points)
    near_edge = edge <= edge_tol
    problems = []
    for i, e in zip(idx[~near_edge], edge[~near_edge]):
        problems.append(f"ray {i}: A face {a.face[i]} at {a.distance[i]!r} m, B face {b.face[i]} "
                        f"at {b.distance[i]!r} m; nearer hit {e:.3g} m from an edge "
                        f"(tolerance {edge_tol:.3g} m)")
    return problems, int(near_edge.sum())


class BackendConformance:
    """Subclass me (named ``Test...``) and set :attr:`backend_name` or :attr:`backend_class`.

    Attributes
    ----------
    backend_name
        Registered name of the backend under test (looked up in the plugin registry).
    backend_class
        Alternatively, the backend class itself (for a class that is not registered).
    backend_options
        Options passed to the backend (validated by its ``Options`` model).
    reference_rays
        Rays of the brute-force comparison on Envisat.
    agreement_rays
        Rays of the comparison with every other available registered backend.
    """

    backend_name: ClassVar[str | None] = None
    backend_class: ClassVar[type[RayBackend] | None] = None
    backend_options: ClassVar[dict[str, Any]] = {}
    reference_rays: ClassVar[int] = 1500
    agreement_rays: ClassVar[int] = 20000

    @classmethod
    def resolve_backend_class(cls) -> type[RayBackend]:
        """The class under test, from :attr:`backend_class` or the registry."""
        if cls.backend_class is not None:
            return cls.backend_class
        if not cls.backend_name:
            raise TypeError(f"{cls.__name__} sets neither backend_name nor backend_class")
        from ..plugins.manager import get_registry

        return get_registry().get("ray_backend", cls.backend_name)

    @pytest.fixture(scope="class")
    @classmethod
    def backend(cls) -> RayBackend:
        """The backend under test (skips the class when it cannot run here)."""
        backend_cls = cls.resolve_backend_class()
        ok, why = backend_cls.is_available()
        if not ok:
            pytest.skip(f"ray backend '{backend_cls.name}' is not available: {why}")
        return backend_cls.from_config(cls.backend_options)

    # ---- canonical scenes with exact answers ----------------------------------------------
    @pytest.mark.parametrize("case_id", CASE_IDS)
    def test_canonical_scene(self, backend: RayBackend, case_id: str) -> None:
        """Each canonical scene gives its exact answer within the stated precision."""
        check_case(backend, _cases(_epsilon(backend))[case_id])

    def test_empty_ray_set(self, backend: RayBackend) -> None:
        """No rays give empty, well-typed results."""
        mesh = _cases(_epsilon(backend))["box_faces"].mesh
        hits = backend.cast(mesh, np.empty((0, 3)), np.empty((0, 3)))
        check_contract(hits, mesh, 0, _epsilon(backend))

    def test_prepared_mesh_is_cached(self, backend: RayBackend) -> None:
        """Preparing a mesh twice returns the cached structure (built once per mesh)."""
        mesh = _cases(_epsilon(backend))["sphere_inside"].mesh
        assert backend.prepared(mesh) is backend.prepared(mesh)

    # ---- robustness of the interface ---------------------------------------------------------
    def test_results_do_not_depend_on_batching(self, backend: RayBackend) -> None:
        """A ray's answer does not depend on the other rays cast with it, or on repetition."""
        origins, directions, _ = _reference(self.reference_rays, 7)
        mesh = satellite_mesh()
        whole = backend.cast(mesh, origins, directions)
        again = backend.cast(mesh, origins, directions)
        order = np.random.default_rng(3).permutation(len(origins))
        shuffled = backend.cast(mesh, origins[order], directions[order])
        parts = [backend.cast(mesh, origins[i:i + 97], directions[i:i + 97])
                 for i in range(0, len(origins), 97)]
        for label, other, index in (("repeated", again, slice(None)),
                                    ("permuted", shuffled, np.argsort(order)),
                                    ("in batches of 97", Hits(
                                        np.concatenate([p.distance for p in parts]),
                                        np.concatenate([p.face for p in parts]),
                                        np.concatenate([p.normal for p in parts])), slice(None))):
            np.testing.assert_array_equal(other.face[index], whole.face, err_msg=label)
            np.testing.assert_array_equal(other.distance[index], whole.distance, err_msg=label)

    def test_concurrent_casts_agree(self, backend: RayBackend) -> None:
        """A ``thread_safe`` backend gives the same answers when cast from several threads."""
        if not backend.thread_safe:
            pytest.skip("the backend does not declare thread_safe: the pipeline casts on one "
                        "thread")
        from concurrent.futures import ThreadPoolExecutor

        origins, directions, _ = _reference(self.reference_rays, 7)
        mesh = satellite_mesh()
        serial = backend.cast(mesh, origins, directions)
        parts = np.array_split(np.arange(len(origins)), 8)
        with ThreadPoolExecutor(4) as pool:
            results = list(pool.map(lambda i: backend.cast(mesh, origins[i], directions[i]),
                                    parts + parts))
        for i, hits in zip(parts + parts, results):
            np.testing.assert_array_equal(hits.face, serial.face[i])
            np.testing.assert_array_equal(hits.distance, serial.distance[i])

    def test_accepts_float32_and_strided_input(self, backend: RayBackend) -> None:
        """float32, non-contiguous and list inputs are accepted and converted to float64."""
        case = _cases(_epsilon(backend))["box_faces"]
        o32 = case.origins.astype(np.float32)
        d32 = case.directions.astype(np.float32)
        as64 = backend.cast(case.mesh, o32.astype(np.float64), d32.astype(np.float64))
        got = backend.cast(case.mesh, o32, d32)
        np.testing.assert_array_equal(got.face, as64.face)
        np.testing.assert_array_equal(got.distance, as64.distance)
        wide = np.zeros((len(case), 6))
        wide[:, ::2] = case.origins
        strided = backend.cast(case.mesh, wide[:, ::2], case.directions.tolist())
        reference = backend.cast(case.mesh, case.origins, case.directions)
        np.testing.assert_array_equal(strided.face, reference.face)
        np.testing.assert_array_equal(strided.distance, reference.distance)

    # ---- a realistic satellite scene ------------------------------------------------------------
    def test_satellite_contract(self, backend: RayBackend) -> None:
        """On Envisat: well-formed answers with a sound share of hits."""
        origins, directions, _ = _reference(self.reference_rays, 7)
        hits = backend.cast(satellite_mesh(), origins, directions)
        check_contract(hits, satellite_mesh(), len(origins), _epsilon(backend))
        assert 0.2 < hits.hit.mean() < 0.9

    def test_satellite_matches_brute_force(self, backend: RayBackend) -> None:
        """On Envisat, from 1.5 to 4 radii and from 2 km: same hits, faces and distances as a
        brute-force float64 test of every triangle, except within the edge tolerance."""
        origins, directions, truth = _reference(self.reference_rays, 7)
        mesh = satellite_mesh()
        hits = backend.cast(mesh, origins, directions)
        problems, tolerated = compare_hits(mesh, origins, directions, hits, truth,
                                           backend.distance_rtol + 1e-12,
                                           backend.edge_tolerance_rel + 1e-12)
        assert not problems, (f"{len(problems)} rays disagree with the brute-force reference "
                              f"(A = backend, B = reference; {tolerated} more within the edge "
                              "tolerance):\n  " + "\n  ".join(problems[:_SHOWN]))
        assert tolerated <= max(3, len(origins) // 500), \
            f"{tolerated} rays differ near edges: the edge tolerance is too loose to be honest"

    def test_agrees_with_other_backends(self, backend: RayBackend) -> None:
        """On Envisat, every other available registered backend gives the same hits, faces
        and distances, except within the two backends' stated tolerances."""
        from ..plugins.manager import get_registry

        registry = get_registry()
        others = []
        for entry in registry.iter("ray_backend"):
            if entry.obj is type(backend) or not entry.obj.is_available()[0]:
                continue
            others.append(entry.obj.from_config({}))
        if not others:
            pytest.skip("no other available ray backend to compare with")
        mesh = satellite_mesh()
        origins, directions = satellite_rays(mesh, self.agreement_rays, seed=8)
        mine = backend.cast(mesh, origins, directions)
        for other in others:
            theirs = other.cast(mesh, origins, directions)
            problems, tolerated = compare_hits(
                mesh, origins, directions, mine, theirs,
                backend.distance_rtol + other.distance_rtol,
                backend.edge_tolerance_rel + other.edge_tolerance_rel)
            assert not problems, (f"{len(problems)} of {len(origins)} rays disagree with "
                                  f"backend '{other.name}' (A = this backend, B = "
                                  f"'{other.name}'; {tolerated} more within the edge tolerance)"
                                  ":\n  " + "\n  ".join(problems[:_SHOWN]))
