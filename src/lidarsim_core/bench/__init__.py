"""``lidarsim bench``: ray-casting throughput of every backend (:mod:`.throughput`) and the
whole simulation on realistic scenes against bare Embree (:mod:`.suite`)."""

from .suite import bench_suite_scene, run_suite
from .throughput import (bench_divergence, bench_scene, pipeline_stages, run_benchmark,
                         scan_rays)

__all__ = ["bench_divergence", "bench_scene", "bench_suite_scene", "pipeline_stages",
           "run_benchmark", "run_suite", "scan_rays"]
