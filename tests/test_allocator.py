"""glibc keeps a frame's freed blocks for the next one (lidarsim_core.base.allocator): frames of
large arrays stop faulting their pages in again, counted by the kernel (getrusage)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

from lidarsim_core.base.allocator import malloc_mode
from lidarsim_core.base.errors import ConfigError

#: Three arrays of 16, 16 and 8 MB allocated, written and freed per "frame", as a piece does.
PROBE = textwrap.dedent("""
    import resource
    import numpy as np
    from lidarsim_core.base.allocator import keep_freed_memory
    applied = keep_freed_memory()
    def frame():
        a, b, c = np.ones(2_000_000), np.ones(2_000_000), np.ones(1_000_000)
        del a, b, c
    frame(); frame()
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(10):
        frame()
    print(applied, (resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before) / 10)
""")


def _faults_per_frame(mode: str) -> tuple[bool, float]:
    env = {**os.environ, "LIDARSIM_MALLOC": mode}
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True,
                         text=True, check=True).stdout.split()
    return out[0] == "True", float(out[1])


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc settings")
def test_frames_reuse_the_last_frames_pages() -> None:
    applied, kept = _faults_per_frame("keep")
    assert applied
    assert kept < 20  # 40 MB per frame: 10,000 pages if they were faulted in again
    untouched, system = _faults_per_frame("system")
    assert not untouched
    assert system > 1000  # glibc's defaults hand the blocks back and fault them in again


def test_malloc_mode_refuses_junk(monkeypatch) -> None:
    monkeypatch.setenv("LIDARSIM_MALLOC", "fast")
    with pytest.raises(ConfigError, match="LIDARSIM_MALLOC='fast' must be one of keep, system"
                       ) as caught:
        malloc_mode()
    assert caught.value.field == "LIDARSIM_MALLOC"
    monkeypatch.setenv("LIDARSIM_MALLOC", " ")
    assert malloc_mode() == "keep"
