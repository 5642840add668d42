"""Swap the ray backend: the same scenario with every installed backend, compared and timed.

Choosing a backend is configuration, never code: ``backend: NAME`` in a scenario,
``--backend NAME`` on the command line, or ``scenario.with_updates(backend=...)`` here.

Usage::

    python examples/swap_backends.py

``LIDARSIM_EXAMPLE_DURATION`` sets the scan time (s; default 0.5).

Timings are fair: the compiled kernels are compiled (or loaded from numba's cache) first, each
backend builds its acceleration structure outside the timed cast, runs the frame once to warm
up (thread pools, caches), and the cast is the best of ``REPEATS`` runs.
"""

from __future__ import annotations

import os
import time

import numpy as np

import lidarsim_core as ls
from lidarsim_core import kernels
from lidarsim_core.plugins import get_registry
from lidarsim_core.pipeline import Simulation

DURATION_S = float(os.environ.get("LIDARSIM_EXAMPLE_DURATION", "0.5"))
REPEATS = 3

started = time.perf_counter()
if kernels.warm_up():  # one-time compilation, reported apart from every backend's time
    print(f"compiled kernels ready in {time.perf_counter() - started:.2f} s")

scenario = ls.demo_scenario(duration_s=DURATION_S, noise=False, detail="medium")
clouds = {}
for entry in get_registry().iter("ray_backend"):
    usable, why = entry.obj.is_available()
    if not usable:
        print(f"{entry.name:>8}: not available here ({why})")
        continue
    sim = Simulation(scenario.with_updates(backend={"name": entry.name}))
    started = time.perf_counter()
    sim.backend.prepared(sim.targets[0].mesh)      # acceleration structure, built once per mesh
    build_s = time.perf_counter() - started
    cloud = sim.run_frame(0)                       # warm-up run, not timed
    times = []
    for _ in range(REPEATS):
        started = time.perf_counter()
        cloud = sim.run_frame(0)
        times.append(time.perf_counter() - started)
    clouds[entry.name] = cloud
    cast_s = min(times)
    print(f"{entry.name:>8}: {len(cloud):,} points from {cloud.frame.rays_emitted:,} rays; "
          f"build {build_s:.2f} s, simulate {cast_s:.3f} s, best of {REPEATS} after a warm-up "
          f"({cloud.frame.rays_emitted / cast_s:,.0f} rays/s); "
          f"precision: {entry.obj.precision or 'not stated'}")

reference = clouds.pop("numpy")                    # the float64 reference is always installed
for name, cloud in clouds.items():
    common, i_ref, i_other = np.intersect1d(reference["ray_index"], cloud["ray_index"],
                                            return_indices=True)
    only = len(reference) + len(cloud) - 2 * len(common)
    gap = np.abs(reference["range"][i_ref] - cloud["range"][i_other])
    print(f"numpy vs {name}: {len(common):,} rays hit in both, {only} in one only "
          f"(grazing edges), largest range difference {gap.max():.1e} m")
    assert only <= max(5, len(common) // 1000)
    assert gap.max() < 1e-6
