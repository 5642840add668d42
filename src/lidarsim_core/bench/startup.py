"""How soon a new process simulates: the time from ``import lidarsim_core`` to the first
frame of the demo, in a fresh interpreter, once the kernels are compiled on this machine; and
what of it the libraries the frame needs take on their own in another fresh interpreter
(``dependencies_s``: their imports and numba's set-up for a first cached kernel), the part no
change to lidarsim can remove."""

from __future__ import annotations

import json
import subprocess
import sys
from typing import Any

#: What the fresh process runs: import, then the demo's first frame (0.01 s of scan; the
#: kernels it uses load from the disk cache as they are first called), timed from just after
#: ``import lidarsim_core``; ``kernels_s`` is the import of the pipeline and of numba.
_CODE = """
import json, time
t0, c0 = time.perf_counter(), time.process_time()
import lidarsim_core
t1, c1 = time.perf_counter(), time.process_time()
from lidarsim_core import kernels
from lidarsim_core.pipeline.simulation import Simulation
from lidarsim_core.scenario.demo import demo_scenario
kernels.enabled()
t2, c2 = time.perf_counter(), time.process_time()
Simulation(demo_scenario(duration_s=0.01)).run_frame(0)
t3, c3 = time.perf_counter(), time.process_time()
print(json.dumps({"import_s": t1 - t0, "kernels_s": t2 - t1, "first_frame_s": t3 - t2,
                  "import_to_first_frame_s": t3 - t1,
                  "import_to_first_frame_cpu_s": c3 - c1,
                  "kernels_compiled": kernels.cache_report()["compiled"]}))
"""

#: What the libraries alone take in a fresh process: the third-party packages the demo's first
#: frame imports (the scenario's schemas, the plugin hooks and YAML datasheets, SciPy's
#: rotations, trimesh for the meshes, numba for the kernels), then numba's set-up of its
#: compiler's target on the first call of a small cached kernel (made by ``warm_up``).
_DEPENDENCIES = """
import json, time
t0 = time.perf_counter()
import numpy, pydantic, pluggy, yaml
import scipy.spatial.transform
import trimesh
import numba
t1 = time.perf_counter()
from lidarsim_core import kernels
from lidarsim_core.kernels.philox import ray_uniforms
key = numpy.zeros(2, dtype=numpy.uint64)
key.flags.writeable = False  # as warm_up compiled it
t2 = time.perf_counter()
ray_uniforms(key, numpy.zeros(1, dtype=numpy.int64), 1)
t3 = time.perf_counter()
print(json.dumps({"imports_s": t1 - t0, "numba_first_call_s": t3 - t2,
                  "kernels_compiled": kernels.cache_report()["compiled"]}))
"""


def _fresh(code: str) -> dict[str, Any]:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=600, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def bench_startup(rounds: int = 3) -> dict[str, Any]:
    """Best of ``rounds`` fresh processes (after compiling the kernels once here):
    ``import_to_first_frame_s`` (wall) and ``..._cpu_s`` (the process's CPU time, which load
    from other work does not inflate), and their parts; ``dependencies_s``, the best of as
    many fresh processes that only import the libraries and call one cached kernel
    (:data:`_DEPENDENCIES`, interleaved with the others), and ``lidarsim_s``, the rest."""
    from .. import kernels

    kernels.warm_up()  # compiled once per machine (numba's disk cache)
    runs, floors = [], []
    for _ in range(rounds):
        runs.append(_fresh(_CODE))
        floors.append(_fresh(_DEPENDENCIES))
    best = min(runs, key=lambda r: r["import_to_first_frame_s"])
    best["import_to_first_frame_cpu_s"] = min(r["import_to_first_frame_cpu_s"] for r in runs)
    floor = min(floors, key=lambda r: r["imports_s"] + r["numba_first_call_s"])
    best["dependencies_s"] = floor["imports_s"] + floor["numba_first_call_s"]
    best["dependencies"] = floor
    best["lidarsim_s"] = best["import_to_first_frame_s"] - best["dependencies_s"]
    best["rounds"] = rounds
    return best
