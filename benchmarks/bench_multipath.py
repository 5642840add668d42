"""Benchmark multipath: the demo scan with ``max_bounces: 2`` against the same scan without
bounces (the light stops at the first surface), both with the detection model on.

Run from the repository root::

    python benchmarks/bench_multipath.py [--duration 1.0] [--repeat 3]

Three runs are interleaved ``--repeat`` times and the best time of each is kept (timings on a
shared machine are noisy; ratios within one run are what to read):

* ``direct``: detection on, no multipath;
* ``bounces=2``: ``sensor.multipath: {max_bounces: 2}`` with the default ``min_coupling``
  (bounces whose two-way mirror coupling is below 1e-6 are not followed);
* ``bounces=1`` / ``bounces=1 all``: the same with one bounce (the single-bounce runs);
* ``bounces=2 all``: ``min_coupling: 0``: every pulse that meets a surface with
  any specular component (most of Envisat: MLI, cover glass, radiators) is bounced twice, the
  worst case.

It prints the time of each, the ratio to ``direct``, the rays cast (direct, bounce and any
other casts: a count that does not depend on the machine's load) and how many ghosts the run
reported.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from lidarsim_core.scenario.demo import demo_scenario  # noqa: E402
from lidarsim_core.pipeline import Simulation  # noqa: E402
from lidarsim_core.scenario.load import scenario_from_dict  # noqa: E402


def scenario(duration_s: float, multipath: dict | None):
    data = demo_scenario(duration_s=duration_s).model_dump()
    data["sensor"]["detection"] = {}
    if multipath is not None:
        data["sensor"]["multipath"] = multipath
    return scenario_from_dict(data)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=1.0, help="scan time (s)")
    parser.add_argument("--repeat", type=int, default=3, help="interleaved repetitions")
    args = parser.parse_args()
    runs = {"direct": None, "bounces=1": {"max_bounces": 1}, "bounces=2": {"max_bounces": 2},
            "bounces=1 all": {"max_bounces": 1, "min_coupling": 0.0},
            "bounces=2 all": {"max_bounces": 2, "min_coupling": 0.0}}
    sims = {name: Simulation(scenario(args.duration, mp)) for name, mp in runs.items()}
    rays = {}
    for name, sim in sims.items():  # warm up (acceleration structures, kernels); count rays
        counter = {"rays": 0}
        cast = sim.backend.cast

        def counting(mesh, origins, directions, cast=cast, counter=counter):
            counter["rays"] += len(origins)
            return cast(mesh, origins, directions)

        sim.backend.cast = counting
        for stage in sim.stages:
            if hasattr(stage, "backend"):
                stage.backend = sim.backend
        sim.run_frame(0)
        rays[name] = counter["rays"]
        sim.backend.cast = cast
    best = {name: float("inf") for name in runs}
    ghosts = {}
    for _ in range(args.repeat):
        for name, sim in sims.items():
            t0 = time.perf_counter()
            cloud = sim.run_frame(0)
            best[name] = min(best[name], time.perf_counter() - t0)
            ghosts[name] = int((cloud["bounces"] > 0).sum()) if "bounces" in cloud.columns \
                else 0
            points = len(cloud)
    print(f"demo scan {args.duration} s, {sims['direct'].backend.name} backend, "
          f"best of {args.repeat}")
    for name in runs:
        print(f"{name:>14}: {best[name]:.3f} s  ({best[name] / best['direct']:.2f}x direct)  "
              f"rays cast {rays[name]} ({rays[name] / rays['direct']:.2f}x)  "
              f"ghost points: {ghosts[name]}")
    print(f"points (last run): {points}")
    print(f"max_bounces 2 / max_bounces 1: {best['bounces=2'] / best['bounces=1']:.2f}x "
          f"(default), {best['bounces=2 all'] / best['bounces=1 all']:.2f}x (min_coupling 0)")


if __name__ == "__main__":
    main()
