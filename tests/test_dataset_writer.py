"""Serial ``dataset`` runs write each frame on a writer thread while the next is simulated:
the same bytes as writing in line, results in order, errors and interrupts stop both sides."""

from __future__ import annotations

import functools
from pathlib import Path

import pytest

import lidarsim_core.dataset.executors as executors
from lidarsim_core.dataset import generate
from lidarsim_core.dataset.generate import generate_dataset
from lidarsim_core.scenario import demo_scenario


def _files(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes()
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != ".lock"}


def test_overlapped_writing_gives_the_same_bytes_as_writing_in_line(tmp_path, monkeypatch):
    data = demo_scenario(duration_s=0.01, detail="coarse").model_dump(mode="json")
    data["scan"] = {"duration_s": 0.01, "frames": 5, "frame_period_s": 0.05}
    from lidarsim_core.scenario import scenario_from_dict

    scenario = scenario_from_dict(data, source="<test>")
    generate_dataset(scenario, tmp_path / "overlap")
    monkeypatch.setattr(generate, "run_serial",
                        functools.partial(executors.run_serial, overlap=False))
    generate_dataset(scenario, tmp_path / "inline")
    overlap, inline = _files(tmp_path / "overlap"), _files(tmp_path / "inline")
    assert len([n for n in overlap if n.endswith(".ply")]) == 5
    assert overlap == inline


class _Spool:
    closed: list[int] = []

    def __init__(self, frame: int) -> None:
        self.frame = frame

    def close(self) -> None:
        _Spool.closed.append(self.frame)


class _Job:
    def __init__(self, frame: int) -> None:
        self.frame = frame


def _fake(monkeypatch, *, fail_write: int | None = None, interrupt_at: int | None = None):
    _Spool.closed = []
    written: list[int] = []

    def simulate(job):
        if job.frame == interrupt_at:
            raise KeyboardInterrupt
        return _Spool(job.frame), None

    def write(job, spool, info):
        if job.frame == fail_write:
            spool.close()
            raise OSError("disk full")
        written.append(job.frame)
        spool.close()
        return {"frame": job.frame}

    monkeypatch.setattr(executors, "simulate_frame_job", simulate)
    monkeypatch.setattr(executors, "write_frame_job", write)
    return written


def test_results_arrive_in_order_and_every_spool_is_closed(monkeypatch):
    written = _fake(monkeypatch)
    seen: list[int] = []
    executors.run_serial((_Job(k) for k in range(20)), lambda r: seen.append(r["frame"]))
    assert seen == written == list(range(20))
    assert sorted(_Spool.closed) == list(range(20))


def test_a_writer_error_stops_the_run(monkeypatch):
    written = _fake(monkeypatch, fail_write=3)
    seen: list[int] = []
    with pytest.raises(OSError, match="disk full"):
        executors.run_serial((_Job(k) for k in range(50)), lambda r: seen.append(r["frame"]))
    assert written == [0, 1, 2]
    assert seen == written[:len(seen)]
    # frames simulated after the failure were dropped, not left open
    assert set(_Spool.closed) >= set(range(3))
    assert len(_Spool.closed) < 50


def test_an_interrupt_while_simulating_finishes_the_queued_frames_or_drops_them(monkeypatch):
    written = _fake(monkeypatch, interrupt_at=6)
    with pytest.raises(KeyboardInterrupt):
        executors.run_serial((_Job(k) for k in range(50)), lambda r: None)
    # nothing after the interrupt; every simulated frame's spool closed
    assert max(written, default=-1) < 6
    assert sorted(_Spool.closed) == list(range(6))
