"""At 80 columns and piped (a log, ``| less``, a CI job), every ``--help`` and every listing is
plain text: no box characters, nothing cut with an ellipsis, every value printed whole, and
the help and the benchmark tables fit 80 columns."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

LIDARSIM = [sys.executable, "-m", "lidarsim_core"]
#: Box-drawing characters (U+2500-U+257F).
BOX = re.compile("[\u2500-\u257f]")


def _run(*args: str) -> str:
    env = {**os.environ, "COLUMNS": "80", "LINES": "40", "TERM": "xterm-256color"}
    env.pop("NO_COLOR", None)
    res = subprocess.run(LIDARSIM + list(args), capture_output=True, text=True, env=env,
                         timeout=120)  # stdout is a pipe
    assert res.returncode == 0, res.stdout + res.stderr
    return res.stdout


def _command_paths() -> list[list[str]]:
    """Every command of the app, as the words that call it (``["schema", "sensor"]``)."""
    import typer.main

    from lidarsim_core.cli.main import app

    paths: list[list[str]] = [[]]

    def walk(command, prefix):
        for name, sub in getattr(command, "commands", {}).items():
            paths.append(prefix + [name])
            walk(sub, prefix + [name])

    walk(typer.main.get_command(app), [])
    return paths


def _check_plain(text: str, where: str, *, width: int | None = 80) -> None:
    assert text.strip(), where
    assert not BOX.search(text), f"{where}: box characters\n{text}"
    # rich cuts a value with "…"; Click cuts a command's summary with "..." at the line's
    # end ("[ARGS]..." in a usage line is Click's notation for "several")
    assert "\u2026" not in text, f"{where}: '\u2026'\n{text}"
    cut = [line for line in text.splitlines()
           if line.rstrip().endswith("...") and not line.startswith("Usage:")]
    assert not cut, f"{where}: cut with '...': {cut}"
    if width is not None:
        wide = [line for line in text.splitlines() if len(line) > width]
        assert not wide, f"{where}: lines wider than {width}: {wide}"


def test_every_command_is_found():
    paths = {" ".join(p) for p in _command_paths()}
    assert {"", "demo", "simulate", "plugins", "bench", "evaluate", "schema sensor"} <= paths
    assert len(paths) >= 16


@pytest.mark.parametrize("path", [" ".join(p) for p in _command_paths()])
def test_help_is_plain_and_whole_at_80_columns_piped(path):
    text = _run(*path.split(), "--help")
    _check_plain(text, f"lidarsim {path} --help")
    assert text.startswith("Usage: lidarsim")


def test_help_shows_long_values_whole():
    """The values rich used to cut at 80 columns (`livox_ros_driver2/ms…`, the range bins of
    ``evaluate``) are printed whole, wrapped at word boundaries only."""
    words = " ".join(_run("simulate", "--help").split())
    assert "livox_ros_driver2/msg/CustomMsg" in words
    for fmt in (".ply", ".pcd", ".las", ".laz", ".npz", ".csv", ".mcap"):
        assert fmt in words, fmt
    top = " ".join(_run("--help").split())
    from lidarsim_core.cli.main import app

    for info in app.registered_commands:  # each command's first paragraph, whole
        doc = " ".join(info.callback.__doc__.split("\n\n")[0].split())
        assert doc in top, doc


def test_the_check_catches_boxes_cuts_and_width():
    for bad in ("\u256d\u2500 Options", "livox_ros_driver2/ms\u2026", "Envisat...", "x" * 81):
        with pytest.raises(AssertionError):
            _check_plain(bad, "sample")


def test_listings_print_every_summary_whole():
    from lidarsim_core.plugins.manager import get_registry

    registry = get_registry()
    listed = json.loads(_run("plugins", "--json"))
    table = _run("plugins")
    _check_plain(table, "lidarsim plugins", width=None)  # long cells stay on one line
    by_name = {(e["kind"], e["name"]): e["summary"] for e in listed}
    estimators = [n for k, n in by_name if k == "pose_estimator"]
    assert estimators, listed
    for (kind, name), summary in by_name.items():
        assert summary in table, (kind, name)
        if kind == "pose_estimator":
            cls = registry.get("pose_estimator", name)
            doc = " ".join(cls.__doc__.split("\n\n")[0].split())
            assert summary == doc, (name, summary, doc)  # the whole first paragraph
    sensors = _run("sensors")
    _check_plain(sensors, "lidarsim sensors", width=None)
    for entry in json.loads(_run("sensors", "--json")):
        assert entry["name"] in sensors
    coverage = _run("coverage", "livox-mid70", "--time", "0.02")
    _check_plain(coverage, "lidarsim coverage", width=None)
    assert "off-axis" in coverage


def test_bench_tables_fit_80_columns(monkeypatch, capsys):
    """``lidarsim bench`` (the figures faked: the layout is under test) prints tables no wider
    than 80 columns when piped, every figure whole."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("bench_fixture",
                                                  Path(__file__).with_name("test_bench.py"))
    fixture = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fixture)
    fake = {**fixture.FAKE, "suite": fixture.SUITE}
    fake["scenes"] = {**fake["scenes"], "envisat-close": {
        **fake["scenes"]["envisat"], "backends": {"numpy": 2.2e6, "embree": 3.3e7},
        "bare_embree": 3.5e7, "bare_embree_1thread": 1.9e7, "simulate_over_bare": 0.31}}
    fake["suite"]["scenes"] = {**fake["suite"]["scenes"],
                               "vlp16-circling-15m": fake["suite"]["scenes"]["tumbling-risley"]}
    monkeypatch.setattr("lidarsim_core.bench.throughput.run_benchmark",
                        lambda quick=False: fake)
    from lidarsim_core.cli.main import main

    with pytest.raises(SystemExit) as stop:
        main(["bench", "--quick"])
    assert stop.value.code == 0
    out = capsys.readouterr().out
    assert not BOX.search(out) and "\u2026" not in out
    table_lines = [line for line in out.splitlines() if re.match(r"[\w-]+ {2,}\S", line)]
    assert len(table_lines) == 6, out  # two tables, each a header and two scenes
    assert max(len(line) for line in table_lines) <= 80, table_lines
    for figure in ("33.00M", "35.00M", "19.00M", "0.31", "2.00M", "20.00M", "0.12"):
        assert figure in out, figure


def test_demo_warms_the_kernels_with_a_bar_before_any_output(monkeypatch, tmp_path):
    """The first ``lidarsim demo`` after installing spends up to a minute compiling the
    kernels: they are compiled up front with a progress display, before anything is
    written."""
    import lidarsim_core.kernels as kernels
    from lidarsim_core.cli.progress import KernelBar

    seen: list[object] = []

    class Stop(Exception):
        pass

    def warm_up(display=None):
        seen.append(display)
        raise Stop

    monkeypatch.setattr(kernels, "warm_up", warm_up)
    from lidarsim_core.cli.demo import _demo

    with pytest.raises(Stop):
        _demo(tmp_path / "out", 0.1, "auto", "coarse", 1)
    assert len(seen) == 1 and isinstance(seen[0], KernelBar), seen
    assert not (tmp_path / "out").exists()  # nothing written before the work


def _terminal_bar(monkeypatch, times):
    """A KernelBar drawing on a fake 80-column terminal, with a clock reading ``times``."""
    import io

    from rich.console import Console

    import lidarsim_core.cli.progress as progress

    screen = io.StringIO()
    monkeypatch.setattr(progress, "_stderr_console",
                        lambda: Console(file=screen, force_terminal=True, width=80))
    bar = progress.KernelBar()
    clock = iter(times)
    bar._clock = lambda: next(clock)
    return bar, screen


def test_kernel_bar_shows_a_slow_compile_and_names_the_kernel(monkeypatch):
    # three kernels, the first taking 20 s (compiled): the bar appears and names the next
    bar, screen = _terminal_bar(monkeypatch, [0.0, 20.0, 21.0, 22.0])
    for done, name in enumerate(["philox", "rose", "risley"]):
        bar(done, 3, name)
    bar(3, 3, "")
    text = screen.getvalue()
    assert "compiling kernels" in text and "rose" in text and "1/3" in text, text


def test_kernel_bar_stays_silent_when_the_kernels_load_from_the_cache(monkeypatch):
    bar, screen = _terminal_bar(monkeypatch, [0.0, 0.05, 0.1, 0.15])
    for done, name in enumerate(["philox", "rose", "risley"]):
        bar(done, 3, name)
    bar(3, 3, "")
    assert screen.getvalue() == ""


def test_kernel_bar_is_silent_when_stderr_is_not_a_terminal(capsys):
    from lidarsim_core.cli.progress import KernelBar

    bar = KernelBar()
    bar._clock = iter([0.0, 30.0, 60.0]).__next__
    bar(0, 2, "philox")
    bar(1, 2, "rose")
    bar(2, 2, "")
    assert capsys.readouterr().err == ""
