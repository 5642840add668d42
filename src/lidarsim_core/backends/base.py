"""The ray-backend contract and its base class.

Given a prepared mesh and rays (origins, unit directions, float64, in the mesh's body frame), a
backend returns for every ray the first hit with distance greater than ``epsilon_m``: the
distance (NaN on a miss), the face index (-1 on a miss) and the unit geometric normal of that
face (right-hand rule of its vertex order, not flipped toward the ray; NaN on a miss).
Backends may compute in float32 but return float64 and state their precision in
:attr:`RayBackend.precision`.
"""

from __future__ import annotations

import threading
from abc import abstractmethod
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from pydantic import Field

from ..base.components import Component, ComponentOptions
from ..geometry.vec3 import rowdot
from ..scene.mesh import Mesh


@dataclass(frozen=True)
class Hits:
    """Closest hits of N rays.

    Attributes
    ----------
    distance
        (N,) float64 distance along the ray (m); NaN for a miss.
    face
        (N,) int64 index of the hit face; -1 for a miss.
    normal
        (N, 3) float64 unit geometric normal of the hit face; NaN for a miss.
    """

    distance: np.ndarray
    face: np.ndarray
    normal: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """(N,) bool: which rays hit."""
        return self.face >= 0

    @classmethod
    def misses(cls, n: int) -> "Hits":
        """N misses."""
        return cls(np.full(n, np.nan), np.full(n, -1, dtype=np.int64), np.full((n, 3), np.nan))


@dataclass(frozen=True)
class CompiledCast:
    """What a compiled loop needs to cast on one prepared mesh without Python in between
    (:meth:`RayBackend.compiled_cast`): Embree's intersect function and scene by address, and
    the float64 arrays of the refinement
    (:func:`lidarsim_core.kernels.fused_cast.cast_closest`'s arguments).

    Attributes
    ----------
    intersect
        Address of ``rtcIntersect1`` (``width`` 1) or ``rtcIntersect{width}``.
    scene
        The committed scene's handle (valid while ``owner`` lives).
    width, fields
        Packet width and 4-byte fields of the library's ray/hit structure.
    centre, radius, epsilon
        The mesh's box centre (the scene is relative to it), bounding-sphere radius, and the
        backend's smallest distance.
    first_vertex, normals
        (F, 3) float64 first vertex and unit normal of every face.
    owner
        The prepared structure that owns the scene (kept alive with this handle).
    """

    intersect: int
    scene: int
    width: int
    fields: int
    centre: np.ndarray
    radius: float
    epsilon: float
    first_vertex: np.ndarray
    normals: np.ndarray
    owner: Any = field(repr=False)


class BackendOptions(ComponentOptions):
    """Options every backend accepts."""

    epsilon_m: float = Field(1e-6, ge=0, description="Hits closer than this are ignored (m).")


class RayBackend(Component):
    """Base of ray-casting backends.

    Subclasses implement :meth:`prepare` (build the acceleration structure of one mesh) and
    :meth:`intersect`. :meth:`cast` combines both with a per-process cache of prepared meshes.
    """

    Options: ClassVar[type[BackendOptions]] = BackendOptions
    options: BackendOptions
    #: One sentence on the numerical precision of returned distances.
    precision: ClassVar[str] = ""
    #: Bound on the error of returned distances, relative to the largest length involved
    #: (the distance, the ray origin's coordinates, the mesh's coordinates and extent).
    distance_rtol: ClassVar[float] = 1e-9
    #: Rays passing closer than this to a triangle edge, relative to the same length scale
    #: as the mesh (its largest coordinate or extent), may report a neighbouring face or miss
    #: a silhouette that exact arithmetic would hit.
    edge_tolerance_rel: ClassVar[float] = 1e-9
    #: Whether :meth:`intersect` may run on several threads at once on the same prepared mesh
    #: (the pipeline then casts pieces of a frame in parallel; otherwise on one thread).
    thread_safe: ClassVar[bool] = False
    #: Prepared meshes shared by every instance of the class, keyed by (options, mesh key).
    _cache_size: ClassVar[int] = 8

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls._prepared: OrderedDict[tuple, Any] = OrderedDict()
        cls._lock = threading.Lock()

    @classmethod
    def is_available(cls) -> tuple[bool, str]:
        """Whether the backend can run here, and why not (e.g. a missing optional package)."""
        return True, ""

    @abstractmethod
    def prepare(self, mesh: Mesh) -> Any:
        """Build the acceleration structure for ``mesh`` (called once per mesh and options)."""

    @abstractmethod
    def intersect(self, prepared: Any, origins: np.ndarray, directions: np.ndarray) -> Hits:
        """Closest hits of rays against a prepared mesh (see the module contract)."""

    def compiled_cast(self, mesh: Mesh) -> CompiledCast | None:
        """The handle a compiled loop casts ``mesh`` with, giving :meth:`cast`'s hits bit for
        bit, or None (the default) when the backend casts only through :meth:`cast`."""
        return None

    def prepared_variant(self) -> Any:
        """What a prepared structure depends on besides the options and the mesh (part of its
        cache key; None by default)."""
        return None

    def prepared(self, mesh: Mesh) -> Any:
        """The cached prepared structure of ``mesh``, building it on first use."""
        key = (self.options, mesh.key, self.prepared_variant())
        with self._lock:
            if key in self._prepared:
                self._prepared.move_to_end(key)
                return self._prepared[key]
        built = self.prepare(mesh)
        with self._lock:
            self._prepared[key] = built
            while len(self._prepared) > self._cache_size:
                self._prepared.popitem(last=False)
        return built

    def cast(self, mesh: Mesh, origins: np.ndarray, directions: np.ndarray) -> Hits:
        """Closest hits of rays against ``mesh`` (prepares and caches the mesh as needed)."""
        origins = np.ascontiguousarray(origins, dtype=np.float64).reshape(-1, 3)
        directions = np.ascontiguousarray(directions, dtype=np.float64).reshape(-1, 3)
        if len(origins) != len(directions):
            raise ValueError("origins and directions differ in length")
        if len(origins) == 0:
            return Hits.misses(0)
        return self.intersect(self.prepared(mesh), origins, directions)


def refine_on_faces(mesh: Mesh, face: np.ndarray, origins: np.ndarray,
                    directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact float64 distance to the plane of each hit face, and that face's unit normal.

    Used by backends that find the face in lower precision: the plane intersection of the
    known face is exact to float64 rounding. ``face`` must be >= 0 for every ray given.
    """
    normal = mesh.face_normals[face]
    v0 = mesh.vertices[mesh.faces[face, 0]]
    denom = rowdot(directions, normal)
    v0 -= origins
    with np.errstate(divide="ignore", invalid="ignore"):
        distance = rowdot(v0, normal) / denom
    return distance, normal
