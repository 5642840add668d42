"""Every bit of the reference outputs stays where it was (issue 21: the package-layout change
moved code, not results).

``tests/data/golden_hashes.json`` holds the SHA-256 of the demo's clouds (PLY and NPZ with
their sidecars), a 20-frame tumbling dataset (every file and its manifest), the same scenario
as a ROS 2 bag and its ``lidarsim poses`` file, as the commit before that change wrote them,
per class of CPU (:func:`golden_outputs.bits_class`: NumPy's AVX-512 builds of its float64
functions round differently from its AVX2 ones). A change that moves a bit on purpose
regenerates the entry of each class with ``python tests/golden_outputs.py`` on such a CPU and
says why in its commit message; a class with no entry is skipped, with the command that
records it.
"""

from __future__ import annotations

import json
import platform
from pathlib import Path

import pytest
from golden_outputs import bits_class, golden_hashes

EXPECTED = Path(__file__).parent / "data" / "golden_hashes.json"


def test_reference_outputs_are_bit_identical() -> None:
    pytest.importorskip("rosbags")
    recorded = json.loads(EXPECTED.read_text(encoding="utf-8"))
    here = bits_class()
    if here not in recorded:
        pytest.skip(f"no reference outputs for CPUs of the class '{here}' (recorded: "
                    f"{'; '.join(sorted(recorded))}): record them from the commit before a "
                    "change with python tests/golden_outputs.py")
    expected = recorded[here]
    actual = golden_hashes()
    moved = sorted(name for name in expected if actual.get(name) != expected[name])
    assert sorted(actual) == sorted(expected), "the set of output files changed"
    assert not moved, f"{len(moved)} of {len(expected)} outputs changed: {moved[:5]}"


def test_the_class_of_this_cpu_is_named_by_numpys_builds() -> None:
    """The key of the references names what decides the bits: an AVX-512 CPU, whose NumPy
    runs its X86_V4 builds, is another class than an AVX2 one."""
    introspect = pytest.importorskip("numpy.lib.introspect")
    info = introspect.opt_func_info(func_name="^arctan2$", signature="^float64")
    current = next(iter(info["arctan2"].values()))["current"]
    here = bits_class()
    assert here.startswith(platform.machine())
    assert ("X86_V4" in here) == (current == "X86_V4")
