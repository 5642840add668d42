"""How soon a new process simulates: the time from ``import lidarsim_core`` to the first
frame of the demo, in a fresh interpreter, once the kernels are compiled on this machine."""

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


def bench_startup(rounds: int = 3) -> dict[str, Any]:
    """Best of ``rounds`` fresh processes (after compiling the kernels once here):
    ``import_to_first_frame_s`` (wall) and ``..._cpu_s`` (the process's CPU time, which load
    from other work does not inflate), and their parts."""
    from .. import kernels

    kernels.warm_up()  # compiled once per machine (numba's disk cache)
    runs = []
    for _ in range(rounds):
        out = subprocess.run([sys.executable, "-c", _CODE], capture_output=True, text=True,
                             timeout=600, check=True)
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    best = min(runs, key=lambda r: r["import_to_first_frame_s"])
    best["import_to_first_frame_cpu_s"] = min(r["import_to_first_frame_cpu_s"] for r in runs)
    best["rounds"] = rounds
    return best
