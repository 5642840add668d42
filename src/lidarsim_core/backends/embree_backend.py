"""Built-in plugin: the Embree backend (Intel Embree through ``embreex``; extra ``embree``).

Embree traces in float32. To keep precision at any scale, the mesh is stored relative to the
centre of its bounding box (so a mesh far from its body origin keeps float32 resolution), each
ray's origin is moved (in float64) to just before the mesh's bounding sphere and expressed
relative to that centre, and after Embree has found the face, the distance is recomputed in
float64 as the intersection of the original ray with that face's plane. Distances therefore
have float64 precision for the face found; only the choice of face is float32: rays passing
within ~1e-6 of the mesh size of a triangle edge may be attributed to the neighbouring face or
miss a silhouette edge that float64 would hit (:attr:`EmbreeBackend.edge_tolerance_rel`).
Embree releases the GIL, so chunks of rays run on several threads.

With the compiled kernels on (``LIDARSIM_KERNELS``), the backend calls Embree from numba
instead of through embreex: :mod:`.embree4` loads the Embree 4 library of embreex's wheel and
checks its ray/hit layout, and :func:`lidarsim_core.kernels.embree_cast.cast_refined` shifts
each ray, casts it in packets of up to 16 rays (``rtcIntersect16``: 1.8 × embreex's rays/s on
the demo's rays) and refines the distance, in one loop without the GIL. The scene is built as
embreex builds it (robust traversal, the same vertices), so the faces found are the same bit
for bit. Where the binding cannot load (an embreex without an Embree 4.0–4.4 library, a
layout that does not match), the backend casts through embreex as with ``LIDARSIM_KERNELS=numpy``
(:func:`binding_status` says why).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import Field

from .. import kernels
from ..base.errors import BackendError
from ..base.threads import in_pipeline_worker, shared_pool, worker_threads
from ..geometry.vec3 import add_vector, rowdot, scale_rows
from ..hookspecs import hookimpl
from ..scene.mesh import Mesh
from . import embree4
from .base import BackendOptions, CompiledCast, Hits, RayBackend, refine_on_faces

#: Fewest rays handed to a thread at once (smaller parts cost more in dispatch than they gain).
_MIN_PART = 4096


class EmbreeOptions(BackendOptions):
    """Options of the Embree backend."""

    threads: int = Field(0, ge=0, description="Worker threads; 0 = LIDARSIM_THREADS, else one "
                                              "per CPU core.")
    chunk_rays: int = Field(65536, ge=1024, description="Most rays per task handed to a thread.")


def binding_status() -> tuple[bool, str]:
    """Whether the Embree backend calls Embree from compiled code here (the kernels are on and
    the Embree 4 binding loads), and why not."""
    if not kernels.enabled():
        return False, "the compiled kernels are off (LIDARSIM_KERNELS=numpy or no numba)"
    return embree4.available()


@dataclass
class _PreparedEmbree:
    #: embreex's EmbreeScene, or the binding's :class:`.embree4.EmbreeScene` (``compiled``)
    scene: Any
    mesh: Mesh
    center: np.ndarray
    radius: float
    #: (F, 3) first vertex of every face (for the float64 refinement kernel)
    first_vertex: np.ndarray
    #: (address of rtcIntersectN, packet width N, RTCRayHit fields) for the compiled cast
    compiled: tuple[int, int, int] | None = None


class EmbreeBackend(RayBackend):
    """Intel Embree (embreex) ray caster: float32 traversal, float64 distances, all cores."""

    name = "embree"
    Options = EmbreeOptions
    options: EmbreeOptions
    precision = ("float32 traversal; distance recomputed in float64 on the hit face's plane "
                 "(exact to ~1e-12 relative); hit/miss may differ from float64 within ~1e-6 "
                 "of the mesh size from triangle edges.")
    distance_rtol = 1e-9
    edge_tolerance_rel = 1e-6
    thread_safe = True  # a committed Embree scene is read-only

    @classmethod
    def is_available(cls) -> tuple[bool, str]:
        try:
            import embreex  # noqa: F401
        except ImportError as exc:
            return False, f"embreex is not installed ({exc}); pip install 'lidarsim-core[embree]'"
        return True, ""

    def prepare(self, mesh: Mesh) -> _PreparedEmbree:
        ok, why = self.is_available()
        if not ok:
            raise BackendError(f"the 'embree' backend cannot run: {why}")
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        lo, hi = mesh.bounds
        center = (lo + hi) / 2
        radius = float(np.linalg.norm(hi - lo) / 2) * (1 + 1e-6) + 1e-9
        # relative to the box centre: float32 then resolves the mesh's own size, not its offset
        triangles = np.ascontiguousarray(mesh.triangles - center, dtype=np.float32)
        first_vertex = np.ascontiguousarray(mesh.vertices[mesh.faces[:, 0]])
        if binding_status()[0]:
            library = embree4.load()
            width = library.packet_width  # the widest the CPU traces natively
            return _PreparedEmbree(library.new_scene(triangles), mesh, center, radius,
                                   first_vertex, (library.intersect[width], width,
                                                  library.layout.fields))
        scene = rtcore_scene.EmbreeScene()
        TriangleMesh(scene, triangles)
        return _PreparedEmbree(scene, mesh, center, radius, first_vertex)

    def prepared_variant(self) -> bool:
        # the binding's scene or embreex's: a mesh prepared while the kernels were off is
        # not the one to cast with once they are on
        return binding_status()[0]

    def compiled_cast(self, mesh: Mesh) -> CompiledCast | None:
        """The binding's intersect function, scene and refinement arrays of ``mesh`` (None
        where the backend casts through embreex: no binding, or the kernels off)."""
        if not kernels.enabled():
            return None
        prepared = self.prepared(mesh)
        if prepared.compiled is None:
            return None
        address, width, fields = prepared.compiled
        return CompiledCast(address, prepared.scene.handle, width, fields, prepared.center,
                            prepared.radius, float(self.options.epsilon_m),
                            prepared.first_vertex,
                            np.ascontiguousarray(mesh.face_normals, dtype=np.float64), prepared)

    def _threads(self) -> int:
        if in_pipeline_worker():  # the pipeline's pieces already use every core
            return 1
        return self.options.threads or worker_threads()

    def intersect(self, prepared: _PreparedEmbree, origins: np.ndarray,
                  directions: np.ndarray) -> Hits:
        n = len(origins)
        face = np.empty(n, dtype=np.int64)
        if kernels.enabled():  # the refinement kernel writes every row
            distance, normal = np.empty(n), np.empty((n, 3))
        else:
            distance, normal = np.full(n, np.nan), np.full((n, 3), np.nan)
        threads = self._threads()
        # two parts per thread balance rays that hit (slow) against misses (fast)
        step = n if threads <= 1 else max(_MIN_PART, -(-n // (2 * threads)))
        step = min(self.options.chunk_rays, step)
        bounds = [(lo, min(lo + step, n)) for lo in range(0, n, step)]
        out = (face, distance, normal)
        if threads <= 1 or len(bounds) == 1:
            for lo, hi in bounds:
                self._cast_part(prepared, origins, directions, lo, hi, out)
        else:
            pool = shared_pool(threads)
            for job in [pool.submit(self._cast_part, prepared, origins, directions, lo, hi, out)
                        for lo, hi in bounds]:
                job.result()
        return Hits(distance, face, normal)

    def _cast_part(self, prepared: _PreparedEmbree, origins: np.ndarray,
                   directions: np.ndarray, lo: int, hi: int,
                   out: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
        """Cast rays ``lo:hi`` and write their hits into ``out`` (runs on a worker thread)."""
        eps = self.options.epsilon_m
        # shift, cast and refinement in one compiled loop (a mesh prepared with the kernels on
        # stays on this path if LIDARSIM_KERNELS changes later in the process: same bits)
        if prepared.compiled is not None:
            from ..kernels.embree_cast import cast_refined

            address, width, fields = prepared.compiled
            cast_refined(address, prepared.scene.handle, width, fields, origins, directions,
                         prepared.center, prepared.radius, eps, prepared.first_vertex,
                         prepared.mesh.face_normals, *out, lo, hi)
            return
        if kernels.enabled():  # the same arithmetic compiled: no temporaries, no GIL
            from ..kernels.raycast import embree_rays, refine_hits

            o32, d32 = embree_rays(origins[lo:hi], directions[lo:hi], prepared.center,
                                   prepared.radius, eps)
            face32 = prepared.scene.run(o32, d32)
            refine_hits(face32, origins, directions, prepared.first_vertex,
                        prepared.mesh.face_normals, eps, *out, lo)
            return
        o, d = origins[lo:hi], directions[lo:hi]
        # start each ray just before the bounding sphere, relative to the mesh centre (float64),
        # so that float32 only ever sees coordinates of the mesh's own size
        rel = add_vector(o, -prepared.center)
        shift = rowdot(rel, d)
        np.negative(shift, out=shift)
        shift -= prepared.radius
        np.maximum(shift, eps, out=shift)
        rel += scale_rows(d, shift)
        face = prepared.scene.run(rel.astype(np.float32), d.astype(np.float32))
        hit = np.flatnonzero(face >= 0)
        f = face[hit].astype(np.int64)
        dist, nrm = refine_on_faces(prepared.mesh, f, o[hit], d[hit])
        # a refined distance at or below epsilon is a grazing float32 artefact: count a miss
        good = dist > eps
        hit, f, dist, nrm = hit[good], f[good], dist[good], nrm[good]
        face_out, distance_out, normal_out = out
        face_out[lo:hi] = -1
        face_out[lo + hit] = f
        distance_out[lo + hit] = dist
        normal_out[lo + hit] = nrm


@hookimpl
def lidarsim_register_ray_backends(register: Any) -> None:
    """Register the Embree backend (embreex is imported only when it is used)."""
    register(EmbreeBackend)
