"""Cores used by a whole frame on all threads, hot and after the process sat idle.

Issue #22's all-thread ratios stayed below the one-thread ones because a frame's second
piece often does not run beside the first: ``Simulation.run_frame`` of the suite's
tumbling-rose scene uses 1.55-1.64 cores when frames follow each other, but mostly 1.00-1.10
cores (a few frames 1.45), once the process has slept for half a second (measured on the 2-core
development VM). A numba loop that releases the GIL for its whole run scales to 1.97 cores
in the same process in both states, and a frame's pieces are handed to both pool threads at
once, yet after the idle period the second piece starts only when the first has finished
(per-piece timestamps). The pieces hold the GIL between short compiled kernels; our
unconfirmed reading is that a pool thread woken on an idle virtual CPU loses the GIL to the
running thread at each of those hand-offs. Lowering CPython's switch interval from 5 ms to
0.2 ms (``sys.setswitchinterval``) helped only some frames (1.0-1.67 cores after idle).

Run: ``python benchmarks/bench_threads_idle.py [scene] [idle seconds]``; prints, for each of
three rounds of nine frames, the wall time (ms) and cores used of every frame.
"""

from __future__ import annotations

import sys
import time

from lidarsim_core.bench.suite import SUITE
from lidarsim_core.pipeline.simulation import Simulation
from lidarsim_core.scenario.load import scenario_from_dict


def main() -> None:
    scene = sys.argv[1] if len(sys.argv) > 1 else "tumbling-rose"
    idle = float(sys.argv[2]) if len(sys.argv) > 2 else 0.5
    sim = Simulation(scenario_from_dict(SUITE[scene][1](1.0), source=f"<bench {scene}>"))
    sim.run_frame(0)
    for state in ("hot", f"after {idle} s idle", f"after {idle} s idle"):
        figures = []
        for _ in range(9):
            cpu0, wall0 = time.process_time(), time.perf_counter()
            sim.run_frame(0)
            wall = time.perf_counter() - wall0
            figures.append(f"{wall * 1e3:.1f} ms/{(time.process_time() - cpu0) / wall:.2f}")
        print(f"{scene} {state}: " + "  ".join(figures))
        time.sleep(idle)


if __name__ == "__main__":
    main()
