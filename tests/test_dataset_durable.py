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
from lidarsim_core.dataset import generate
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

    def crash(*args, **kwargs):  # the machine stops before the final manifest
        raise KeyboardInterrupt

    monkeypatch.setattr(generate, "_finish", crash)
    out = tmp_path / "crashed"
    with monkeypatch.context() as m:
        m.setattr(atomic.os, "fsync", lambda fd: (
            fsyncs.append(Path(os.readlink(f"/proc/self/fd/{fd}")).name), real_fsync(fd)))
        with pytest.raises(KeyboardInterrupt):
            generate_dataset(scenario, out)
    # frames are renamed into place without an fsync each and synced two at a time, in order
    assert synced == [[f"frame_{f:06d}.ply{x}" for f in (k, k + 1) for x in ("", ".json")]
                      for k in range(0, 8, 2)]
    assert not [n for n in fsyncs if "frame_" in n]
    assert len([n for n in fsyncs if DURABLE in n]) == len(synced)  # the record, once a block
    record = json.loads((out / DURABLE).read_text())
    (name, ranges), = record["sequences"].items()
    assert ranges == [[0, 8]]

    # the last block was not synced when the machine stopped: its frames are not in the
    # record, and one of them is what a crash can leave, a file of the right size of zeros
    (out / DURABLE).write_text(json.dumps({"sequences": {name: [[0, 6]]}}))
    path = out / "frames" / "frame_000007.ply"
    path.write_bytes(bytes(path.stat().st_size))
    monkeypatch.undo()
    generate_dataset(scenario, out)
    assert _files(out) == reference
    assert not (out / DURABLE).exists()
