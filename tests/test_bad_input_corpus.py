"""The bad-input corpus (tests/bad_inputs/cases.yaml) through the CLI and the Python API.

Every case must end with its documented exit status: 2 with exactly one line on stderr that
names the file and the field (and no traceback), leaving the directory exactly as it was, or
0 with a documented result (an empty cloud, a streamed one). Every case runs through the Typer
app in process and through the API; the representative subset marked ``subprocess: true``
also runs as a real ``python -m lidarsim_core`` process.
"""

from __future__ import annotations

import os
import stat
import sys
from collections import Counter
from pathlib import Path

import pytest
from bad_inputs.corpus import (
    Case,
    Outcome,
    build,
    load_cases,
    points_in,
    run_api,
    run_in_process,
    run_subprocess,
    snapshot,
)

CASES = load_cases()
API_CASES = [c for c in CASES if c.api != "none"]
SUBPROCESS_CASES = [c for c in CASES if c.subprocess]


def _ids(cases: list[Case]) -> list[str]:
    return [c.id for c in cases]


@pytest.fixture
def prepare(tmp_path, monkeypatch, fresh_registry):
    """Build a case in its own directory, enter it, and set its environment."""

    def _prepare(case: Case, *, in_process: bool = True) -> Path:
        work = build(case, tmp_path)
        monkeypatch.chdir(work)
        if in_process:
            for key, value in case.env.items():
                monkeypatch.setenv(key, value)
            if "LIDARSIM_PLUGINS" in case.env:
                monkeypatch.syspath_prepend(str(work))
            if case.spool_memory is not None:
                from lidarsim_core.cli import simulate as cli_simulate

                monkeypatch.setattr(cli_simulate, "SPOOL_MEMORY_BYTES", case.spool_memory)
        if not case.writable:
            _make_read_only(work / "locked", monkeypatch, inject=in_process)
        return work

    yield _prepare
    for name in [m for m in sys.modules if m.startswith("corpus_plugin_")]:
        del sys.modules[name]
    for path in tmp_path.rglob("*"):  # let pytest clean up read-only directories
        if path.is_dir():
            path.chmod(stat.S_IRWXU)


def _make_read_only(directory: Path, monkeypatch: pytest.MonkeyPatch, *, inject: bool) -> None:
    directory.chmod(stat.S_IRUSR | stat.S_IXUSR)
    if os.geteuid() != 0 or not inject:
        return
    # root ignores permissions: give the errors the kernel would give any other user
    real_access, real_open = os.access, os.open
    locked = directory.resolve()

    def access(path, mode, *args, **kwargs):
        if Path(path).resolve() == locked and mode & os.W_OK:
            return False
        return real_access(path, mode, *args, **kwargs)

    def open_(path, flags, *args, **kwargs):
        if flags & os.O_CREAT and Path(path).resolve().parent == locked:
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(path, flags, *args, **kwargs)

    monkeypatch.setattr(os, "access", access)
    monkeypatch.setattr(os, "open", open_)


def check_outcome(case: Case, outcome: Outcome, work: Path, before: dict) -> None:
    """The case's documented outcome, and nothing left behind on failure."""
    everything = outcome.stdout + outcome.stderr
    assert outcome.exit == case.exit, everything
    assert "Traceback" not in everything
    if case.exit != 0:
        assert len(outcome.error_lines) == 1, outcome.stderr
        line = outcome.error_lines[0]
        assert line.startswith("error: ")
        for fragment in case.fragments:
            assert fragment in line, f"{fragment!r} not in {line!r}"
        assert snapshot(work) == before, "a failed run changed the directory"
        return
    assert not outcome.error_lines, outcome.stderr
    for fragment in case.message:
        assert fragment in outcome.stdout, outcome.stdout
    after = snapshot(work)
    added = set(after) - set(before)
    assert added == {name for out in case.outputs for name in (out, f"{out}.json")}
    for out in case.outputs:
        count = points_in(work / out)
        assert count == 0 if case.result == "empty" else count > 0


@pytest.mark.parametrize("case", CASES, ids=_ids(CASES))
def test_cli(case, prepare, monkeypatch):
    work = prepare(case)
    before = snapshot(work)
    spilled: list[bool] = []
    if case.result == "streamed":
        from lidarsim_core.io.points import PointSpool

        close = PointSpool.close
        monkeypatch.setattr(PointSpool, "close",
                            lambda self: (spilled.append(self.spilled), close(self))[1])
    check_outcome(case, run_in_process(case), work, before)
    if case.result == "streamed":
        assert spilled == [True], "the frame did not stream through a temporary file"


@pytest.fixture(scope="module")
def subprocess_runs(tmp_path_factory) -> dict[str, tuple[Path, dict, Outcome]]:
    """Every ``subprocess: true`` case as a real process, a few at a time (they are
    independent; running them side by side keeps the corpus fast)."""
    from concurrent.futures import ThreadPoolExecutor

    root = tmp_path_factory.mktemp("subprocess")
    runnable = [c for c in SUBPROCESS_CASES if c.writable or os.geteuid() != 0]
    works = {c.id: build(c, root) for c in runnable}
    befores = {cid: snapshot(work) for cid, work in works.items()}
    with ThreadPoolExecutor(4) as pool:
        outcomes = dict(zip(works, pool.map(lambda c: run_subprocess(c, works[c.id]),
                                            runnable)))
    return {cid: (works[cid], befores[cid], outcomes[cid]) for cid in works}


@pytest.mark.parametrize("case", SUBPROCESS_CASES, ids=_ids(SUBPROCESS_CASES))
def test_cli_subprocess(case, subprocess_runs):
    if case.id not in subprocess_runs:
        pytest.skip("root ignores directory permissions")
    work, before, outcome = subprocess_runs[case.id]
    check_outcome(case, outcome, work, before)


@pytest.mark.parametrize("case", API_CASES, ids=_ids(API_CASES))
def test_api(case, prepare):
    from lidarsim_core.base.errors import PluginError, UserInputError

    work = prepare(case)
    before = snapshot(work)
    if case.exit == 0:
        result = run_api(case)
        sizes = [len(cloud) for cloud in result]
        assert all(n == 0 for n in sizes) if case.result == "empty" else all(sizes)
        return
    with pytest.raises((UserInputError, PluginError)) as info:
        run_api(case)
    message = str(info.value)
    assert "\n" not in message
    for fragment in case.fragments:
        if fragment.startswith("--"):
            continue  # command-line advice (e.g. '--overwrite') belongs to the CLI's words
        assert fragment in message, f"{fragment!r} not in {message!r}"
    assert snapshot(work) == before, "a failed call changed the directory"


def test_corpus_size_and_categories():
    """At least 40 cases; every category the issue names is present."""
    counts = Counter(c.category for c in CASES)
    assert len(CASES) >= 40
    assert {"malformed config", "wrong type", "unknown key", "out of range", "trajectory",
            "mesh", "geometry", "pattern file", "plugin", "duplicate name", "output path",
            "security", "streaming"} <= set(counts)
    assert len(SUBPROCESS_CASES) >= len(counts) - 2  # most categories also as a real process


def test_debug_shows_the_traceback(prepare):
    """``--debug`` lets the exception through instead of the one line."""
    from lidarsim_core.base.errors import ConfigError

    case = next(c for c in CASES if c.id == "zero-duration")
    prepare(case)
    debug = Case(**{**case.__dict__, "run": ["--debug", *case.run]})
    with pytest.raises(ConfigError, match="scan.duration_s"):
        run_in_process(debug)
