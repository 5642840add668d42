"""``lidarsim view --screenshot``: a real picture for PLY, PCD, LAS, NPZ and a run directory
(with the target mesh drawn at its ground-truth pose)."""

from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path

import numpy as np
import pytest

import lidarsim_core as ls

pytestmark = pytest.mark.skipif(importlib.util.find_spec("pyvista") is None,
                                reason="the viz extra is not installed")
SCENARIO = Path(__file__).parents[1] / "examples" / "envisat_mid70.yaml"


def _cli(*args: str):
    from typer.testing import CliRunner

    import lidarsim_core.cli.view  # noqa: F401  (registers the command)
    from lidarsim_core.cli import app

    return CliRunner().invoke(app, list(args))


def _ink(path: Path) -> int:
    """Pixels that are not the white background."""
    from PIL import Image

    image = np.asarray(Image.open(path).convert("RGB"), dtype=np.int64)
    return int(np.sum(np.abs(image - 255).sum(axis=2) > 30))


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """A run directory: its scenario (0.1 s) and the frame as PLY, PCD, LAS and NPZ."""
    pytest.importorskip("laspy")
    from lidarsim_core.report.render import rendering_backend

    rendering_backend()  # fails, naming what to install, when no OpenGL renders here
    root = tmp_path_factory.mktemp("view") / "run"
    root.mkdir()
    text = SCENARIO.read_text().replace("duration_s: 1.0 ", "duration_s: 0.1 ")
    (root / "scenario.yaml").write_text(text)
    cloud = ls.simulate(ls.load_scenario(root / "scenario.yaml"))
    assert len(cloud) > 200
    for fmt in ("ply", "pcd", "las", "npz"):
        cloud.save(root / f"cloud.{fmt}")
    return root


@pytest.mark.parametrize("fmt, colour", [("ply", "part"), ("pcd", "intensity"),
                                         ("las", "range"), ("npz", "time")])
def test_screenshot_of_each_format_is_a_real_picture(run_dir, tmp_path, fmt, colour):
    out = tmp_path / f"{fmt}.png"
    res = _cli("view", str(run_dir / f"cloud.{fmt}"), "--color-by", colour,
               "--screenshot", str(out))
    assert res.exit_code == 0, res.output
    assert _ink(out) > 300


def test_run_directory_adds_the_target_mesh(run_dir, tmp_path):
    alone = tmp_path / "alone.png"
    assert _cli("view", str(run_dir / "cloud.npz"), "--screenshot", str(alone)).exit_code == 0
    out = tmp_path / "run.png"
    res = _cli("view", str(run_dir), "--screenshot", str(out))
    assert res.exit_code == 0, res.output
    assert "1 target mesh" in res.output
    # same camera (fitted to the points): the translucent Envisat covers far more pixels
    assert _ink(out) > 2 * _ink(alone)


def test_view_errors_are_one_line(run_dir, tmp_path):
    res = _cli("view", str(run_dir / "cloud.ply"), "--color-by", "colour",
               "--screenshot", str(tmp_path / "a.png"))
    assert res.exit_code == 2 and "colour" in res.output
    empty = tmp_path / "empty"
    empty.mkdir()
    res = _cli("view", str(empty), "--screenshot", str(tmp_path / "b.png"))
    assert res.exit_code == 2 and "no point cloud written by lidarsim" in res.output
    shutil.rmtree(empty)
    assert sorted(p.name for p in tmp_path.iterdir()) == []
