"""Killing ``lidarsim dataset`` mid-run (SIGKILL or SIGINT) and running it again gives the
same directory, byte for byte, as an uninterrupted run; no partial file is ever visible as a
frame."""

from __future__ import annotations

import os
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from test_dataset import SCENARIO, run_cli, tree

FRAMES = 32
CODE = "import sys; from lidarsim_core.cli import main; main(sys.argv[1:])"


def ply_is_whole(path: Path) -> bool:
    """Whether a PLY file has exactly the bytes its header announces."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().split("\n")
    count = next(int(line.split()[2]) for line in header if line.startswith("element vertex"))
    sizes = {"double": 8, "float": 4, "uchar": 1, "short": 2, "int": 4, "uint": 4}
    record = sum(sizes[line.split()[1]] for line in header if line.startswith("property"))
    return len(data) == end + count * record


@pytest.fixture(scope="module")
def scenario(tmp_path_factory) -> Path:
    data = {**SCENARIO, "scan": {"duration_s": 0.05, "frame_period_s": 0.1,
                                 "frames": FRAMES}}
    path = tmp_path_factory.mktemp("scene") / "scene.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def reference(scenario, tmp_path_factory) -> dict[str, str]:
    out = tmp_path_factory.mktemp("ref") / "ds"
    res = run_cli("dataset", str(scenario), "--out", str(out), "--quiet")
    assert res.returncode == 0, res.stderr
    return tree(out)


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT], ids=["SIGKILL", "SIGINT"])
def test_interrupted_run_resumes_to_the_same_directory(scenario, reference, tmp_path, sig):
    out = tmp_path / "ds"
    env = {**os.environ, "LIDARSIM_DISABLE_PLUGIN_AUTOLOAD": "1"}
    proc = subprocess.Popen([sys.executable, "-c", CODE, "dataset", str(scenario), "--out",
                             str(out), "--quiet"], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    frames = out / "frames"
    deadline = time.monotonic() + 60
    try:
        while time.monotonic() < deadline:  # watch until the first frames are finished
            done = list(frames.glob("frame_*.ply.json")) if frames.is_dir() else []
            for path in frames.glob("frame_*.ply") if frames.is_dir() else []:
                assert ply_is_whole(path), f"partial frame visible: {path.name}"
            if len(done) >= 2 or proc.poll() is not None:
                break
            time.sleep(0.005)
        assert proc.poll() is None, "the run finished before it could be interrupted"
        proc.send_signal(sig)
        _, stderr = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    finished = sorted(p.name for p in frames.glob("frame_*.ply"))
    if sig == signal.SIGINT:  # a clean stop: one line, exit 130, its temporary files removed
        assert proc.returncode == 130 and "interrupted" in stderr
        assert not list(out.rglob("*.part"))
        # the message tells the truth: what is kept, and that rerunning resumes
        assert f"{len(finished)} of {FRAMES} frames are complete and kept" in stderr, stderr
        assert "rerun the same command to resume" in stderr
        assert "no partial output was kept" not in stderr
    else:
        assert proc.returncode == -signal.SIGKILL
    assert 0 < len(finished) < FRAMES
    assert all(ply_is_whole(p) for p in frames.glob("frame_*.ply"))
    res = run_cli("dataset", str(scenario), "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert "already done" in res.stdout
    assert tree(out) == reference
    assert not list(out.rglob("*.part"))


def test_ply_checker_detects_truncation(tmp_path):
    path = tmp_path / "t.ply"
    header = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty double x\n" \
             b"end_header\n"
    path.write_bytes(header + struct.pack("<2d", 1.0, 2.0))
    assert ply_is_whole(path)
    path.write_bytes(header + struct.pack("<d", 1.0))
    assert not ply_is_whole(path)
