"""A serial dataset's frames written by a child process (dataset.writer_process): the same
bytes as the writer threads, the same one-line errors, and a child that dies mid-run ends
the run with one line; the rerun resumes to the same directory."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

import lidarsim_core.dataset.writer_process as writer_module
from lidarsim_core.base.errors import ConfigError, OutputError
from lidarsim_core.dataset.generate import generate_dataset
from lidarsim_core.scenario import demo_scenario, scenario_from_dict

pytestmark = pytest.mark.skipif(os.name != "posix", reason="the writer process is POSIX-only")

FRAMES = 12


def _scenario():
    data = demo_scenario(duration_s=0.01, detail="coarse").model_dump(mode="json")
    data["scan"] = {"duration_s": 0.01, "frames": FRAMES, "frame_period_s": 0.05}
    return scenario_from_dict(data, source="<test>")


def _files(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes()
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != ".lock"}


def _ready(monkeypatch) -> writer_module.WriterProcess:
    monkeypatch.setenv("LIDARSIM_WRITER", "process")
    process = writer_module.writer_process()
    assert process is not None and process.ready.wait(120), "the writer process did not start"
    return process


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> dict[str, bytes]:
    """The dataset written by the writer threads alone."""
    out = tmp_path_factory.mktemp("threads") / "ds"
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("LIDARSIM_WRITER", "threads")
        generate_dataset(_scenario(), out)
    return _files(out)


def test_the_process_writes_the_same_bytes_as_the_threads(tmp_path, monkeypatch, reference):
    process = _ready(monkeypatch)
    before = process.sent
    generate_dataset(_scenario(), tmp_path / "ds")
    assert process.sent - before == FRAMES  # every frame went to the child
    assert _files(tmp_path / "ds") == reference


def test_an_error_in_the_child_is_the_threads_error(tmp_path, monkeypatch):
    import lidarsim_core.dataset.executors as executors

    real = executors._FrameWriter.put

    def put(self, job, spool, info):
        if job.frame == 3:  # a directory appears in the frame's way
            Path(job.path).mkdir()
        return real(self, job, spool, info)

    monkeypatch.setattr(executors._FrameWriter, "put", put)
    messages = []
    for mode in ("threads", "process"):
        out = tmp_path / mode
        if mode == "process":
            _ready(monkeypatch)
        else:
            monkeypatch.setenv("LIDARSIM_WRITER", "threads")
        with pytest.raises(OutputError) as info:
            generate_dataset(_scenario(), out)
        messages.append(str(info.value).replace(str(out), "OUT"))
        assert not list(out.rglob("*.part"))
    assert messages[0] == messages[1]
    assert messages[0] == "OUT/frames/frame_000003.ply: output path is a directory"


def test_a_child_killed_mid_run_stops_the_run_and_the_rerun_resumes(tmp_path, monkeypatch,
                                                                      reference):
    process = _ready(monkeypatch)
    real = writer_module.WriterProcess.send

    def send(self, token, *args):
        if token == 4:  # frames 0-3 sent: the child dies while it has them in hand
            os.kill(self._child.pid, signal.SIGKILL)
            self._child.wait()
        return real(self, token, *args)

    monkeypatch.setattr(writer_module.WriterProcess, "send", send)
    with pytest.raises(OutputError, match="the dataset writer process stopped"):
        generate_dataset(_scenario(), tmp_path / "ds")
    assert process.broken is not None
    monkeypatch.setattr(writer_module.WriterProcess, "send", real)
    replacement = _ready(monkeypatch)
    assert replacement is not process
    generate_dataset(_scenario(), tmp_path / "ds")
    assert _files(tmp_path / "ds") == reference


def test_a_forked_process_starts_its_own_child(monkeypatch):
    process = _ready(monkeypatch)
    monkeypatch.setattr(process, "pid", -1)  # as a fork's copy sees it
    other = writer_module.writer_process()
    assert other is not None and other is not process
    monkeypatch.setattr(writer_module, "_process", process)
    other.close()


def test_the_mode_is_read_from_the_environment(monkeypatch):
    monkeypatch.setenv("LIDARSIM_WRITER", "threads")
    assert writer_module.writer_process() is None
    monkeypatch.setenv("LIDARSIM_WRITER", "proces")
    with pytest.raises(ConfigError, match="LIDARSIM_WRITER='proces' must be one of"):
        writer_module.writer_process()


def _spool_of(parts):
    from lidarsim_core.io.points import PointSpool
    from lidarsim_core.records.pointcloud import FrameInfo

    spool = PointSpool(FrameInfo.from_dict(_frame_dict()))
    for part in parts:
        spool.append(part)
    return spool


def _frame_dict():
    from lidarsim_core.pipeline import Simulation

    return Simulation(_scenario()).frame_info(0).to_dict()


def test_the_child_joins_the_chunks_as_the_spool_does():
    """The chunks' columns go to the child as they are (no join on the simulating thread);
    joined there, column by column with NumPy's assignment casts, they are the spool's own
    records to the bit: a float64 column of a float32 field (rounded), an int64 column of an
    int16 field, a bool column of a uint8 field, a plugin's extra column, an empty chunk."""
    import numpy as np

    rng = np.random.default_rng(7)

    def part(n):
        return {"x": rng.normal(size=n), "intensity": rng.normal(size=n) * 1e3,
                "target": rng.integers(-3, 3, size=n), "detected": rng.random(n) < 0.5,
                "snr_db": rng.normal(size=n).astype(np.float32)}

    parts = [part(5), part(0), part(1), part(64)]
    spool = _spool_of(parts)
    layout_parts = spool.parts()
    assert writer_module.sendable(layout_parts)
    layout, columns = writer_module._layout(layout_parts)
    data = b"".join(bytes(b) for b in columns)
    assert len(data) == writer_module._columns_size(layout)
    joined = writer_module.joined_records(spool.record_dtype, layout, data)
    expected = spool.records()
    assert joined.dtype == expected.dtype and joined.tobytes() == expected.tobytes()
    assert joined["intensity"].dtype == np.float32 and joined["target"].dtype == np.int16


def test_a_frame_header_and_its_columns_are_read_as_sent():
    """The header goes down the pipe in the frame's one ``writev``, framed as
    ``Connection.send`` frames it: a real connection's ``recv`` reads exactly the header,
    and the columns' bytes follow it untouched (a large header and an empty message too)."""
    import os
    from multiprocessing.connection import Connection

    import numpy as np

    read_fd, write_fd = os.pipe()
    rx = Connection(read_fd, writable=False)
    header = (3, "frames/f.ply", "ply", {"binary": True}, _frame_dict(), None, [(2, ["<f8"])])
    large = ("x" * 30_000, list(range(2_000)))  # beyond Connection's 16 KiB single write
    columns = [np.arange(2.0)]
    for message in (header, large, None):
        writer_module._write_all(write_fd, [*writer_module._framed(message), *columns])
        assert rx.recv() == message
        assert bytes(writer_module._read_exact(read_fd, 16)) == columns[0].tobytes()
    os.close(write_fd)
    rx.close()


def test_only_plain_columns_are_sent_as_bytes():
    """Frames the child could not rebuild from bytes stay with the writer thread."""
    import numpy as np

    plain = {"x": np.arange(4.0), "target": np.arange(4, dtype=np.int16)}
    assert writer_module.sendable([plain])
    assert not writer_module.sendable([{**plain, "label": np.array(list("abcd"), dtype=object)}])
    assert not writer_module.sendable([{**plain, "x": np.arange(8.0)[::2]}])  # strided
    pairs = np.zeros(4, dtype=[("a", "f8"), ("b", "f8")])
    assert not writer_module.sendable([{**plain, "pair": pairs}])
    stamps = np.zeros(4, dtype="M8[ns]")  # no buffer export
    assert not writer_module.sendable([{**plain, "time": stamps}])
    assert not writer_module.sendable([{**plain, "xyz": np.zeros((4, 3))}])
    assert not writer_module.sendable([{**plain, "listed": [1, 2, 3, 4]}])


def test_the_child_answers_frames_in_groups(tmp_path, monkeypatch, reference):
    """The child answers up to REPLY_FRAMES frames in one reply (one wake-up of the receiving
    thread; here the twelve frames came as 4 + 4 + 4), and every frame sent is answered by the
    end of the run (the parent asks for the last answers when it waits for them)."""
    process = _ready(monkeypatch)
    sizes = []
    real = writer_module.WriterProcess._in_flight_done

    def done(self, tokens):
        sizes.append(len(tokens))
        return real(self, tokens)

    monkeypatch.setattr(writer_module.WriterProcess, "_in_flight_done", done)
    before = process.sent
    generate_dataset(_scenario(), tmp_path / "ds")
    assert process.sent - before == FRAMES == sum(sizes)
    assert max(sizes) <= writer_module.REPLY_FRAMES
    assert _files(tmp_path / "ds") == reference
