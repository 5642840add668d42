"""Embree called from compiled code (issue 22): the binding's calls against embreex, and the
Embree backend and the whole simulation before and after it.

Run from the repository root::

    python benchmarks/bench_embree_binding.py [--rounds 11] [--scenes static-demo tumbling-rose]

For each scene of the bench suite (frame 0 of 1 s, every ray the simulation casts, in the
target's body frame), in one process and interleaved rounds (best of ``--rounds``):

1. ns per ray on one thread of the bare float32 cast: embreex's ``EmbreeScene.run``, and the
   binding's ``rtcIntersect1`` loop and packets of 4, 8 and 16 rays
   (:func:`lidarsim_core.kernels.embree_cast.cast_faces`), with the faces checked equal;
2. ``EmbreeBackend.intersect`` on the same float64 rays, before (embreex between the two
   compiled float64 steps) and after (one compiled loop through the binding), one thread and
   all threads, with every output bit checked equal;
3. ``Simulation.run_frame`` before and after, over bare embreex (``simulate_over_bare``) and
   over the binding's packet cast, one thread and all threads.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from lidarsim_core.backends import embree4  # noqa: E402
from lidarsim_core.backends.embree_backend import EmbreeBackend  # noqa: E402
from lidarsim_core.base.threads import worker_threads  # noqa: E402
from lidarsim_core.bench.suite import SUITE, cast_rays  # noqa: E402
from lidarsim_core.bench.timing import (bare_embree_probe, interleaved_best,  # noqa: E402
                                        packet_embree_probe, threads_env)
from lidarsim_core.pipeline.simulation import Simulation  # noqa: E402
from lidarsim_core.scenario.load import scenario_from_dict  # noqa: E402


def _embreex_prepared(prepared):  # noqa: ANN001, ANN202
    """The same prepared mesh cast through embreex (the backend's path before the binding)."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, np.ascontiguousarray(
        prepared.scene._vertices[:, :3].reshape(-1, 3, 3)))
    return dataclasses.replace(prepared, scene=scene, compiled=None)


def bench_scene(name: str, rounds: int) -> None:
    sim = Simulation(scenario_from_dict(SUITE[name][1](1.0), source=f"<bench {name}>"))
    assert isinstance(sim.backend, EmbreeBackend) and len(sim.targets) == 1
    mesh = sim.targets[0].mesh
    after = sim.backend.prepared(mesh)
    assert after.compiled is not None, "the binding did not load"
    before = _embreex_prepared(after)
    key = next(k for k, v in EmbreeBackend._prepared.items() if v is after)
    (_, origins, directions), = cast_rays(sim)
    n = len(origins)
    threads = worker_threads()
    print(f"\n{name}: {n:,} rays, {mesh.n_faces:,} faces, {threads} threads, "
          f"packets of {embree4.load().packet_width} in the backend")

    # 1. the bare cast, one thread
    library = embree4.load()
    triangles = np.ascontiguousarray(mesh.triangles, dtype=np.float32)
    scene = library.new_scene(triangles)
    o32 = np.ascontiguousarray(origins, dtype=np.float32)
    d32 = np.ascontiguousarray(directions, dtype=np.float32)
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    reference = rtcore_scene.EmbreeScene()
    TriangleMesh(reference, triangles)
    faces = reference.run(o32, d32)
    probes = {"embreex run": lambda: reference.run(o32, d32)}
    for width in embree4.PACKET_WIDTHS:
        assert np.array_equal(scene.faces(o32, d32, width), faces)
        label = "rtcIntersect1" if width == 1 else f"rtcIntersect{width}"
        probes[label] = lambda width=width: scene.faces(o32, d32, width)
    best, _ = interleaved_best(probes, rounds)
    print(f"  bare cast, one thread, ns per ray (hit fraction {np.mean(faces >= 0):.3f}):")
    for label, seconds in best.items():
        print(f"    {label:14s} {1e9 * seconds / n:6.1f} ns   "
              f"{best['embreex run'] / seconds:.2f} x embreex")

    # 2. EmbreeBackend.intersect before / after
    a = sim.backend.intersect(after, origins, directions)
    b = sim.backend.intersect(before, origins, directions)
    for x, y in ((a.face, b.face), (a.distance, b.distance), (a.normal, b.normal)):
        assert x.tobytes() == y.tobytes()
    probes = {}
    for label, count in (("1 thread", 1), (f"{threads} threads", threads)):
        for which, prepared in (("before", before), ("after", after)):
            probes[f"{which} {label}"] = threads_env(
                count, lambda p=prepared: sim.backend.intersect(p, origins, directions))
    best, _ = interleaved_best(probes, rounds)
    print("  EmbreeBackend.intersect, ns per ray:")
    for label in ("1 thread", f"{threads} threads"):
        t0, t1 = best[f"before {label}"], best[f"after {label}"]
        print(f"    {label:10s} before {1e9 * t0 / n:6.1f}  after {1e9 * t1 / n:6.1f}  "
              f"speed-up {t0 / t1:.2f}")

    # 3. the whole frame before / after, over bare embreex and the binding's packets
    def run_with(prepared):  # noqa: ANN001, ANN202
        def run():  # noqa: ANN202
            EmbreeBackend._prepared[key] = prepared
            return sim.run_frame(0)
        return run

    cloud_after, cloud_before = run_with(after)(), run_with(before)()
    assert all(np.array_equal(cloud_after[c], cloud_before[c], equal_nan=True)
               for c in cloud_after.columns)
    probes = {}
    for suffix, count in (("_1thread", 1), ("", threads)):
        probes[f"bare{suffix}"] = bare_embree_probe(mesh, origins, directions, count)
        probes[f"packets{suffix}"] = packet_embree_probe(mesh, origins, directions, count)
        for which, prepared in (("before", before), ("after", after)):
            probes[f"{which}{suffix}"] = threads_env(count, run_with(prepared))
    best, _ = interleaved_best(probes, rounds)
    EmbreeBackend._prepared[key] = after
    print("  Simulation.run_frame over bare Embree (simulate_over_bare; over packets):")
    for suffix, label in (("_1thread", "1 thread"), ("", f"{threads} threads")):
        bare, packets = best[f"bare{suffix}"], best[f"packets{suffix}"]
        parts = [f"{which} {bare / best[which + suffix]:.2f} "
                 f"({packets / best[which + suffix]:.2f})" for which in ("before", "after")]
        print(f"    {label:10s} " + "   ".join(parts) +
              f"   bare embreex {n / bare / 1e6:.1f} M/s, packets {n / packets / 1e6:.1f} M/s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=11)
    parser.add_argument("--scenes", nargs="+", default=["static-demo", "tumbling-rose"])
    args = parser.parse_args()
    library = embree4.load()
    print(f"Embree {library.version_text} from {library.path.name}: "
          f"RTCRayHit {library.layout.nbytes(1)} bytes, native packets {library.native_packets}")
    for name in args.scenes:
        bench_scene(name, args.rounds)


if __name__ == "__main__":
    main()
