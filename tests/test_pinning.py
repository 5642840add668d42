"""Each thread of a worker pool on a CPU of its own (lidarsim_core.base.pinning): the threads
of a real pool report one CPU each, distinct, taken from the process's allowed set; the
setting is refused with one line when mistyped; a pool larger than the allowed CPUs, or
``LIDARSIM_PIN_THREADS=off``, leaves the threads to the scheduler."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

from lidarsim_core.base.errors import ConfigError
from lidarsim_core.base.pinning import pin_mode, pool_cpus

linux_affinity = pytest.mark.skipif(not hasattr(os, "sched_setaffinity"),
                                    reason="needs sched_setaffinity (Linux)")

#: The CPUs each thread of a two-thread pipeline pool may run on, seen from the threads.
PROBE = textwrap.dedent("""
    import os, threading
    from lidarsim_core.base.threads import shared_pool
    pool = shared_pool(2, "pipeline")
    barrier = threading.Barrier(2)
    def where(_):
        barrier.wait()  # both threads started: each reports its own affinity
        return sorted(os.sched_getaffinity(0))
    print(sorted(os.sched_getaffinity(0)), list(pool.map(where, range(2))))
""")


def _affinities(mode: str, cpus: str | None = None) -> tuple[list[int], list[list[int]]]:
    env = {**os.environ, "LIDARSIM_PIN_THREADS": mode}
    command = [sys.executable, "-c", PROBE]
    if cpus is not None:
        command = ["taskset", "-c", cpus, *command]
    out = subprocess.run(command, env=env, capture_output=True, text=True, check=True).stdout
    allowed, per_thread = out.split("] ", 1)
    return eval(allowed + "]"), eval(per_thread)  # noqa: S307 -- our own probe's lists


@linux_affinity
@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs two CPUs")
def test_pool_threads_are_bound_to_distinct_allowed_cpus() -> None:
    allowed, per_thread = _affinities("auto")
    assert all(len(cpus) == 1 for cpus in per_thread)
    bound = sorted(cpus[0] for cpus in per_thread)
    assert bound == allowed[:2]  # distinct, the first two allowed


@linux_affinity
@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs two CPUs")
def test_off_leaves_every_thread_on_every_allowed_cpu() -> None:
    allowed, per_thread = _affinities("off")
    assert per_thread == [allowed, allowed]


@linux_affinity
@pytest.mark.skipif(subprocess.run(["which", "taskset"], capture_output=True).returncode != 0,
                    reason="needs taskset (util-linux)")
def test_more_threads_than_allowed_cpus_are_left_alone() -> None:
    cpu = str(min(os.sched_getaffinity(0)))
    allowed, per_thread = _affinities("auto", cpus=cpu)  # one CPU, two threads
    assert allowed == [int(cpu)] and per_thread == [allowed, allowed]


def test_pool_cpus_follows_the_allowed_set(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("LIDARSIM_PIN_THREADS", raising=False)
    if not hasattr(os, "sched_setaffinity"):
        assert pool_cpus(2) is None
        return
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {3, 1, 7})
    assert pool_cpus(1) is None  # one thread: nothing to keep apart
    assert pool_cpus(2) == [1, 3]
    assert pool_cpus(3) == [1, 3, 7]
    assert pool_cpus(4) is None
    monkeypatch.setenv("LIDARSIM_PIN_THREADS", "off")
    assert pool_cpus(2) is None


@pytest.mark.parametrize("value", ["on", "AUTO", "1", "0", "pin"])
def test_a_mistyped_setting_is_one_clear_error(monkeypatch: pytest.MonkeyPatch,
                                               value: str) -> None:
    monkeypatch.setenv("LIDARSIM_PIN_THREADS", value)
    with pytest.raises(ConfigError) as caught:
        pin_mode()
    message = str(caught.value)
    assert "LIDARSIM_PIN_THREADS" in message and "auto, off" in message
    assert "\n" not in message


@pytest.mark.parametrize("value", ["", "  ", "auto", "off"])
def test_accepted_settings(monkeypatch: pytest.MonkeyPatch, value: str) -> None:
    monkeypatch.setenv("LIDARSIM_PIN_THREADS", value)
    assert pin_mode() == (value.strip() or "auto")
