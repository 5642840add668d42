"""The one overwrite policy of every command and of the Python API.

* An existing file is never replaced unless the caller says so: ``--overwrite`` on the command
  line, ``overwrite=True`` in Python. The check runs for *every* output of a command before
  any work starts, so a refused run costs nothing and changes nothing.
* Files a command would not write are never touched, whatever the flag: ``--overwrite`` on a
  directory replaces only the files of the same names.
* Missing output directories are created (``mkdir -p``); when that is impossible the error
  says why (a file in the way, a folder that is not writable, a read-only file system).
* An output path that cannot work is refused before any work too, with its reason: a
  directory, a symbolic link (replaced only with the flag, even when dangling or looping), a
  NUL character, a name too long for the file system once lidarsim adds its temporary and
  sidecar suffixes.
* Every file is written atomically (temporary file, then rename): an interrupted or failed run
  leaves the previous file or none, never a partial one.
* ``lidarsim dataset`` is the one resumable command: its directory is continued, never
  replaced (see ``docs/datasets.md``).
"""

from __future__ import annotations

import os
import stat
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator

from .errors import OutputError

#: Characters an atomic write adds to a file name for its temporary file (``.NAME.RANDOM.part``)
#: and a sidecar adds (``NAME.json``): the longest name lidarsim creates from an output name.
NAME_OVERHEAD = len(".") + 12 + len("..part") + len(".json")

#: How to ask for replacement, on the command line and in Python.
CLI_HINT = "use --overwrite to replace"
API_HINT = "pass overwrite=True to replace"


def check_directory(directory: str | Path, *, source: str | Path | None = None) -> None:
    """Fail unless ``directory`` exists as a writable directory or can be created (the error
    names ``source``, default the directory)."""
    directory = Path(directory) if str(directory) else Path(".")
    where = source if source is not None else directory
    if directory.is_dir():
        if _read_only(directory):
            raise OutputError(f"output directory is on a read-only file system: {directory}",
                              source=where)
        if not os.access(directory, os.W_OK | os.X_OK):
            raise OutputError(f"output directory is not writable: {directory}", source=where)
        return
    probe = directory
    while not probe.exists() and probe != probe.parent and str(probe.parent):
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise OutputError(f"cannot create the output directory {directory}: {probe} is a file, "
                          "not a folder", source=where)
    if probe.exists() and not os.access(probe, os.W_OK | os.X_OK):
        raise OutputError(f"cannot create the output directory {directory}: {probe} is not "
                          "writable", source=where)


def check_file(path: str | Path, *, overwrite: bool, hint: str = CLI_HINT,
               what: str = "output file") -> None:
    """Fail if ``path`` may not be written (see the module docstring): a NUL character, a
    name too long, a directory, a path the system cannot follow (a link loop), an existing
    file or link without ``overwrite``, or a parent folder that cannot be created.

    Raises
    ------
    OutputError
        Naming ``path`` and the reason.
    """
    if "\0" in str(path):
        raise OutputError("the path contains a NUL character", source=repr(str(path)))
    path = Path(path)
    _check_name_length(path, what)
    try:
        is_dir = path.is_dir()
    except OSError as exc:  # ELOOP, ENAMETOOLONG in a parent, ...
        from .oserrors import describe_os_error

        raise OutputError(f"cannot use this path: {describe_os_error(exc)}",
                          source=path) from None
    if is_dir:
        raise OutputError("output path is a directory", source=path)
    if os.path.islink(path) and not overwrite:
        raise OutputError(f"output path is a symbolic link ({hint} it)", source=path)
    if os.path.lexists(path) and not overwrite:
        raise OutputError(f"{what} exists ({hint} it)", source=path)
    check_replaceable(path)  # a device or FIFO is never replaced, whatever the flag
    check_not_input(path)  # nor a file the command reads
    check_directory(path.parent, source=path)


def _check_name_length(path: Path, what: str) -> None:
    parent = path.parent if str(path.parent) else Path(".")
    try:
        name_max = os.pathconf(parent, "PC_NAME_MAX") if parent.is_dir() else 255
    except (OSError, ValueError):
        name_max = 255
    size = len(os.fsencode(path.name))
    if size + NAME_OVERHEAD > name_max:
        raise OutputError(f"file name too long: {size} bytes, and this file system allows "
                          f"{name_max - NAME_OVERHEAD} for an {what} (with its temporary and "
                          "sidecar names)", source=path)


def _read_only(directory: Path) -> bool:
    try:
        return bool(os.statvfs(directory).f_flag & os.ST_RDONLY)
    except (OSError, AttributeError):
        return False


def check_files(directory: str | Path, names: Iterable[str], *, overwrite: bool,
                hint: str = CLI_HINT) -> None:
    """Fail if the files ``names`` cannot all be written into ``directory``: it is not a
    directory, or, without ``overwrite``, some of them exist (all are named)."""
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise OutputError("--out must be a directory", source=directory)
    check_directory(directory)
    if overwrite or not directory.is_dir():
        return
    existing = [n for n in names if (directory / n).exists()]
    if existing:
        shown = ", ".join(existing[:6]) + (f", ... ({len(existing)} in all)"
                                           if len(existing) > 6 else "")
        raise OutputError(f"would replace existing files: {shown} ({hint} them; other files "
                          "are never touched)", source=directory)


def make_parent(path: str | Path) -> None:
    """Create the folder ``path`` goes into, with its parents (after :func:`check_file`)."""
    parent = Path(path).parent
    if str(parent):
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(f"cannot create the output directory {parent}: "
                              f"{exc.strerror or exc}", source=path) from None


# ---- outputs never replace inputs or non-files (issue 27) ----------------------------------
#: Files read by the running command, by identity ``(device, inode, ctime)`` → the path as
#: read; ``None`` while no command tracks its inputs (the Python API may rewrite a file it
#: read: ``ls.read(p).save(p, overwrite=True)`` is the caller's choice).
_INPUTS: dict[tuple[int, int, int], str] | None = None


@contextmanager
def tracking_inputs() -> Iterator[None]:
    """Record, while the body runs, every file the bounded reader opens as an input
    (:func:`note_input`), so that :func:`check_file` refuses to replace one of them, even
    with ``--overwrite``. The command line runs every command inside it."""
    global _INPUTS
    previous, _INPUTS = _INPUTS, {}
    try:
        yield
    finally:
        _INPUTS = previous


def note_input(path: str | Path, info: os.stat_result | None = None) -> None:
    """Remember ``path`` as an input of the running command (nothing outside
    :func:`tracking_inputs`)."""
    if _INPUTS is None:
        return
    try:
        info = info or os.stat(path)
    except OSError:
        return
    _INPUTS[(info.st_dev, info.st_ino, info.st_ctime_ns)] = str(path)


def check_not_input(path: str | Path) -> None:
    """Refuse an output ``path`` that is (or links to) a file the running command reads.

    Raises
    ------
    OutputError
        Naming the output and the input it would replace; ``--overwrite`` does not lift it.
    """
    if not _INPUTS:
        return
    try:
        info = os.stat(path)
    except (OSError, ValueError):
        return
    key = (info.st_dev, info.st_ino, info.st_ctime_ns)
    if key in _INPUTS:
        raise OutputError(f"output is an input of this command ({_INPUTS[key]}): lidarsim "
                          "never replaces a file it reads, even with --overwrite",
                          source=path)


def check_replaceable(path: str | Path) -> None:
    """Refuse to replace anything but a regular file (or a symbolic link, which is replaced
    itself, never followed): ``--overwrite`` onto a device, FIFO or socket would put a
    regular file where the node was.

    Raises
    ------
    OutputError
        Naming the path and what it is.
    """
    try:
        info = os.lstat(path)
    except (OSError, ValueError):
        return
    mode = info.st_mode
    if stat.S_ISREG(mode) or stat.S_ISLNK(mode):
        return
    kind = ("a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else
            "a named pipe (FIFO)" if stat.S_ISFIFO(mode) else
            "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
    raise OutputError(f"output path is {kind}: --overwrite replaces regular files only",
                      source=path)


def check_group(paths: Iterable[str | Path], *, overwrite: bool, hint: str = CLI_HINT) -> None:
    """Check every file of a multi-file output (OBJ + MTL, cloud + range image, cloud +
    sidecar) before any of them is written: all pass, or nothing is written.

    Raises
    ------
    OutputError
        For the first path that may not be written (see :func:`check_file`).
    """
    for path in paths:
        check_file(path, overwrite=overwrite, hint=hint)
