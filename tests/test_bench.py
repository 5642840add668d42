"""The benchmark: figures present, consistent with each other, and printed by the CLI."""

from __future__ import annotations

import json
import math

import pytest
from typer.testing import CliRunner

from lidarsim_core import bench


def test_benchmark_measures_every_backend_on_the_scan_rays():
    result = bench.run_benchmark(quick=True, scenes={"tiny": "coarse"}, duration_s=0.02)
    scene = result["scenes"]["tiny"]
    assert scene["rays"] == 2000  # MID-70: 100,000 points/s for 0.02 s
    assert scene["triangles"] > 100
    assert 0.02 < scene["hit_fraction"] < 0.5
    assert "numpy" in scene["backends"] and all(v > 0 for v in scene["backends"].values())
    assert set(scene["backends_hits_only"]) == set(scene["backends"])
    assert set(scene["backends_1thread"]) == set(scene["backends"])
    assert scene["simulate"] > 0 and scene["simulate_1thread"] > 0
    assert scene["simulate_noiseless"] > 0
    assert {"simulate", "simulate_1thread", "numpy"} <= set(scene["cores_used"])
    assert scene["simulate_by_backend"][scene["simulate_backend"]] == scene["simulate"]
    if scene["bare_embree"] is None:
        assert scene["simulate_over_bare"] is None
    else:
        assert scene["bare_embree_1thread"] > 0
        assert math.isclose(scene["simulate_over_bare"], scene["simulate"] / scene["bare_embree"])
    assert result["machine"]["cpus"] >= 1 and result["machine"]["kernels"]
    assert set(scene["backend_speedup_all_threads"]) == set(scene["backends"])
    stages = scene["stages_1thread"]
    assert set(stages["ns_per_ray"]) == {"pattern", "cull", "cast", "rest"}
    assert all(v >= 0 for v in stages["ns_per_ray"].values())
    # the culler keeps every pulse that hits
    assert scene["hit_fraction"] <= stages["pulses_after_cull"] <= 1.0


def test_close_scene_hits_more_than_the_demo():
    result = bench.run_benchmark(quick=True, duration_s=0.02, scenes={
        "far": "coarse", "near": {"detail": "coarse", "range_m": 12.0}})
    far, near = result["scenes"]["far"], result["scenes"]["near"]
    assert near["range_m"] == 12.0 and far["range_m"] == 30.0
    assert near["hit_fraction"] > 2 * far["hit_fraction"]


def test_scan_rays_are_the_rays_the_pipeline_casts():
    from lidarsim_core.demo import demo_scenario
    from lidarsim_core.pipeline import Simulation

    sim = Simulation(demo_scenario(duration_s=0.01, detail="coarse", backend="numpy"))
    origins, directions = bench.scan_rays(sim)
    hits = sim.backend.cast(sim.targets[0].mesh, origins, directions)
    cloud = sim.run_frame(0)
    # every point of the cloud is a hit of the benchmark's rays, at the same range
    assert len(cloud) == int(hits.hit.sum())
    rays = cloud["ray_index"]
    assert (hits.distance[rays] == cloud["range_true"]).all()


FAKE = {"machine": {"cpus": 2, "threads": 2, "python": "3", "numpy": "2", "embreex": None,
                    "lidarsim": "0", "processor": "x"},
        "quick": True,
        "scenes": {"envisat": {"triangles": 9884, "rays": 100000, "hit_fraction": 0.11,
                               "backends": {"numpy": 1.5e6}, "backends_hits_only": {},
                               "backends_1thread": {"numpy": 1.4e6}, "simulate_1thread": 1e6,
                               "bare_embree_1thread": None, "bare_embree": None,
                               "simulate_backend": "numpy", "simulate": 1.2e6,
                               "simulate_over_bare": None}}}


@pytest.mark.parametrize("as_json", [True, False])
def test_cli_prints_the_benchmark(monkeypatch, as_json):
    from lidarsim_core.cli import _load_command_modules, app

    _load_command_modules()
    monkeypatch.setattr(bench, "run_benchmark", lambda quick=False: FAKE)
    result = CliRunner().invoke(app, ["bench", "--quick"] + (["--json"] if as_json else []))
    assert result.exit_code == 0, result.output
    if as_json:
        assert json.loads(result.output) == FAKE
    else:
        assert "envisat" in result.output and "1.50M" in result.output
