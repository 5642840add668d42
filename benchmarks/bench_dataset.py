"""Benchmark dataset generation: frames/s on Dask with 1 and 2 workers, and the peak memory
of writing a 10-million-point scan to LAS.

Run from the repository root (needs the ``dask`` and ``las`` extras)::

    python benchmarks/bench_dataset.py [--frames 16] [--las-points 10000000] [--skip-las]

Scaling: Envisat (medium detail) 18 m in front of a Livox MID-70, 3 s frames. Each worker
count gets a fresh ``LocalCluster`` (single-threaded worker processes on 127.0.0.1); the
workers import lidarsim before the clock starts, and the clock covers the frame loop only
(``DatasetResult.elapsed_s``), each worker's first frame, which builds the simulation and the
acceleration structure, included. Workers run their pipeline on one thread
(``LIDARSIM_THREADS=1``) and Embree with ``threads: 1``, so one worker uses one core; the
serial run uses every core through the pipeline's threads. All runs must write the same
bytes as the serial run.

Memory: one frame of ``--las-points`` rays against a 100 m plate that fills the field of
view (every ray returns), generated as a LAS dataset in a child process whose peak resident
set size (``ru_maxrss``) is reported: points stream through a spool file in chunks, so the
peak does not grow with the number of points.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))


def _backend() -> dict:
    from lidarsim_core.backends.embree_backend import EmbreeBackend

    return {"name": "embree", "options": {"threads": 1}} if EmbreeBackend.is_available()[0] \
        else {"name": "numpy"}


def scaling_scenario(frames: int) -> dict:
    """Envisat scanned at 18 m, ``frames`` frames of 3 s (300,000 rays each)."""
    return {
        "seed": 11,
        "sensor": {"datasheet": "livox-mid70-rose", "pose": {"position_m": [0, 0, 0]}},
        "targets": [{"name": "envisat",
                     "mesh": {"model": "envisat", "options": {"detail": "medium"}},
                     "trajectory": {"kind": "constant_velocity", "position_m": [18, -4, 0],
                                    "euler_deg": [0, 0, 90],
                                    "angular_velocity_deg_s": [0, 0, 2.67]}}],
        "scan": {"duration_s": 3.0, "frame_period_s": 3.0, "frames": frames},
        "backend": _backend(),
    }


def plate_scenario(points: int) -> dict:
    """One frame of ``points`` rays, all hitting a 100 m plate 20 m ahead."""
    rate = 100_000.0
    return {
        "seed": 1,
        "sensor": {"datasheet": "livox-mid70-rose", "pose": {"position_m": [0, 0, 0]}},
        "targets": [{"name": "plate",
                     "mesh": {"model": "box", "options": {"extents_m": [1.0, 100.0, 100.0]}},
                     "pose": {"position_m": [20.5, 0, 0]}}],
        "scan": {"duration_s": points / rate},
        "backend": _backend(),
    }


def tree_digest(root: Path) -> str:
    """One hash over every file's relative path and bytes."""
    digest = hashlib.sha256()
    for path in sorted(p for p in root.rglob("*") if p.is_file()):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


def _warm() -> bool:
    from lidarsim_core.plugins import get_registry
    from lidarsim_core.pipeline import Simulation  # noqa: F401

    get_registry()
    return True


def bench_scaling(frames: int, work: Path) -> dict:
    """Frames/s serial and on 1 and 2 Dask workers; checks all outputs are identical."""
    from dask.distributed import Client

    from lidarsim_core.dataset import generate_dataset
    from lidarsim_core.dataset.executors import local_cluster
    from lidarsim_core.scenario.load import scenario_from_dict

    scenario = scenario_from_dict(scaling_scenario(frames))
    results = {}
    serial = generate_dataset(scenario, work / "serial", format="ply")
    results["serial"] = {"frames_per_s": frames / serial.elapsed_s, "seconds": serial.elapsed_s,
                         "digest": tree_digest(work / "serial")}
    for workers in (1, 2):
        with local_cluster(workers) as cluster, Client(cluster, timeout=60) as client:
            client.run(_warm)
            out = work / f"dask{workers}"
            result = generate_dataset(scenario, out, format="ply",
                                      scheduler=cluster.scheduler_address)
        results[f"dask_{workers}"] = {"frames_per_s": frames / result.elapsed_s,
                                      "seconds": result.elapsed_s, "digest": tree_digest(out)}
    digests = {r["digest"] for r in results.values()}
    results["identical"] = len(digests) == 1
    results["speedup_2_vs_1"] = (results["dask_2"]["frames_per_s"] /
                                 results["dask_1"]["frames_per_s"])
    results["points_per_frame"] = serial.points_written / frames
    return results


_LAS_CHILD = """
import json, resource, sys, time
sys.path.insert(0, {src!r})
from lidarsim_core.dataset import generate_dataset
from lidarsim_core.scenario import scenario_from_dict
t = time.perf_counter()
result = generate_dataset(scenario_from_dict(json.loads({scenario!r})), {out!r}, format="las")
print(json.dumps({{"seconds": time.perf_counter() - t, "points": result.points_written,
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}}))
"""


def bench_las_memory(points: int, work: Path) -> dict:
    """Peak RSS of a child process writing one ``points``-ray frame to LAS."""
    src = str(Path(__file__).resolve().parents[1] / "src")
    code = _LAS_CHILD.format(src=src, scenario=json.dumps(plate_scenario(points)),
                             out=str(work / "las"))
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    report = json.loads(run.stdout.strip().splitlines()[-1])
    las = next((work / "las" / "frames").glob("*.las"))
    report["file_mb"] = las.stat().st_size / 2 ** 20
    return report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=12)
    parser.add_argument("--las-points", type=int, default=10_000_000)
    parser.add_argument("--skip-las", action="store_true")
    parser.add_argument("--skip-scaling", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="lidarsim-bench-") as tmp:
        work = Path(tmp)
        if not args.skip_scaling:
            import os

            t0 = time.perf_counter()
            load = os.getloadavg()[0]
            scaling = bench_scaling(args.frames, work)
            print(f"scaling ({args.frames} frames, {scaling['points_per_frame']:,.0f} points "
                  f"per frame, backend {_backend()['name']}):")
            for key in ("serial", "dask_1", "dask_2"):
                r = scaling[key]
                print(f"  {key:8s} {r['frames_per_s']:6.2f} frames/s ({r['seconds']:.1f} s)")
            print(f"  2 workers vs 1: {scaling['speedup_2_vs_1']:.2f}x; outputs identical: "
                  f"{scaling['identical']} (total {time.perf_counter() - t0:.0f} s; load "
                  f"average before {load:.1f}, after {os.getloadavg()[0]:.1f} on "
                  f"{os.cpu_count()} cores: other processes skew the scaling figure)")
        if not args.skip_las:
            report = bench_las_memory(args.las_points, work)
            print(f"LAS: {report['points']:,} points in {report['seconds']:.1f} s, "
                  f"{report['file_mb']:.0f} MB file, peak RSS {report['peak_rss_mb']:.0f} MB")


if __name__ == "__main__":
    main()
