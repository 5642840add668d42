"""The command line for people and pipes (names whole at 80 columns, plain text when piped,
``--json``, help without ``<bool>``), and the one overwrite policy of every command and of
``cloud.save``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from helpers import CLI_SCENARIO as SCENARIO


def run_cli(*args: str, cwd: Path | None = None, columns: int = 80
            ) -> subprocess.CompletedProcess:
    """The CLI as a pipe sees it: stdout is not a terminal, ``COLUMNS=80``."""
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", "COLUMNS": str(columns)}
    return subprocess.run([sys.executable, "-m", "lidarsim_core", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """The CLI in this process (faster; stdout is not a terminal either)."""
    from typer.testing import CliRunner

    from lidarsim_core.cli import app
    old = Path.cwd()
    os.chdir(cwd)
    try:
        result = CliRunner().invoke(app, list(args), env={"COLUMNS": "80"})
    finally:
        os.chdir(old)
    return subprocess.CompletedProcess(args, result.exit_code, result.stdout, result.stderr)


def _snapshot(directory: Path) -> dict[str, tuple[int, int]]:
    return {p.name: (p.stat().st_mtime_ns, p.stat().st_size) for p in directory.iterdir()}


# ---- tables at 80 columns and piped ---------------------------------------------------------
def test_sensors_piped_at_80_columns_prints_every_name_whole():
    from lidarsim_core.plugins import get_registry

    res = run_cli("sensors")
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert lines[0].split()[:3] == ["name", "sensor", "FOV"]
    assert not any(ch in res.stdout for ch in "…┃━│╇\x1b")  # no ellipsis, box, colour
    first_words = [line.split()[0] for line in lines[1:]]
    names = [e.name for e in get_registry().iter("sensor")]
    assert first_words == names and len(names) >= 10
    second = lines[0].index("sensor")  # every row's second column starts under its header
    assert all(line[second - 2:second] == "  " and line[second] != " " for line in lines)


def test_plugins_piped_at_80_columns_prints_every_name_whole():
    from lidarsim_core.plugins import get_registry
    from lidarsim_core.plugins.registry import KINDS

    res = run_cli("plugins")
    assert res.returncode == 0, res.stderr
    rows = [line.split()[:2] for line in res.stdout.splitlines()[1:]]
    expected = [[kind, e.name] for kind in KINDS for e in get_registry().iter(kind)]
    assert rows == expected


def test_every_table_has_json():
    sensors = json.loads(run_cli("sensors", "--json").stdout)
    assert any(s["name"] == "livox-mid70-rose" for s in sensors)
    plugins = json.loads(run_cli("plugins", "--json").stdout)
    assert {"kind", "name", "provider", "summary"} == set(plugins[0])
    coverage = json.loads(run_cli("coverage", "livox-mid70", "--time", "0.02", "--json").stdout)
    assert 0 < coverage["coverage"] < 1


def test_plain_table_aligns_and_never_cuts():
    from lidarsim_core.cli.output import Column, plain_table

    text = plain_table([Column("name"), Column("n", right=True)],
                       [["a-very-long-sensor-name-that-is-wider-than-anything", "1"],
                        ["b", "1,000"]])
    assert text.splitlines() == [
        "name                                                     n",
        "a-very-long-sensor-name-that-is-wider-than-anything      1",
        "b                                                    1,000"]


def test_help_shows_no_type_after_plain_flags():
    for args in (["--help"], ["simulate", "--help"], ["demo", "--help"], ["report", "--help"]):
        res = run_cli(*args)
        assert res.returncode == 0 and "--help" in res.stdout
        assert "<bool>" not in res.stdout, args
    assert "<path>" in run_cli("simulate", "--help").stdout  # options with values keep theirs
    assert "--no-overwrite" not in run_cli("simulate", "--help").stdout


def test_simulate_progress_counts_every_pulse():
    from lidarsim_core.cli.simulate import _counted_chunks
    from lidarsim_core.pipeline import Simulation
    from lidarsim_core.scenario import scenario_from_dict

    sim = Simulation(scenario_from_dict({**SCENARIO, "chunk_rays": 1000}))

    class Counter:
        total = 0

        def advance(self, n: int) -> None:
            self.total += n

    counter = Counter()
    chunks = list(_counted_chunks(sim, 0, counter))
    assert len(chunks) == 5 and counter.total == sim.frame_info(0).rays_emitted == 5000


# ---- the demo: one line of header, its own files only, the policy -------------------------
@pytest.mark.slow  # three demo runs with their reports
def test_demo_output_overwrite_policy_and_json(tmp_path):
    out = tmp_path / "d"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    res = run_cli("demo", "--out", str(out), "--duration", "0.05", "--backend", "numpy",
                  "--json")
    assert res.returncode == 0, res.stderr
    summary = json.loads(res.stdout)
    on_disk = {p.name for p in out.iterdir()} - {"notes.txt"}
    assert set(summary["files"]) == on_disk and len(on_disk) >= 9
    assert [r["run"] for r in summary["runs"]] == ["with_errors", "without_errors"]
    assert all(r["sim_s"] <= r["first_run_s"] for r in summary["runs"])  # best of the runs
    before = _snapshot(out)

    again = run_cli("demo", "--out", str(out), "--duration", "0.05", "--backend", "numpy")
    assert again.returncode == 2
    assert "would replace existing files" in again.stderr and "--overwrite" in again.stderr
    assert "envisat_mid70_with_errors.ply" in again.stderr
    assert _snapshot(out) == before  # refused before any work: nothing changed

    third = run_cli("demo", "--out", str(out), "--duration", "0.05", "--backend", "numpy",
                    "--overwrite")
    assert third.returncode == 0, third.stderr
    lines = third.stdout.splitlines()
    assert lines[0].startswith("lidarsim demo:") and lines[0].endswith("seed 2024")
    assert f"wrote {len(on_disk)} files to {out}/" in third.stdout  # this run's files only
    assert (out / "notes.txt").read_text() == "mine"
    assert "envisat/solar_array" in third.stdout and "┃" not in third.stdout

    # the report of that run, into the same folder: refused, then replaced with --overwrite
    report = run_cli("report", str(out), "--out", str(out), "--no-3d")
    assert report.returncode == 2 and "fig05_pattern.png" in report.stderr
    report = run_cli("report", str(out), "--out", str(out), "--no-3d", "--overwrite")
    assert report.returncode == 0, report.stderr
    assert (out / "notes.txt").read_text() == "mine"


# ---- every other command and cloud.save ---------------------------------------------------
@pytest.fixture()
def scene(tmp_path: Path) -> Path:
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(SCENARIO))
    return path


@pytest.mark.parametrize("command", [
    ["simulate", "scene.yaml", "--out", "{out}.npz"],
    ["poses", "scene.yaml", "--out", "{out}.json"],
    ["pattern", "livox-mid70", "--duration", "0.01", "--out", "{out}.npz"],
], ids=["simulate", "poses", "pattern"])
def test_file_commands_refuse_then_overwrite_and_create_folders(scene, command):
    work = scene.parent
    argv = [a.format(out="new/sub/result") for a in command]
    first = cli(*argv, cwd=work)
    assert first.returncode == 0, first.stderr
    target = work / argv[-1]
    assert target.is_file()  # the missing folders were created
    before = target.stat().st_mtime_ns, target.read_bytes()
    second = cli(*argv, cwd=work)
    assert second.returncode == 2
    assert "output file exists (use --overwrite to replace it)" in second.stderr
    assert (target.stat().st_mtime_ns, target.read_bytes()) == before
    third = cli(*argv, "--overwrite", cwd=work)
    assert third.returncode == 0, third.stderr


def test_output_folder_that_cannot_be_created_is_explained(scene):
    (scene.parent / "blocker").write_text("a file")
    res = cli("simulate", "scene.yaml", "--out", "blocker/x.npz", cwd=scene.parent)
    assert res.returncode == 2
    assert "cannot create the output directory blocker: blocker is a file" in res.stderr


def test_cloud_save_never_replaces_without_overwrite(tmp_path):
    from lidarsim_core.base.errors import OutputError
    from lidarsim_core.pipeline import simulate
    from lidarsim_core.scenario import scenario_from_dict

    cloud = simulate(scenario_from_dict(SCENARIO))
    path = cloud.save(tmp_path / "new" / "c.npz")  # the folder is created
    data = path.read_bytes()
    with pytest.raises(OutputError, match="output file exists .pass overwrite=True"):
        cloud.save(path)
    assert path.read_bytes() == data
    (tmp_path / "new" / "d.npz.json").write_text("{}")  # a sidecar in the way counts too
    with pytest.raises(OutputError, match="d.npz.json"):
        cloud.save(tmp_path / "new" / "d.npz")
    assert not (tmp_path / "new" / "d.npz").exists()
    cloud.save(path, overwrite=True)
    assert np.load(path)["x"].shape == (len(cloud),)


# ---- the top-level API --------------------------------------------------------------------
def test_top_level_namespace_is_the_public_api():
    import lidarsim_core as ls

    assert dir(ls) == sorted(ls.__all__)
    for helper in ("Any", "TYPE_CHECKING", "annotations", "import_module"):
        assert helper not in dir(ls) and helper not in ls.__all__
    assert {"simulate", "load_scenario", "PointCloud", "Simulation"} <= set(ls.__all__)


def test_cloud_and_frame_reprs_are_one_line():
    from lidarsim_core.pipeline import simulate
    from lidarsim_core.scenario import scenario_from_dict

    cloud = simulate(scenario_from_dict(SCENARIO))
    text = repr(cloud)
    assert "\n" not in text and len(text) < 200 and "array" not in text
    assert text.startswith(f"PointCloud({len(cloud):,} points from 5,000 rays, frame 0")
    assert "\n" not in repr(cloud.frame) and "livox-mid70-rose" in repr(cloud.frame)


def test_progress_bar_draws_at_a_terminal_and_stays_silent_in_a_pipe(monkeypatch):
    import io

    from rich.console import Console

    from lidarsim_core.cli import output as cli_output

    screen = io.StringIO()
    monkeypatch.setattr(cli_output, "console", lambda stderr=False: Console(
        file=screen, force_terminal=True, width=100))
    with cli_output.RayProgress(1000, "frame 7") as progress:
        progress.advance(400)
        progress.advance(600)
    assert "frame 7" in screen.getvalue() and "1000/1000" in screen.getvalue()

    piped = io.StringIO()
    monkeypatch.setattr(cli_output, "console", lambda stderr=False: Console(
        file=piped, force_terminal=False))
    with cli_output.RayProgress(1000, "frame 7") as progress:
        progress.advance(1000)
    assert piped.getvalue() == ""


def test_a_narrow_terminal_leaves_out_optional_columns_never_names():
    from lidarsim_core.cli.output import Column, _fitting_columns

    columns = [Column("name", whole=True), Column("model", optional=True), Column("fov"),
               Column("provider", optional=True)]
    rows = [["livox-mid70-rose", "Livox Mid-70 (seed paper's rose model)", "70.4°",
             "lidarsim-core 0.1.0 (built-in)"]]
    assert _fitting_columns(columns, rows, 200) == [0, 1, 2, 3]
    assert _fitting_columns(columns, rows, 80) == [0, 1, 2]     # the last optional goes first
    assert _fitting_columns(columns, rows, 30) == [0, 2]        # names and required stay
    assert _fitting_columns(columns, rows, 5) == [0, 2]
