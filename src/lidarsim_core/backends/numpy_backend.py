"""Built-in plugin: the pure-NumPy reference backend (float64 BVH, no compiled dependency)."""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field

from ..hookspecs import hookimpl
from ..scene.mesh import Mesh
from .base import BackendOptions, Hits, RayBackend


class NumpyOptions(BackendOptions):
    """Options of the NumPy backend."""

    leaf_size: int = Field(8, ge=1, le=64, description="Triangles per BVH leaf.")


class NumpyBackend(RayBackend):
    """Pure-NumPy float64 BVH ray caster: the reference every backend is checked against."""

    name = "numpy"
    Options = NumpyOptions
    options: NumpyOptions
    precision = "float64 Möller–Trumbore: distances exact to ~1e-12 relative."
    distance_rtol = 1e-9
    edge_tolerance_rel = 1e-9
    thread_safe = True  # the BVH is read-only after build

    def prepare(self, mesh: Mesh) -> Any:
        from ._bvh import TriangleBVH

        return TriangleBVH.build(mesh.vertices, mesh.faces, leaf_size=self.options.leaf_size)

    def intersect(self, prepared: Any, origins: np.ndarray, directions: np.ndarray) -> Hits:
        distance, face, normal = prepared.intersect(origins, directions,
                                                    t_min=self.options.epsilon_m)
        return Hits(distance, face.astype(np.int64), normal)


@hookimpl
def lidarsim_register_ray_backends(register: Any) -> None:
    """Register the NumPy backend."""
    register(NumpyBackend)
