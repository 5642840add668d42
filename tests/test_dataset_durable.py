"""A serial ``lidarsim dataset`` run makes its frames durable a block at a time
(lidarsim_core.dataset.durable): the frames of synced blocks are recorded, and a resumed run
checks the checksum of every other frame, so a frame emptied by a crash before its block was
synced is simulated again and the directory ends the same to the bit."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

import lidarsim_core.dataset.executors as executors
from lidarsim_core.base import atomic
from lidarsim_core.dataset.durable import DURABLE
from lidarsim_core.dataset.generate import generate_dataset
from lidarsim_core.scenario import demo_scenario, scenario_from_dict


def _scenario():
    data = demo_scenario(duration_s=0.01, detail="coarse").model_dump(mode="json")
    data["scan"] = {"duration_s": 0.01, "frames": 8, "frame_period_s": 0.05}
    return scenario_from_dict(data, source="<test>")


def _files(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes()
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != ".lock"}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="names fds via /proc")
def test_a_crash_before_a_block_is_synced_is_repaired_on_resume(tmp_path, monkeypatch):
    scenario = _scenario()
    generate_dataset(scenario, tmp_path / "reference")
    reference = _files(tmp_path / "reference")
    assert DURABLE not in reference  # removed once the manifest is final

    monkeypatch.setattr(executors, "SYNC_BLOCK", 2)
    synced: list[list[str]] = []
    real_sync = executors.sync_files
    monkeypatch.setattr(executors, "sync_files",
                        lambda paths: (synced.append([Path(p).name for p in paths]),
                                       real_sync(paths)))
    fsyncs: list[str] = []
    real_fsync = atomic.os.fsync
    simulate = executors.simulate_frame_job

    def stop_at_6(job):
        if job.frame == 6:
            raise KeyboardInterrupt
        return simulate(job)

    monkeypatch.setattr(executors, "simulate_frame_job", stop_at_6)
    out = tmp_path / "crashed"
    with monkeypatch.context() as m:
        m.setattr(atomic.os, "fsync", lambda fd: (
            fsyncs.append(Path(os.readlink(f"/proc/self/fd/{fd}")).name), real_fsync(fd)))
        with pytest.raises(KeyboardInterrupt):
            generate_dataset(scenario, out)
    # frames are renamed into place without an fsync each; the blocks synced are recorded
    frames = sorted(p.name for p in (out / "frames").glob("frame_*.ply"))
    assert len(frames) >= 2
    assert synced and synced[0] == ["frame_000000.ply", "frame_000000.ply.json",
                                    "frame_000001.ply", "frame_000001.ply.json"]
    assert all(len(block) == 4 for block in synced)  # blocks of two frames, two files each
    # no frame file is synced on its own; the record of durable frames is, once a block
    assert not [n for n in fsyncs if "frame_" in n]
    assert len([n for n in fsyncs if DURABLE in n]) == len(synced)
    record = json.loads((out / DURABLE).read_text())
    (name, ranges), = record["sequences"].items()
    durable = {f for a, b in ranges for f in range(a, b)}
    assert durable == {int(n[6:12]) for block in synced for n in block}
    assert 6 not in durable

    # what a crash can leave of a frame whose block was not synced: its sidecar, and a file
    # of the right size holding zeros
    victim = next(f for f in range(8)
                  if f not in durable and (out / "frames" / f"frame_{f:06d}.ply").exists()) \
        if len(frames) > len(durable) else None
    if victim is None:  # every written frame was synced: drop one from the record instead
        victim = max(durable)
        durable.discard(victim)
        (out / DURABLE).write_text(json.dumps({"sequences": {
            name: [[f, f + 1] for f in sorted(durable)]}}))
    path = out / "frames" / f"frame_{victim:06d}.ply"
    path.write_bytes(bytes(path.stat().st_size))
    monkeypatch.setattr(executors, "simulate_frame_job", simulate)
    generate_dataset(scenario, out)
    assert _files(out) == reference
