"""The benchmark: figures present, consistent with each other, and printed by the CLI."""

from __future__ import annotations

import json
import math

import numpy as np
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
    from lidarsim_core.pipeline import Simulation
    from lidarsim_core.scenario import demo_scenario

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
SUITE = {"duration_s": 0.1, "rounds": 2, "scenes": {"tumbling-risley": {
    "description": "tumbling", "rays_emitted": 10000, "triangles": 9884, "simulate": 2.0e6,
    "simulate_1thread": 1.5e6, "bare_embree": 2.0e7, "bare_embree_1thread": 1.2e7,
    "simulate_over_bare": 0.1, "simulate_over_bare_1thread": 0.125,
    "bare_embree_packets": 3.2e7, "bare_embree_packets_1thread": 1.7e7,
    "simulate_over_packets": 0.0625, "simulate_over_packets_1thread": 0.0875,
    "compiled_1thread_s": 0.0025, "profiled_frame_1thread_s": 0.004,
    "bare_over_compiled_1thread": 0.33,
    "stages_1thread": {"ns_per_ray": {"pattern": 40, "poses": 30, "cull": 20, "cast": 20,
                                      "measurement": 60, "record": 10},
                       "pulses_after_cull": 0.16,
                       "fused": {"before_cast": 11, "cast": 20, "closest": 2, "measure": 4,
                                 "columns": 7, "general_measurement": 33}}}},
    "targets": {"min_simulate_over_bare": 0.1, "tumbling_over_static_rose": None,
                "tumbling_over_static_risley": 0.7, "risley_over_rose_static": None},
    "dataset": {"frames": 20, "in_memory_frames_per_s": 50.0, "dataset_frames_per_s": 45.0,
                "dataset_over_in_memory": 0.9},
    "startup": {"import_to_first_frame_s": 0.8, "import_to_first_frame_cpu_s": 0.7,
                "dependencies_s": 0.6, "lidarsim_s": 0.2}}


@pytest.mark.parametrize("as_json", [True, False])
@pytest.mark.parametrize("with_suite", [False, True])
def test_cli_prints_the_benchmark(monkeypatch, as_json, with_suite):
    from lidarsim_core.cli import app
    fake = {**FAKE, "suite": SUITE} if with_suite else FAKE
    monkeypatch.setattr("lidarsim_core.bench.throughput.run_benchmark",
                        lambda quick=False: fake)
    result = CliRunner().invoke(app, ["bench", "--quick"] + (["--json"] if as_json else []))
    assert result.exit_code == 0, result.output
    if as_json:
        assert json.loads(result.output) == fake
    else:
        assert "envisat" in result.output and "1.50M" in result.output
        if with_suite:
            for text in ("tumbling-risley", "2.00M", "0.12", "s/p) 0.09 (1t), 0.06 (2t)",
                         "17.00M (1t)",
                         "poses 30", "0.70 (Risley)",
                         "before_cast 11", "general path's measurement: 33",
                         "45.0 frames/s", "first frame: 0.80 s", "libraries alone: 0.60 s",
                         "lidarsim: 0.20 s", "kernels alone: 2.50 ms", "them 0.33"):
                assert text in result.output, text


def test_suite_scene_figures_are_consistent():
    from lidarsim_core.bench import suite as bench_suite

    scene = bench_suite.bench_suite_scene("tumbling-rose", duration_s=0.01, rounds=1)
    assert scene["rays_emitted"] == 1000 and scene["rays_cast"] == 1000
    assert scene["simulate"] > 0 and scene["simulate_1thread"] > 0
    stages = scene["stages_1thread"]
    assert set(stages["ns_per_ray"]) == {"pattern", "poses", "cull", "cast", "measurement",
                                         "record"}
    assert all(v >= 0 for v in stages["ns_per_ray"].values())
    assert stages["ns_per_ray"]["poses"] > 0  # the tumbling target has a pose per ray
    assert 0 < stages["pulses_after_cull"] <= 1
    # the scene runs the fast path: each of its parts is timed
    fused = stages["fused"]
    from lidarsim_core.backends.embree_backend import binding_status

    # with Embree's binding the cast and the closest target run in the compiled loop
    cast = {"cast_in_loop"} if binding_status()[0] else {"cast", "closest"}
    assert set(fused) == {"before_cast", *cast, "measure", "columns", "general_measurement"}
    assert all(v > 0 for v in fused.values())
    # the kernels' own time is part of the profiled frame; bare Embree over it is the ceiling
    assert 0 < scene["compiled_1thread_s"] < scene["profiled_frame_1thread_s"]
    if scene["bare_embree_1thread"] is not None:
        assert math.isclose(scene["bare_over_compiled_1thread"],
                            1000 / scene["bare_embree_1thread"] / scene["compiled_1thread_s"])
    for suffix in ("", "_1thread"):
        bare = scene[f"bare_embree{suffix}"]
        if bare is None:
            assert scene[f"simulate_over_bare{suffix}"] is None
        else:
            assert math.isclose(scene[f"simulate_over_bare{suffix}"],
                                scene[f"simulate{suffix}"] / bare)
        packets = scene[f"bare_embree_packets{suffix}"]  # lidarsim's Embree binding
        if packets is None:
            assert scene[f"simulate_over_packets{suffix}"] is None
        else:
            assert math.isclose(scene[f"simulate_over_packets{suffix}"],
                                scene[f"simulate{suffix}"] / packets)


def test_suite_casts_every_sub_ray_and_both_targets():
    from lidarsim_core.bench import suite as bench_suite
    from lidarsim_core.pipeline import Simulation
    from lidarsim_core.scenario import scenario_from_dict

    def sim(name):
        data = bench_suite.SUITE[name][1](0.01)
        return Simulation(scenario_from_dict(data, source="<test>"))

    beam = sim("divergence-7")
    (mesh, origins, directions), = bench_suite.cast_rays(beam)
    assert len(directions) == 7 * 1000 and beam.rays_per_pulse == 7
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0, atol=1e-12)
    two = bench_suite.cast_rays(sim("two-targets"))
    assert [m.name for m, _, _ in two] == [t.mesh.name for t in sim("two-targets").targets]
    assert all(len(o) == 1000 for _, o, _ in two)


def test_suite_targets_and_dataset_throughput():
    from lidarsim_core.bench import suite as bench_suite

    scenes = {"static-demo": {"simulate": 10.0, "simulate_over_bare": 0.4,
                              "simulate_over_bare_1thread": 0.3},
              "tumbling-rose": {"simulate": 6.0, "simulate_over_bare": 0.6,
                                "simulate_over_bare_1thread": None},
              "static-risley": {"simulate": 4.0}}
    targets = bench_suite.suite_targets(scenes)
    assert targets["min_simulate_over_bare"] == 0.3
    assert targets["tumbling_over_static_rose"] == 0.6
    assert targets["risley_over_rose_static"] == 0.4
    assert targets["tumbling_over_static_risley"] is None
    data = bench_suite.bench_dataset(frames=3, rounds=1)
    assert data["frames"] == 3
    assert data["in_memory_frames_per_s"] > 0 and data["dataset_frames_per_s"] > 0
    assert math.isclose(data["dataset_over_in_memory"],
                        data["dataset_frames_per_s"] / data["in_memory_frames_per_s"])
    assert 0 < data["file_create_us"] < 1e6  # what the file system charges for a new file


def test_startup_is_measured_in_a_new_process_that_compiles_nothing():
    pytest.importorskip("numba")
    from lidarsim_core.bench.startup import bench_startup

    start = bench_startup(rounds=1)
    assert start["kernels_compiled"] == []  # the kernels came from the disk cache
    assert 0 < start["first_frame_s"] < start["import_to_first_frame_s"]
    assert 0 < start["import_to_first_frame_cpu_s"]
    # the libraries' own share, in a process that loads its one kernel from the cache too
    floor = start["dependencies"]
    assert floor["kernels_compiled"] == []
    assert 0 < floor["imports_s"] and 0 < floor["numba_first_call_s"]
    assert math.isclose(start["dependencies_s"], floor["imports_s"] + floor["numba_first_call_s"])
    assert math.isclose(start["lidarsim_s"],
                        start["import_to_first_frame_s"] - start["dependencies_s"])


def test_compiled_share_counts_the_kernels_and_nothing_else(monkeypatch):
    """The profiler charges the compiled kernels' calls to them: a frame with the kernels
    has some, the same frame on the NumPy path (no kernel called) has none."""
    pytest.importorskip("numba")
    from lidarsim_core.bench.compiled import compiled_share
    from lidarsim_core.pipeline import Simulation
    from lidarsim_core.scenario import demo_scenario

    monkeypatch.setenv("LIDARSIM_THREADS", "1")  # the profiler sees the calling thread only
    share = compiled_share(Simulation(demo_scenario(duration_s=0.02)), rounds=2)
    assert 0 < share["compiled_s"] < share["profiled_frame_s"]
    monkeypatch.setenv("LIDARSIM_KERNELS", "numpy")
    share = compiled_share(Simulation(demo_scenario(duration_s=0.02, backend="numpy")),
                           rounds=1)
    assert share["compiled_s"] == 0 and share["profiled_frame_s"] > 0


def test_warm_up_rounds_are_interleaved_and_not_timed():
    """interleaved_best runs every probe ``warmup`` times, interleaved, before the rounds it
    times (the simulation's plan chooses its way in those rounds)."""
    import time

    from lidarsim_core.bench.timing import interleaved_best

    calls: list[str] = []

    def probe(name, slow_calls):  # noqa: ANN001, ANN202
        def run():  # noqa: ANN202
            calls.append(name)
            if calls.count(name) <= slow_calls:
                time.sleep(0.05)
        return run

    best, _ = interleaved_best({"a": probe("a", 3), "b": probe("b", 0)}, rounds=2, warmup=3)
    assert calls == ["a", "b"] * 5
    assert best["a"] < 0.04 and best["b"] < 0.04  # the three slow calls of a were not timed
