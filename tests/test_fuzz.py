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
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

# the worker caps its memory with RLIMIT_AS and the cases make FIFOs: Linux semantics
pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="the fuzz worker needs Linux")

LONG = "LIDARSIM_FUZZ_EXAMPLES" in os.environ
EXAMPLES = int(os.environ.get("LIDARSIM_FUZZ_EXAMPLES", "0")) or None

#: Share of the CI budget (100 examples) each strategy gets.
SHARE = {"scenarios": 2.0, "options": 1.0, "environment": 0.4, "datasets": 0.6}


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
