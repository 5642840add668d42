"""The fuzzer: mutated scenarios, datasheets, meshes, dataset files, command-line options and
environment variables, each run through the real ``lidarsim`` entry point in a worker process
with capped memory and a time limit, and held to the contract of ``tests/fuzz/harness.py``
(exit 0 with valid outputs, or exit 2 with one line naming a file, option or variable; never
a traceback, exit 1, a hang, memory exhaustion or a stray file).

CI runs a small, derandomised budget. A long session is one command::

    LIDARSIM_FUZZ_EXAMPLES=2000 .venv/bin/python -m pytest -q tests/test_fuzz.py

(``LIDARSIM_FUZZ_EXAMPLES`` examples per strategy, drawn at random; the summary line of each
test reports how many cases ran.)
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
from fuzz.cases import dataset_case, environment_case, option_case, scenario_case
from fuzz.harness import Worker, check_contract, snapshot
from fuzz.readers import reader_case
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

# the worker caps its memory with RLIMIT_AS and the cases make FIFOs: Linux semantics
pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="the fuzz worker needs Linux")

LONG = "LIDARSIM_FUZZ_EXAMPLES" in os.environ
EXAMPLES = int(os.environ.get("LIDARSIM_FUZZ_EXAMPLES", "0")) or None

#: Share of the CI budget (100 examples) each strategy gets.
SHARE = {"scenarios": 2.0, "options": 1.0, "environment": 0.4, "datasets": 0.6,
         "readers": 1.5}


def _settings(name: str) -> settings:
    return settings(max_examples=EXAMPLES or int(100 * SHARE[name]), deadline=None,
                    database=None, derandomize=not LONG, print_blob=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.filter_too_much])


@pytest.fixture(scope="module")
def worker():
    runner = Worker()
    yield runner
    runner.close()
    print(f"\nfuzz cases run: {runner.cases}; exit statuses {dict(runner.outcomes)}; "
          f"slowest case {runner.slowest:.2f} s; worker peak RSS "
          f"{runner.max_rss_kib / 1024:.0f} MiB")


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


def _run(worker: Worker, case) -> None:
    before = snapshot(case.directory)
    result = worker.run(case)
    check_contract(case, before, result)


STRATEGIES = {"scenarios": scenario_case, "options": option_case,
              "environment": environment_case, "datasets": dataset_case}


@pytest.mark.parametrize("name", list(STRATEGIES))
def test_fuzz_contract(name, worker, base):
    strategy = STRATEGIES[name]

    @_settings(name)
    @given(data=st.data())
    def run(data):
        _run(worker, data.draw(strategy(base)))

    run()


@pytest.fixture(scope="module")
def reader_seeds(tmp_path_factory) -> dict:
    """Valid files the reader cases mutate: a cloud in every format lidarsim writes (with its
    sidecar), an OBJ with its MTL, a GLB with two parts, and a complete two-frame dataset."""
    import yaml

    from fuzz.cases import BASE_SCENARIO
    from lidarsim_core import cli
    from lidarsim_core.dataset import generate_dataset
    from lidarsim_core.io.meshfile import export_mesh
    from lidarsim_core.models.builtin import BoxModel

    root = tmp_path_factory.mktemp("reader-seeds")
    scene = root / "s.yaml"
    scene.write_text(yaml.safe_dump(BASE_SCENARIO))
    seeds: dict = {}
    formats = ["ply", "pcd", "npz"]
    try:
        import laspy  # noqa: F401

        formats.append("las")
    except ImportError:
        pass
    for fmt in formats:
        with pytest.raises(SystemExit) as stop:
            cli.main(["simulate", str(scene), "--out", str(root / f"c.{fmt}")])
        assert stop.value.code == 0
        seeds[fmt] = (root / f"c.{fmt}").read_bytes()
    if "las" not in seeds:
        seeds["las"] = seeds["ply"]
    seeds["sidecar"] = (root / "c.ply.json").read_bytes()
    mesh = BoxModel.from_config({"extents_m": [1, 2, 3]}).mesh()
    export_mesh(mesh, root / "m.obj")
    seeds["obj"], seeds["mtl"] = (root / "m.obj").read_bytes(), (root / "m.mtl").read_bytes()
    export_mesh(mesh, root / "m.glb")
    seeds["glb"] = (root / "m.glb").read_bytes()
    sequence = dict(BASE_SCENARIO, scan={"duration_s": 0.01, "frame_period_s": 0.1,
                                         "frames": 2})
    (root / "seq.yaml").write_text(yaml.safe_dump(sequence))
    generate_dataset(root / "seq.yaml", root / "ds", quiet=True)
    seeds["dataset"] = root / "ds"
    return seeds


def test_fuzz_readers(worker, base, reader_seeds):
    """Mutated PLY/PCD/LAS/NPZ/OBJ/GLB/manifest/poses files through the readers
    (``tests/fuzz/readers.py``)."""

    @_settings("readers")
    @given(data=st.data())
    def run(data):
        _run(worker, data.draw(reader_case(base, reader_seeds)))

    run()
