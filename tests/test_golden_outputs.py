"""Every bit of the reference outputs stays where it was (issue 21: the package-layout change
moved code, not results).

``tests/data/golden_hashes.json`` holds the SHA-256 of the demo's clouds (PLY and NPZ with
their sidecars), a 20-frame tumbling dataset (every file and its manifest), the same scenario
as a ROS 2 bag and its ``lidarsim poses`` file, as the commit before that change wrote them.
A change that moves a bit on purpose regenerates the file with ``python tests/golden_outputs.py``
and says why in its commit message.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from golden_outputs import golden_hashes

EXPECTED = Path(__file__).parent / "data" / "golden_hashes.json"


def test_reference_outputs_are_bit_identical() -> None:
    pytest.importorskip("rosbags")
    expected = json.loads(EXPECTED.read_text(encoding="utf-8"))
    actual = golden_hashes()
    moved = sorted(name for name in expected if actual.get(name) != expected[name])
    assert sorted(actual) == sorted(expected), "the set of output files changed"
    assert not moved, f"{len(moved)} of {len(expected)} outputs changed: {moved[:5]}"
