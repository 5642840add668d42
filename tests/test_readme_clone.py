"""The README's first command, as written, in a fresh clone: venv, pip install, the demo.

Slow (a new virtual environment and an install), so marked ``slow``: deselected by default and
run by its own step of ``.ci/run`` (``pytest -m slow``).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def readme_commands() -> list[str]:
    """The commands of the README's "The two commands" block, in order."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("## The two commands", 1)[1]
    block = re.search(r"```bash[^\n]*\n(.*?)```", section, re.S).group(1)
    return [line for line in block.splitlines() if line and not line.startswith("#")]


def test_the_readme_names_two_commands_and_ci_runs_the_second_verbatim():
    demo, tests = readme_commands()
    assert demo.endswith("lidarsim demo --out demo-out") and "pip install" in demo
    assert tests.endswith("python -m pytest -n auto --dist loadscope")
    assert tests in (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_readme_first_command_works_in_a_fresh_clone(tmp_path):
    clone = tmp_path / "lidarsim"
    subprocess.run(["git", "clone", "--quiet", str(ROOT), str(clone)], check=True, timeout=300)
    command = readme_commands()[0]
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
    env["COLUMNS"] = "80"
    res = subprocess.run(["bash", "-c", command], cwd=clone, env=env, capture_output=True,
                         text=True, timeout=1800)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    out = clone / "demo-out"
    names = {p.name for p in out.iterdir()}
    for label in ("with_errors", "without_errors"):
        for suffix in (".ply", ".npz"):
            assert f"envisat_mid70_{label}{suffix}" in names
            assert f"envisat_mid70_{label}{suffix}.json" in names
    assert {"scenario.yaml", "report.html", "report.json", "fig05_pattern.png",
            "fig09_range_error.png", "coverage.png"} <= names
    lines = res.stdout.splitlines()
    assert lines[0].startswith("lidarsim demo: livox-mid70-rose scanning Envisat for 1 s")
    assert f"wrote {len(names)} files to demo-out/" in res.stdout
    sigma = float(re.search(r"range error: mean [-+]\d+\.\d+ mm, σ (\d+\.\d+) mm",
                            res.stdout).group(1))
    assert 18.0 < sigma < 22.0  # the datasheet's 20 mm, from ~11,000 points
    # the same points in the NPZ and the PLY (read by an independent PLY reader)
    import numpy as np
    from plyfile import PlyData

    npz = np.load(out / "envisat_mid70_with_errors.npz")
    ply = PlyData.read(str(out / "envisat_mid70_with_errors.ply"))["vertex"]
    assert 10_000 < len(npz["x"]) < 13_000
    np.testing.assert_array_equal(np.asarray(ply["x"]), npz["x"])
