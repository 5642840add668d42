"""A frame's files written by one compiled call (io.filegroup, kernels.oswrite): the same
files as the usual path, the usual path's checks and errors for everything but a new target,
and real system-call failures met inside the compiled call end as the usual one-line error
with nothing left behind."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from lidarsim_core import kernels
from lidarsim_core.base import atomic
from lidarsim_core.base.errors import OutputError
from lidarsim_core.base.libc import file_functions
from lidarsim_core.io import filegroup
from lidarsim_core.io.filegroup import write_files_atomic

compiled = pytest.mark.skipif(file_functions() is None or not kernels.enabled(),
                              reason="the compiled writer needs numba on Linux x86-64/AArch64")


@pytest.fixture
def fallbacks(monkeypatch) -> list[Path]:
    """The paths written by the usual path (``write_bytes_atomic``) during the test."""
    seen: list[Path] = []
    real = filegroup.write_bytes_atomic

    def spy(path, data, *, overwrite=True):
        seen.append(Path(path))
        return real(path, data, overwrite=overwrite)

    monkeypatch.setattr(filegroup, "write_bytes_atomic", spy)
    return seen


def _entries(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir()}


@compiled
def test_new_files_are_written_by_the_compiled_call_with_the_usual_bytes_and_mode(
        tmp_path, fallbacks):
    data = bytes(range(256)) * 400  # 100 KiB, more than a pipe or a page
    write_files_atomic([(tmp_path / "a.ply", data), (tmp_path / "a.ply.json", b"{}\n")])
    assert fallbacks == []
    (tmp_path / "usual").mkdir()
    atomic.write_bytes_atomic(tmp_path / "usual" / "a.ply", data)
    assert (tmp_path / "a.ply").read_bytes() == data
    assert (tmp_path / "a.ply.json").read_bytes() == b"{}\n"
    assert _entries(tmp_path) == {"a.ply", "a.ply.json", "usual"}  # no '.part' left
    mode = stat.S_IMODE((tmp_path / "a.ply").stat().st_mode)
    assert mode == stat.S_IMODE((tmp_path / "usual" / "a.ply").stat().st_mode)


@compiled
def test_inside_deferred_sync_the_files_are_collected_for_the_block_sync(tmp_path, fallbacks):
    with atomic.deferred_sync([]) as written:
        write_files_atomic([(tmp_path / "a", b"1"), (tmp_path / "b", memoryview(b"22"))])
    assert written == [tmp_path / "a", tmp_path / "b"] and fallbacks == []


@compiled
def test_an_existing_target_goes_the_usual_way_from_that_file_on(tmp_path, fallbacks):
    (tmp_path / "b").write_bytes(b"old")
    write_files_atomic([(tmp_path / "a", b"new a"), (tmp_path / "b", b"new b"),
                        (tmp_path / "c", b"new c")])
    assert fallbacks == [tmp_path / "b", tmp_path / "c"]
    assert [(tmp_path / n).read_bytes() for n in "abc"] == [b"new a", b"new b", b"new c"]


@compiled
@pytest.mark.parametrize("kind", ["directory", "link to a directory"])
def test_a_directory_at_the_target_is_refused_as_before(tmp_path, kind):
    (tmp_path / "d").mkdir()
    target = tmp_path / "t"
    if kind == "directory":
        target.mkdir()
    else:
        target.symlink_to(tmp_path / "d")
    with pytest.raises(OutputError, match="output path is a directory"):
        write_files_atomic([(tmp_path / "first", b"1"), (target, b"2")])
    assert (tmp_path / "first").read_bytes() == b"1"  # written before, as one at a time
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".part")]


@compiled
def test_overwrite_flags_apply_per_file(tmp_path):
    (tmp_path / "side.json").write_bytes(b"old")
    write_files_atomic([(tmp_path / "f", b"1"), (tmp_path / "side.json", b"new")],
                       overwrite=(False, True))
    assert (tmp_path / "side.json").read_bytes() == b"new"
    with pytest.raises(OutputError, match="output file exists"):
        write_files_atomic([(tmp_path / "f", b"2")], overwrite=False)
    with pytest.raises(ValueError, match="one overwrite flag per file"):
        write_files_atomic([(tmp_path / "g", b"2")], overwrite=(True, True))


@compiled
def test_a_missing_directory_fails_in_the_call_and_ends_as_the_usual_error(tmp_path):
    import errno

    import numpy as np

    from lidarsim_core.base.libc import AT_FDCWD, AT_SYMLINK_NOFOLLOW
    from lidarsim_core.kernels.oswrite import write_files

    temporary, target = (os.fsencode(tmp_path / "no" / name) for name in (".x.part", "x"))
    names = np.frombuffer(temporary + b"\0" + target + b"\0", dtype=np.uint8)
    plan = np.array([1, atomic.PART_FLAGS, atomic.PART_MODE, AT_FDCWD, os.F_OK,
                     AT_SYMLINK_NOFOLLOW, errno.ENOENT, errno.EINTR,
                     1, 0, len(temporary) + 1, 0, 0], dtype=np.int64)
    assert write_files(file_functions(), names, plan) == (0, errno.ENOENT)
    with pytest.raises(OutputError, match="output directory does not exist"):
        write_files_atomic([(tmp_path / "no" / "x", b"1")])
    assert _entries(tmp_path) == set()


@compiled
def test_a_write_error_inside_the_call_removes_its_temporary_file_and_is_reported(tmp_path):
    """A real failure of ``write`` (a file-size limit: EFBIG) in the compiled call: its
    temporary file is removed and the usual path reports the same error, one line naming
    the file."""
    script = textwrap.dedent(f"""
        import resource, signal, sys
        from pathlib import Path
        from lidarsim_core.io import filegroup
        from lidarsim_core.base.errors import OutputError
        folder = Path({str(tmp_path)!r})
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (50000, 50000))
        assert filegroup._write_compiled([folder / "probe"], [b"1" * 60000]) == 0
        assert sorted(p.name for p in folder.iterdir()) == [], list(folder.iterdir())
        try:
            filegroup.write_files_atomic([(folder / "a.ply", b"1" * 60000)])
        except OutputError as exc:
            print(exc)
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith(f"{tmp_path / 'a.ply'}: cannot write: "), result.stdout
    assert result.stdout.endswith("cannot write: file too large\n"), result.stdout
    assert _entries(tmp_path) == set()


@compiled
def test_large_files_and_nul_names_take_the_usual_path(tmp_path, fallbacks):
    big = b"x" * (filegroup.COMPILED_BYTES + 1)
    write_files_atomic([(tmp_path / "big", big)])
    assert fallbacks == [tmp_path / "big"]
    assert filegroup._write_compiled([Path("a\0b")], [b"1"]) == 0


def test_without_the_compiled_call_the_files_are_the_same(tmp_path, monkeypatch):
    data = os.urandom(5000)
    write_files_atomic([(tmp_path / "a", data)])
    monkeypatch.setattr(filegroup, "_write_compiled", lambda paths, contents: 0)
    write_files_atomic([(tmp_path / "b", data)])
    assert (tmp_path / "a").read_bytes() == (tmp_path / "b").read_bytes() == data


@pytest.mark.parametrize("writer", ["write_bytes_atomic", "atomic_output"])
def test_an_interrupt_while_the_temporary_file_is_created_leaves_nothing(tmp_path, monkeypatch,
                                                                         writer):
    """Ctrl-C (or SIGTERM under the CLI) handled just after the temporary file is created,
    before its name reaches the writer: the name was known before the file existed, so the
    file is removed and the target never appears (a CI run of test_interrupts met this)."""
    real_open = os.open

    def open_then_interrupt(name, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        fd = real_open(name, *args, **kwargs)
        if str(name).endswith(".part"):
            os.close(fd)
            raise KeyboardInterrupt
        return fd

    monkeypatch.setattr(atomic.os, "open", open_then_interrupt)
    target = tmp_path / "frame.ply"
    with pytest.raises(KeyboardInterrupt):
        if writer == "write_bytes_atomic":
            atomic.write_bytes_atomic(target, b"x" * 100)
        else:
            with atomic.atomic_output(target) as stream:
                stream.write(b"x")
    monkeypatch.setattr(atomic.os, "open", real_open)
    assert sorted(p.name for p in tmp_path.iterdir()) == []
