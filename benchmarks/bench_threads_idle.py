"""Cores used by a whole frame on all threads, hot and after the process sat idle.

Issue #22's all-thread ratios stayed below the one-thread ones partly because a frame's second
piece often did not run beside the first: ``Simulation.run_frame`` of the suite's
tumbling-rose scene used 1.55-1.64 cores when frames followed each other, but mostly
1.00-1.17 cores once the process had slept for half a second (the 2-core development VM).
The cause was the guest kernel packing both woken pool threads onto one vCPU
(``sched_vcpu_pack`` on its command line): two nogil loops handed to the pool together ran
one after the other. Binding each pool thread to a CPU of its own
(:mod:`lidarsim_core.base.pinning`, the default) brought the frames after idle to
1.43-1.51 cores (34 of 36 frames); ``LIDARSIM_PIN_THREADS=off`` shows the old behaviour.

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
