"""Benchmark the pure-NumPy TriangleBVH: build time and closest-hit rays/s.

Run from the repository root::

    python benchmarks/bench_bvh.py [--rays 100000] [--repeat 3]

Each scene is hit by bundles of rays from a single origin 50 m from the object,
spread uniformly over a cone aimed at it: once a 35 degree cone, once a cone
sized by bisection so that about half of the rays hit (misses are cheap, so
this second figure is the one comparable across scenes).  Timings are
single-threaded, best of ``--repeat`` runs, reported both per wall-clock second
and per CPU second of this process (the latter is the fairer figure on a busy
machine).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from lidarsim_core.backends._bvh import TriangleBVH  # noqa: E402


def satellite(detail: int) -> trimesh.Trimesh:
    """Satellite-like mesh: bus, two solar wings, dish, struts and nozzles.

    ``detail`` scales the tessellation; 0 gives ~20k faces, 1 gives ~100k.
    """
    sub = 4 + detail  # each subdivision quadruples a box's 12 faces
    parts = []
    bus = trimesh.creation.box(extents=(2.0, 2.0, 3.0))
    parts.append(_subdivided(bus, sub - 1))
    for side in (-1.0, 1.0):
        wing = trimesh.creation.box(extents=(7.0, 0.04, 1.8))
        wing.apply_translation((side * 5.0, 0.0, 0.0))
        parts.append(_subdivided(wing, sub - 1))
        boom = trimesh.creation.cylinder(radius=0.05, height=1.6, sections=32 * (1 + 3 * detail))
        boom.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))
        boom.apply_translation((side * 1.6, 0.0, 0.0))
        parts.append(boom)
    dish = trimesh.creation.icosphere(subdivisions=5 + detail, radius=1.2)
    dish.vertices[:, 2] *= 0.25
    dish.apply_translation((0.0, 0.0, 2.0))
    parts.append(dish)
    for dx, dy in ((0.6, 0.6), (-0.6, 0.6), (0.6, -0.6), (-0.6, -0.6)):
        nozzle = trimesh.creation.cone(radius=0.2, height=0.5, sections=64 * (1 + 3 * detail))
        nozzle.apply_translation((dx, dy, -2.0))
        parts.append(nozzle)
    return trimesh.util.concatenate(parts)


def _subdivided(mesh: trimesh.Trimesh, times: int) -> trimesh.Trimesh:
    for _ in range(times):
        mesh = mesh.subdivide()
    return mesh


def cone_rays(n: int, origin: np.ndarray, target: np.ndarray, full_angle_deg: float, seed: int = 0):
    """``n`` unit rays from ``origin`` uniformly filling a cone aimed at ``target``."""
    rng = np.random.default_rng(seed)
    axis = target - origin
    axis /= np.linalg.norm(axis)
    a = np.cross(axis, (0.0, 0.0, 1.0))
    a /= np.linalg.norm(a)
    b = np.cross(axis, a)
    cos_t = rng.uniform(np.cos(np.radians(full_angle_deg / 2)), 1.0, n)
    sin_t = np.sqrt(1.0 - cos_t**2)
    phi = rng.uniform(0.0, 2.0 * np.pi, n)
    dirs = cos_t[:, None] * axis + sin_t[:, None] * (
        np.cos(phi)[:, None] * a + np.sin(phi)[:, None] * b
    )
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    return np.tile(origin, (n, 1)), dirs


def half_hit_cone(bvh: TriangleBVH, origin, center, n_probe: int = 4000) -> float:
    """Full cone angle (degrees) at which about half of the rays hit, by bisection."""
    lo, hi = 0.5, 90.0
    for _ in range(12):
        mid = 0.5 * (lo + hi)
        o, d = cone_rays(n_probe, origin, center, mid, seed=1)
        if np.mean(bvh.intersect(o, d)[1] >= 0) > 0.5:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def bench(name: str, mesh: trimesh.Trimesh, n_rays: int, repeat: int) -> None:
    """Print build time and rays/s of one scene for a 35 degree and a half-hit cone."""
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces)
    t0, c0 = time.perf_counter(), time.process_time()
    bvh = TriangleBVH.build(vertices, faces)
    build_s, build_cpu = time.perf_counter() - t0, time.process_time() - c0
    print(
        f"{name}: faces={faces.shape[0]} nodes={bvh.n_nodes} depth={bvh.depth} "
        f"build {build_s:.3f} s wall / {build_cpu:.3f} s cpu"
    )

    center = 0.5 * (vertices.min(0) + vertices.max(0))
    origin = center + 50.0 * np.array([0.8, 0.36, 0.48])
    for cone_deg in (35.0, half_hit_cone(bvh, origin, center)):
        origins, dirs = cone_rays(n_rays, origin, center, cone_deg)
        wall = cpu = np.inf
        for _ in range(repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            _, face, _ = bvh.intersect(origins, dirs)
            wall = min(wall, time.perf_counter() - t0)
            cpu = min(cpu, time.process_time() - c0)
        print(
            f"    cone {cone_deg:5.1f} deg  hit {np.mean(face >= 0):6.1%}  "
            f"{n_rays / wall:>11,.0f} rays/s wall  {n_rays / cpu:>11,.0f} rays/s cpu"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rays", type=int, default=100_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    scenes = [
        ("satellite ~20k", satellite(0)),
        ("satellite ~100k", satellite(1)),
        ("icosphere sub5 r=10 m", trimesh.creation.icosphere(subdivisions=5, radius=10.0)),
        ("icosphere sub7 r=10 m", trimesh.creation.icosphere(subdivisions=7, radius=10.0)),
    ]
    for name, mesh in scenes:
        bench(name, mesh, args.rays, args.repeat)


if __name__ == "__main__":
    main()
