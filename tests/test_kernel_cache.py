"""Kernels are compiled once per machine: after one process has warmed them up, a new
process loads every kernel from numba's disk cache and compiles none
(lidarsim_core.kernels.warm_up / cache_report); the warm-up reports its progress."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

pytest.importorskip("numba", reason="the compiled kernels need the extra 'fast'")

CODE = """
import json
from lidarsim_core import kernels
steps = []
kernels.warm_up(display=lambda done, total, name: steps.append([done, total, name]))
print(json.dumps({"steps": steps, **kernels.cache_report()}))
"""


def _run() -> dict:
    env = {**os.environ, "LIDARSIM_KERNELS": "numba"}
    out = subprocess.run([sys.executable, "-c", CODE], env=env, capture_output=True,
                         text=True, timeout=600, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_new_process_loads_every_kernel_from_the_cache():
    first = _run()  # compiles what is not cached yet (nothing, on a warm machine)
    second = _run()
    steps = second["steps"]
    total = steps[0][1]
    assert [s[0] for s in steps] == list(range(total + 1)) and steps[-1] == [total, total, ""]
    assert all(s[1] == total for s in steps) and all(s[2] for s in steps[:-1])
    assert sorted(first["compiled"] + first["loaded"]) == sorted(second["loaded"])
    assert second["compiled"] == [] and len(second["loaded"]) == total
