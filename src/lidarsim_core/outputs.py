"""The one overwrite policy of every command and of the Python API.

* An existing file is never replaced unless the caller says so: ``--overwrite`` on the command
  line, ``overwrite=True`` in Python. The check runs for *every* output of a command before
  any work starts, so a refused run costs nothing and changes nothing.
* Files a command would not write are never touched, whatever the flag: ``--overwrite`` on a
  directory replaces only the files of the same names.
* Missing output directories are created (``mkdir -p``); when that is impossible the error
  says why (a file in the way, a folder that is not writable).
* Every file is written atomically (temporary file, then rename): an interrupted or failed run
  leaves the previous file or none, never a partial one.
* ``lidarsim dataset`` is the one resumable command: its directory is continued, never
  replaced (see ``docs/datasets.md``).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable

from .errors import OutputError

#: How to ask for replacement, on the command line and in Python.
CLI_HINT = "use --overwrite to replace"
API_HINT = "pass overwrite=True to replace"


def check_directory(directory: str | Path, *, source: str | Path | None = None) -> None:
    """Fail unless ``directory`` exists as a writable directory or can be created (the error
    names ``source``, default the directory)."""
    directory = Path(directory) if str(directory) else Path(".")
    where = source if source is not None else directory
    if directory.is_dir():
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


def check_file(path: str | Path, *, overwrite: bool, hint: str = CLI_HINT) -> None:
    """Fail if ``path`` may not be written: a directory, an existing file without
    ``overwrite``, or a parent folder that cannot be created."""
    path = Path(path)
    if path.is_dir():
        raise OutputError("output path is a directory", source=path)
    if path.exists() and not overwrite:
        raise OutputError(f"output file exists ({hint} it)", source=path)
    check_directory(path.parent, source=path)


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
