"""Timing helpers of the benchmark: best of interleaved rounds, thread settings, and bare
Embree on the same rays (the reference every pipeline figure is compared with), through
embreex and through the fastest call of lidarsim's Embree binding (packets)."""

from __future__ import annotations

import math
import os
import time
from typing import Any, Callable

import numpy as np

from ..backends import embree4
from ..base.errors import BackendError
from ..base.threads import shared_pool
from ..scene.mesh import Mesh


def interleaved_best(probes: dict[str, Callable[[], Any]], rounds: int, warmup: int = 1
                     ) -> tuple[dict[str, float], dict[str, float]]:
    """Shortest wall time (s) of each probe, measured in ``rounds`` interleaved rounds after
    ``warmup`` interleaved rounds that are not timed, and the cores each probe kept busy on
    average (process CPU time over wall time).

    Running every probe once per round, rather than each probe many times in a row, spreads
    each probe's samples over the whole run: on a machine shared with other work, every
    figure then gets the same chance of catching the quiet moments, and their ratios are
    fair. The cores used show multi-threading at work even when other jobs hold the
    machine's other cores part of the time.
    """
    best = {name: math.inf for name in probes}
    wall = {name: 0.0 for name in probes}
    cpu = {name: 0.0 for name in probes}
    for round_ in range(rounds + warmup):
        for name, probe in probes.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            probe()
            elapsed = time.perf_counter() - start
            if round_ >= warmup:
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


def packet_embree_probe(mesh: Mesh, origins: np.ndarray, directions: np.ndarray,
                        threads: int) -> Callable[[], Any] | None:
    """As :func:`bare_embree_probe`, through the fastest call of lidarsim's Embree binding
    (:mod:`lidarsim_core.backends.embree4`): the same float32 rays, traced by the compiled
    :func:`~lidarsim_core.kernels.embree_cast.cast_faces` in packets of the widest width the
    CPU traces natively (None where the binding or numba is missing)."""
    try:
        library = embree4.load()
        from ..kernels.embree_cast import cast_faces
    except (BackendError, ImportError):
        return None
    scene = library.new_scene(np.ascontiguousarray(mesh.triangles, dtype=np.float32))
    width, fields = library.packet_width, library.layout.fields
    address = library.intersect[width]
    o32 = np.ascontiguousarray(origins, dtype=np.float32)
    d32 = np.ascontiguousarray(directions, dtype=np.float32)
    out = np.empty(len(o32), dtype=np.int32)

    def part(lo: int, hi: int) -> None:
        cast_faces(address, scene.handle, width, fields, o32[lo:hi], d32[lo:hi], out[lo:hi])

    n = len(o32)
    if threads <= 1:
        return lambda: part(0, n)
    step = max(1024, -(-n // (2 * threads)))  # as bare_embree_probe
    bounds = [(lo, min(lo + step, n)) for lo in range(0, n, step)]
    pool = shared_pool(threads)
    return lambda: list(pool.map(lambda b: part(*b), bounds))


def binding_description() -> str:
    """What lidarsim's Embree binding loaded (version, ``RTCRayHit`` size, packet width), or
    why it did not."""
    try:
        library = embree4.load()
    except BackendError as exc:
        return f"not loaded: {exc}"
    return (f"Embree {library.version_text}, {library.layout.nbytes(1)}-byte RTCRayHit, "
            f"packets of {library.packet_width}")


def add_packet_columns(result: dict[str, Any], rate: dict[str, float]) -> None:
    """Add to a scene's ``result`` the packet cast's rays/s (``bare_embree_packets``,
    ``bare_embree_packets_1thread``; None without the binding) and the simulation over it
    (``simulate_over_packets``, ``simulate_over_packets_1thread``)."""
    for suffix in ("", "_1thread"):
        packets = rate.get(f"bare_embree_packets{suffix}")
        result[f"bare_embree_packets{suffix}"] = packets
        result[f"simulate_over_packets{suffix}"] = \
            result[f"simulate{suffix}"] / packets if packets else None


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
