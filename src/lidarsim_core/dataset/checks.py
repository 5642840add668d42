"""Checks before a dataset run creates anything: the output folder, the sequences, and what a
rerun may resume; a refusal removes what this run created and names the file and field."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any, Callable

import yaml

from ..base.config_io import read_text_file
from ..base.errors import OutputError, UserInputError
from .config import DatasetPlan
from .identity import (
    differences,
)
from .inputs import INPUTS_DIR
from .layout import (
    DATASET_COPY,
    LOCK,
    SCENARIO_COPY,
)
from .sequence import SequenceRun


def check_directory(root: Path, manifest: dict[str, Any] | None) -> None:
    if manifest is not None:
        return
    # a run killed before its first manifest leaves only these; anything else is not ours
    ours = {LOCK, INPUTS_DIR, SCENARIO_COPY, DATASET_COPY, "sequences"}
    foreign = [p.name for p in root.iterdir()
               if p.name not in ours and not (p.name.startswith(".") and p.name.endswith(".part"))]
    if foreign:
        raise OutputError(f"directory is not empty and holds no lidarsim dataset "
                          f"({', '.join(sorted(foreign)[:3])}...); choose an empty or new "
                          "--out directory", source=root)


def check_dataset_dir(root: Path) -> None:
    """Refuse an output directory that cannot be a dataset before anything is created: a
    file, a name too long, or a place (the directory, or its nearest existing parent) that
    is read-only or not writable."""
    from ..base.oserrors import describe_os_error

    try:
        if root.exists() and not root.is_dir():
            raise OutputError("--out must be a directory", source=root)
        place = root
        while not place.exists():
            place = place.parent
    except OSError as exc:
        raise OutputError(f"cannot use this directory: {describe_os_error(exc)}",
                          source=root) from None
    if not place.is_dir():
        raise OutputError(f"a parent of the directory is a file: {place}", source=root)
    try:
        name_max = os.pathconf(place, "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    for part in root.relative_to(place).parts if place != root else ():
        if len(os.fsencode(part)) > name_max:
            raise OutputError(f"directory name too long: {len(os.fsencode(part))} bytes, and "
                              f"this file system allows {name_max}", source=root)
    try:
        read_only = bool(os.statvfs(place).f_flag & os.ST_RDONLY)
    except (OSError, AttributeError):
        read_only = False
    if read_only:
        raise OutputError(f"{place} is on a read-only file system", source=root)
    if not os.access(place, os.W_OK | os.X_OK):
        raise OutputError(f"{place} is not writable", source=root)


def validate_sequences(plan: DatasetPlan) -> None:
    """Build every sequence's simulation from the user's files (meshes, datasheets,
    trajectories, the resource budget) before the dataset directory is touched.

    Sequences that differ only by seed share one check.
    """
    from ..pipeline.simulation import Simulation

    seen: set[str] = set()
    for seq in plan.sequences:
        data = seq.scenario.model_dump(mode="json")
        data.pop("seed", None)
        key = f"{seq.scenario.source}|{json.dumps(data, sort_keys=True)}"
        if key in seen:
            continue
        seen.add(key)
        Simulation(seq.scenario)


def remove_created(root: Path, before: set[str]) -> None:
    """Delete what a failed first run created in ``root`` (everything not in ``before``,
    except the lock, which its holder removes)."""
    for name in set(os.listdir(root)) - before - {LOCK}:
        path = root / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)


def refuse(root: Path, lines: list[str]) -> None:
    shown = "; ".join(lines[:6]) + (f"; and {len(lines) - 6} more" if len(lines) > 6 else "")
    raise OutputError(f"holds a dataset made differently ({shown}); use another --out "
                      "directory, or delete this one to start over", source=root)


def old_scenario(path: Path) -> dict[str, Any] | None:
    try:  # the bounded reader: a FIFO or a huge file in its place is not read
        return yaml.safe_load(read_text_file(path, "dataset scenario"))
    except (UserInputError, yaml.YAMLError, RecursionError):
        return None


def scenario_differences(root: Path, sequences: list[SequenceRun], manifest: dict[str, Any],
                         old_of: Callable[[SequenceRun], dict[str, Any] | None] | None = None
                         ) -> list[str]:
    """What differs between the sequences of this run and those of the dataset in ``root``:
    their names, then each one's scenario against the copy the dataset kept (``old_of`` reads
    that copy; by default the sequence folder's ``scenario.yaml``)."""
    old_names = [s["name"] for s in manifest.get("identity", {}).get("sequences", [])]
    new_names = [s.plan.name for s in sequences]
    if old_names != new_names:
        return [f"sequences: {old_names} → {new_names}"]
    lines = []
    for seq in sequences:
        old = old_of(seq) if old_of is not None else old_scenario(seq.copy_path)
        prefix = "" if len(sequences) == 1 else f"{seq.plan.name}: "
        lines += [prefix + line for line in differences(old, seq.data)]
    return lines
