"""Copy a scenario's input files into the dataset, so the dataset is self-contained.

Mesh files (``targets[*].mesh.path``) and trajectory files (a ``file`` option of any
trajectory, e.g. keyframes) are copied to ``DIR/inputs/<sha256[:12]>-<name>`` and the
scenario copy points there with a path relative to itself. The dataset directory can then be
moved or archived and still regenerates every frame bit for bit:
``lidarsim simulate DIR/scenario.yaml --frame 7 --out f.ply`` writes the same bytes as
``DIR/frames/frame_000007.ply``. Content-addressed names make reruns find the same files.
Scan-pattern table files are resolved against the working directory (see
:mod:`lidarsim_core.patterns.table`) and are not copied.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

from ..base.atomic import atomic_output
from ..base.errors import ConfigError
from ..io.sidecar import sha256_file
from ..scenario.model import Scenario

INPUTS_DIR = "inputs"


class InputCopier:
    """Copies input files into ``root/inputs`` and remembers which ones it created.

    Parameters
    ----------
    root
        The dataset directory.
    """

    def __init__(self, root: Path) -> None:
        self.root = root
        self.created: list[Path] = []

    def copy(self, path: Path, *, source: str, field: str) -> Path:
        """Copy ``path`` (if not there yet) and return the copy's path."""
        if not path.is_file():
            raise ConfigError(f"file not found: {path}", source=source, field=field)
        digest = sha256_file(path)[:12]
        inputs = (self.root / INPUTS_DIR).resolve()
        if path.resolve().parent == inputs and path.name.startswith(f"{digest}-"):
            return path.resolve()  # already this dataset's copy (a rerun from DIR/scenario.yaml)
        target = self.root / INPUTS_DIR / f"{digest}-{path.name}"
        if not target.is_file():
            target.parent.mkdir(exist_ok=True)
            with open(path, "rb") as src, atomic_output(target) as dst:
                shutil.copyfileobj(src, dst)
            self.created.append(target)
        return target

    def forget_created(self) -> None:
        """Delete the files this copier created (when the run is refused)."""
        for path in self.created:
            path.unlink(missing_ok=True)
        self.created.clear()

    def localize(self, scenario: Scenario, data: dict[str, Any], copy_dir: Path) -> None:
        """Rewrite the file paths of the scenario dump ``data`` to copies in ``inputs/``,
        relative to ``copy_dir`` (where the scenario copy will be written)."""
        src = scenario.source
        for i, target in enumerate(scenario.targets):
            if target.mesh.path is not None:
                copied = self.copy(scenario.resolve(target.mesh.path), source=src,
                                   field=f"targets.{i}.mesh.path")
                data["targets"][i]["mesh"]["path"] = _relative(copied, copy_dir)
        posed = [("sensor", data["sensor"])] + [(f"targets.{i}", t)
                                                for i, t in enumerate(data["targets"])]
        for field, entry in posed:
            trajectory = entry.get("trajectory")
            if isinstance(trajectory, dict) and isinstance(trajectory.get("file"), str):
                copied = self.copy(scenario.resolve(Path(trajectory["file"])), source=src,
                                   field=f"{field}.trajectory.file")
                trajectory["file"] = _relative(copied, copy_dir)


def _relative(path: Path, start: Path) -> str:
    return Path(os.path.relpath(path, start)).as_posix()
