"""Stopping ``lidarsim simulate`` with SIGINT (Ctrl-C) or SIGTERM while it simulates or while
it writes: one line on stderr, exit 130 or 143, finished frames intact, nothing partial left."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

import pytest
import yaml

SCENARIO = {
    "seed": 3,
    "sensor": {"datasheet": "livox-mid70-rose", "pose": {"position_m": [0, 0, 0]}},
    "targets": [{"name": "plate", "mesh": {"model": "plate", "options": {"size_m": [60, 60]}},
                 "pose": {"position_m": [30, 0, 0]}}],
    "backend": "numpy",
    "noise": [],
}
EXPECTED = {signal.SIGINT: (130, "error: interrupted; no partial output was kept"),
            signal.SIGTERM: (143, "error: terminated (SIGTERM); no partial output was kept")}


def _start(tmp_path: Path, duration_s: float, out: str) -> subprocess.Popen:
    scan = {"duration_s": duration_s, "frames": 2}
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump({**SCENARIO, "scan": scan}))
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", "COLUMNS": "200",
           "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, "-m", "lidarsim_core", "simulate", "scene.yaml",
                             "--out", out], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _wait_for(proc: subprocess.Popen, ready: Callable[[], bool]) -> None:
    deadline = time.monotonic() + 60
    while not ready():
        assert proc.poll() is None, f"the run ended before the signal: {proc.communicate()}"
        assert time.monotonic() < deadline, "timed out waiting for the run"
        time.sleep(0.002)


def _interrupt(proc: subprocess.Popen, sig: int) -> tuple[str, str]:
    proc.send_signal(sig)
    try:
        return proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def _assert_clean_stop(proc: subprocess.Popen, sig: int, stderr: str, tmp_path: Path,
                       finished: set[str]) -> None:
    code, line = EXPECTED[sig]
    assert proc.returncode == code, stderr
    assert [x for x in stderr.splitlines() if x.strip()] == [line]
    assert "Traceback" not in stderr
    names = {p.name for p in tmp_path.iterdir()}
    assert names == {"scene.yaml"} | finished, names  # no partial file, no '.part' file


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_while_writing_leaves_no_file(tmp_path, sig):
    """The signal arrives while frame 0 is being written (its hidden '.part' file exists)."""
    proc = _start(tmp_path, 1.0, "cloud_{frame}.csv")  # CSV: a slow writer, a wide window
    _wait_for(proc, lambda: any(p.suffix == ".part" for p in tmp_path.iterdir()))
    _, stderr = _interrupt(proc, sig)
    _assert_clean_stop(proc, sig, stderr, tmp_path, finished=set())


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_during_a_sequence_keeps_finished_frames_whole(tmp_path, sig):
    """The signal arrives once frame 0 is finished: frame 0 stays, whole; frame 1 never
    appears, not even in part."""
    proc = _start(tmp_path, 5.0, "cloud_{frame}.ply")
    first = proc.stdout.readline()  # printed once frame 0 is written; frame 1 then starts
    assert first.startswith("frame 0: 500,000 points"), (first, proc.communicate())
    _, stderr = _interrupt(proc, sig)
    _assert_clean_stop(proc, sig, stderr, tmp_path, finished={"cloud_0.ply", "cloud_0.ply.json"})
    data = (tmp_path / "cloud_0.ply").read_bytes()
    header = data[:data.index(b"end_header\n") + len(b"end_header\n")].decode()
    assert "element vertex 500000" in header


def test_sigterm_handler_is_restored_after_the_command():
    """The CLI's SIGTERM handler lives only while a command runs (library users keep theirs)."""
    from lidarsim_core import cli

    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(SystemExit) as info:
        cli.main(["--version"])
    assert info.value.code == 0
    assert signal.getsignal(signal.SIGTERM) is before


def test_sigterm_stops_a_dataset_run_cleanly(tmp_path):
    """``lidarsim dataset`` gets the same treatment: one line, exit 143, no '.part' file."""
    scan = {"duration_s": 0.05, "frame_period_s": 0.1, "frames": 40}
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump({**SCENARIO, "scan": scan}))
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1", "COLUMNS": "200"}
    out = tmp_path / "ds"
    proc = subprocess.Popen([sys.executable, "-m", "lidarsim_core", "dataset", "scene.yaml",
                             "--out", "ds", "--quiet"], cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _wait_for(proc, lambda: len(list(out.glob("frames/*.json"))) >= 2)
    _, stderr = _interrupt(proc, signal.SIGTERM)
    code, _ = EXPECTED[signal.SIGTERM]
    assert proc.returncode == code, stderr
    kept = len(list(out.glob("frames/*.ply")))
    assert [x for x in stderr.splitlines() if x.strip()] == [
        f"error: terminated (SIGTERM); {kept} of 40 frames are complete and kept in "
        f"{out.resolve()} (no "
        "partial frame file); rerun the same command to resume"]
    assert not list(out.rglob("*.part"))


def _surfacing_through_a_kernel(interrupt: KeyboardInterrupt) -> SystemError:
    """What numba's dispatcher raises when a signal handler fires while it is called."""
    try:
        try:
            raise interrupt
        except KeyboardInterrupt as exc:
            raise SystemError("CPUDispatcher(...) returned a result with an exception set") \
                from exc
    except SystemError as error:
        return error


def test_an_interrupt_behind_a_kernel_error_is_found():
    from lidarsim_core.base.signals import Terminated, interrupt_behind

    term = Terminated()
    assert interrupt_behind(_surfacing_through_a_kernel(term)) is term
    assert interrupt_behind(ValueError("unrelated")) is None
    assert interrupt_behind(None) is None


@pytest.mark.parametrize("interrupt,code,line", [
    ("Terminated", 143, "error: terminated (SIGTERM); no partial output was kept"),
    ("KeyboardInterrupt", 130, "error: interrupted; no partial output was kept")])
def test_cli_reports_an_interrupt_surfacing_through_a_kernel_as_the_interrupt(
        interrupt, code, line, capsys):
    from lidarsim_core.cli import errors as cli_errors
    from lidarsim_core.base import signals as guard

    cause = guard.Terminated() if interrupt == "Terminated" else KeyboardInterrupt()

    def body() -> None:
        raise _surfacing_through_a_kernel(cause)

    import typer

    with pytest.raises(typer.Exit) as info:
        cli_errors.run_guarded(body)
    assert info.value.exit_code == code
    assert capsys.readouterr().err.strip() == line


def test_simulation_reraises_an_interrupt_surfacing_through_a_kernel(monkeypatch):
    from lidarsim_core.base.signals import Terminated
    from lidarsim_core.pipeline import Simulation
    from lidarsim_core.scenario import demo_scenario

    sim = Simulation(demo_scenario(duration_s=0.01, detail="coarse", backend="numpy"))
    term = Terminated()

    def interrupted(*args, **kwargs):
        raise _surfacing_through_a_kernel(term)

    monkeypatch.setattr("lidarsim_core.pipeline.simulation.process_piece", interrupted)
    fused = sim.fused  # the compiled fast path of the seed paper's model, where it applies
    if fused is not None:
        monkeypatch.setattr(fused, "process", interrupted)
    for path in ([fused, None] if fused is not None else [None]):
        sim.fused = path
        with pytest.raises(Terminated) as info:
            sim.run_frame(0)
        assert info.value is term
