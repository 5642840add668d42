"""One output-path rule for ``mesh``, ``view --screenshot`` and range images: missing folders
are created, and every check that can fail runs before anything is built or written (a refused
run leaves the file system as it was, and its one line names the file)."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import pytest
import trimesh

from lidarsim_core.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
TWO_TARGETS = ROOT / "examples" / "scenarios" / "two_targets.yaml"


def _cli(args: list[str], capsys) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as stop:
        main(args)
    out, err = capsys.readouterr()
    return stop.value.code, out, err


def _tree(root: Path) -> set[str]:
    return {p.relative_to(root).as_posix() for p in root.rglob("*")}


def _faces_of_targets() -> dict[str, int]:
    from lidarsim_core.pipeline.simulation import Simulation
    from lidarsim_core.scenario.load import load_scenario

    return {t.name: t.mesh.n_faces for t in Simulation(load_scenario(TWO_TARGETS)).targets}


def test_mesh_template_creates_its_folder(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = _cli(["mesh", str(TWO_TARGETS), "--out", "meshes/{target}.ply"], capsys)
    assert code == 0, err
    faces = _faces_of_targets()
    assert _tree(tmp_path) == {"meshes"} | {f"meshes/{n}.ply" for n in faces}
    for name, n_faces in faces.items():  # read back by an outside reader
        assert len(trimesh.load(tmp_path / "meshes" / f"{name}.ply", process=False).faces) \
            == n_faces


def test_mesh_directory_with_format_creates_it(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = _cli(["mesh", str(TWO_TARGETS), "--out", "new/deeper/", "--format", "obj"],
                          capsys)
    assert code == 0, err
    names = set(_faces_of_targets())
    assert _tree(tmp_path / "new" / "deeper") == \
        {f"{n}{s}" for n in names for s in (".obj", ".mtl")}


def test_mesh_checks_every_output_before_writing_any(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "debris.ply").write_bytes(b"mine")
    code, out, err = _cli(["mesh", str(TWO_TARGETS), "--out", "meshes/{target}.ply"], capsys)
    assert code == 2
    assert err.count("\n") == 1 and "meshes/debris.ply" in err and "exists" in err
    assert _tree(tmp_path) == {"meshes", "meshes/debris.ply"}  # envisat.ply not written
    assert (tmp_path / "meshes" / "debris.ply").read_bytes() == b"mine"
    code, out, err = _cli(["mesh", "envisat", "--out", "a/b/envisat.xyz"], capsys)
    assert code == 2 and "a/b/envisat.xyz" in err and "no mesh format" in err
    assert not (tmp_path / "a").exists()  # no folder made for a refused run


FLASH = """\
seed: 1
sensor: {datasheet: ball-vns-flash}
targets:
  - name: sat
    mesh: {model: envisat, options: {detail: coarse}}
    pose: {position_m: [30, 0, 0]}
scan: {duration_s: DURATION}
"""


def test_range_image_of_several_flashes_fails_before_anything_is_written(tmp_path, capsys,
                                                                        monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("flash.yaml").write_text(FLASH.replace("DURATION", "0.2"))  # 30 Hz: 6 flashes
    code, out, err = _cli(["simulate", "flash.yaml", "--out", "ri/f.ply", "--range-image"],
                          capsys)
    assert code == 2
    assert err.startswith("error: flash.yaml: field 'scan.duration_s': the frame holds 6 "
                          "flashes"), err
    assert _tree(tmp_path) == {"flash.yaml"}


def test_range_image_of_one_flash_goes_into_a_new_folder(tmp_path, capsys, monkeypatch):
    import numpy as np

    monkeypatch.chdir(tmp_path)
    Path("flash.yaml").write_text(FLASH.replace("DURATION", "0.03"))
    code, out, err = _cli(["simulate", "flash.yaml", "--out", "ri/f.ply", "--range-image"],
                          capsys)
    assert code == 0, err
    assert _tree(tmp_path / "ri") == {"f.ply", "f.ply.json", "f.range.npz", "f.range.png"}
    with np.load(tmp_path / "ri" / "f.range.npz") as image:
        assert image["range"].shape == (256, 256)
        assert np.isfinite(image["range"]).sum() == int((image["point_index"] >= 0).sum()) > 0


def test_range_image_files_are_checked_before_simulating(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("flash.yaml").write_text(FLASH.replace("DURATION", "0.03"))
    Path("f.range.png").write_bytes(b"mine")
    code, out, err = _cli(["simulate", "flash.yaml", "--out", "f.ply", "--range-image"], capsys)
    assert code == 2 and "f.range.png" in err and "exists" in err
    assert _tree(tmp_path) == {"flash.yaml", "f.range.png"}  # no cloud written first


@pytest.mark.skipif(importlib.util.find_spec("pyvista") is None, reason="needs the viz extra")
def test_view_screenshot_creates_its_folder(tmp_path, capsys, monkeypatch):
    from lidarsim_core.report.render import RenderingUnavailable, rendering_backend

    try:
        rendering_backend()
    except RenderingUnavailable as exc:
        pytest.skip(str(exc))
    import lidarsim_core as ls

    monkeypatch.chdir(tmp_path)
    scenario = ls.demo_scenario(duration_s=0.02, detail="coarse")
    ls.simulate(scenario).save("run.ply")
    code, out, err = _cli(["view", "run.ply", "--screenshot", "nd3/deeper/v.png"], capsys)
    assert code == 0, err
    assert (tmp_path / "nd3" / "deeper" / "v.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    code, out, err = _cli(["view", "run.ply", "--screenshot", "nd4/v.jpg"], capsys)
    assert code == 2 and "nd4/v.jpg" in err and not os.path.exists("nd4")
