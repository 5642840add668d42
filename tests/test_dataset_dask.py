"""Dask execution: a LocalCluster run (loopback, bounded, always shut down) writes the same
bytes as the serial run, and each worker builds a sequence's simulation (meshes and their
acceleration structures) once and reuses it for every frame it is given."""

from __future__ import annotations

import pytest
import yaml
from test_dataset import SCENARIO, tree

from lidarsim_core.dataset import generate_dataset, worker_cache_info

pytest.importorskip("dask.distributed")

FRAMES = 8


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    data = {**SCENARIO, "scan": {"duration_s": 0.03, "frame_period_s": 0.1, "frames": FRAMES}}
    path = tmp_path_factory.mktemp("scene") / "scene.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def serial(scenario, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial") / "ds"
    generate_dataset(scenario, out, format="las" if _has_laspy() else "ply")
    return tree(out)


def _has_laspy() -> bool:
    try:
        import laspy  # noqa: F401
    except ImportError:
        return False
    return True


def test_local_cluster_run_equals_serial_run(scenario, serial, tmp_path):
    out = tmp_path / "ds"
    result = generate_dataset(scenario, out, format="las" if _has_laspy() else "ply",
                              workers=2)
    assert result.frames_written == FRAMES
    assert tree(out) == serial


def test_workers_build_each_mesh_once_and_reuse_it(scenario, serial, tmp_path):
    from dask.distributed import Client

    from lidarsim_core.dataset.executors import local_cluster

    with local_cluster(2) as cluster, Client(cluster, timeout=60) as client:
        out = tmp_path / "ds"
        generate_dataset(scenario, out, format="las" if _has_laspy() else "ply",
                         scheduler=cluster.scheduler_address)
        infos = list(client.run(worker_cache_info, wait=True).values())
        threads = set(client.run(lambda: __import__("os").environ.get("LIDARSIM_THREADS"))
                      .values())
    assert threads == {"1"}  # one core per single-threaded worker
    assert tree(out) == serial
    assert sum(i["frames"] for i in infos) == FRAMES
    for info in infos:
        if info["frames"]:
            # one sequence: one simulation built, its two meshes prepared once each
            assert info["simulations_built"] == 1 and info["prepared_meshes"] == 2
