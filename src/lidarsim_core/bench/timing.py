"""Timing helpers of the benchmark: best of interleaved rounds, thread settings, and bare
Embree on the same rays (the reference every pipeline figure is compared with)."""

from __future__ import annotations

import math
import os
import time
from typing import Any, Callable

import numpy as np

from ..base.threads import shared_pool
from ..scene.mesh import Mesh


def interleaved_best(probes: dict[str, Callable[[], Any]], rounds: int
                     ) -> tuple[dict[str, float], dict[str, float]]:
    """Shortest wall time (s) of each probe, measured in ``rounds`` interleaved rounds after
    one warm-up round, and the cores each probe kept busy on average (process CPU time over
    wall time).

    Running every probe once per round, rather than each probe many times in a row, spreads
    each probe's samples over the whole run: on a machine shared with other work, every
    figure then gets the same chance of catching the quiet moments, and their ratios are
    fair. The cores used show multi-threading at work even when other jobs hold the
    machine's other cores part of the time.
    """
    best = {name: math.inf for name in probes}
    wall = {name: 0.0 for name in probes}
    cpu = {name: 0.0 for name in probes}
    for round_ in range(rounds + 1):
        for name, probe in probes.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            probe()
            elapsed = time.perf_counter() - start
            if round_:
                best[name] = min(best[name], elapsed)
                wall[name] += elapsed
                cpu[name] += time.process_time() - start_cpu
    return best, {name: cpu[name] / wall[name] for name in probes if wall[name] > 0}


def bare_embree_probe(mesh: Mesh, origins: np.ndarray, directions: np.ndarray,
                      threads: int) -> Callable[[], Any] | None:
    """A function casting the rays with plain embreex in float32 on ``threads`` threads, with
    no lidarsim code around it (None without embreex)."""
    try:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
    except ImportError:
        return None
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, np.ascontiguousarray(mesh.triangles, dtype=np.float32))
    o32 = np.ascontiguousarray(origins, dtype=np.float32)
    d32 = np.ascontiguousarray(directions, dtype=np.float32)
    n = len(o32)
    if threads <= 1:
        return lambda: scene.run(o32, d32)
    # two parts per thread: the best split of a 100k-ray scan on this kind of machine
    # (1, 2, 4 parts per thread were measured within 10 % of each other)
    step = max(1024, -(-n // (2 * threads)))
    bounds = [(lo, min(lo + step, n)) for lo in range(0, n, step)]
    pool = shared_pool(threads)  # persistent threads, as the Embree backend's

    def cast() -> None:
        list(pool.map(lambda b: scene.run(o32[b[0]:b[1]], d32[b[0]:b[1]]), bounds))

    return cast


def with_threads(threads: int | None, func: Callable[[], Any]) -> Any:
    """Run ``func`` with ``LIDARSIM_THREADS`` set to ``threads`` (None: leave as is)."""
    if threads is None:
        return func()
    before = os.environ.get("LIDARSIM_THREADS")
    os.environ["LIDARSIM_THREADS"] = str(threads)
    try:
        return func()
    finally:
        if before is None:
            del os.environ["LIDARSIM_THREADS"]
        else:
            os.environ["LIDARSIM_THREADS"] = before


def threads_env(threads: int, func: Callable[[], Any]) -> Callable[[], Any]:
    return lambda: with_threads(threads, func)
