"""An independent ray-triangle reference (Möller–Trumbore in float64, every ray against every
triangle) that the conformance cases compare backends with, and rays over a satellite."""

from __future__ import annotations

import numpy as np

from ..backends.base import Hits
from ..scene.mesh import Mesh
from .meshes import unit


# ---- independent reference ------------------------------------------------------------------
def reference_intersect(mesh: Mesh, origins: np.ndarray, directions: np.ndarray,
                        epsilon: float = 1e-6, chunk: int = 64) -> Hits:
    """Closest hits by testing every ray against every triangle (float64 Möller–Trumbore).

    Degenerate faces and rays parallel to a face never hit; ties keep the lowest face index.
    Costs ``O(rays × faces)``: meant for a few thousand rays against ~10⁴ faces.
    """
    origins = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    directions = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    tri = mesh.triangles
    v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    usable = mesh.face_areas > 0
    n = len(origins)
    distance = np.full(n, np.nan)
    face = np.full(n, -1, dtype=np.int64)
    for lo in range(0, n, chunk):
        o = origins[lo:lo + chunk, None, :]
        d = directions[lo:lo + chunk, None, :]
        p = np.cross(d, e2)
        det = np.einsum("rfk,fk->rf", p, e1)
        parallel = np.abs(det) <= 1e-14 * np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            s = o - v0
            u = np.einsum("rfk,rfk->rf", s, p) * inv
            q = np.cross(s, e1)
            v = np.einsum("rfk,rfk->rf", np.broadcast_to(d, q.shape), q) * inv
            t = np.einsum("rfk,fk->rf", q, e2) * inv
        ok = usable & ~parallel & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > epsilon)
        t = np.where(ok, t, np.inf)
        best = np.argmin(t, axis=1)
        tb = t[np.arange(len(best)), best]
        hit = np.isfinite(tb)
        distance[lo:lo + chunk][hit] = tb[hit]
        face[lo:lo + chunk][hit] = best[hit]
    normal = np.full((n, 3), np.nan)
    normal[face >= 0] = mesh.face_normals[face[face >= 0]]
    return Hits(distance, face, normal)


def satellite_rays(mesh: Mesh, n: int, seed: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """Rays at a satellite from all around: origins 1.5–4 bounding radii from its centre
    (a tenth of them 2 km away), aimed at random points of its bounding box."""
    rng = np.random.default_rng(seed)
    lo, hi = mesh.bounds
    center, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo) / 2)
    dist = rng.uniform(1.5, 4.0, (n, 1)) * radius
    dist[: n // 10] = 2000.0
    origins = center + unit(rng.normal(size=(n, 3))) * dist
    aims = lo + rng.uniform(0.0, 1.0, (n, 3)) * (hi - lo)
    return origins, unit(aims - origins)
