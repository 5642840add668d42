"""What ``lidarsim evaluate`` reads from a dataset directory: sequences, frames, truth, model.

Everything comes from the files ``lidarsim dataset`` writes (docs/datasets.md): the manifest
lists the sequences (with their split) and every frame file, each sequence's ``poses.json``
holds the true poses at frame start and end, and its normalised ``scenario.yaml`` names the
target's mesh, which is loaded by the simulation's own loader.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..base.errors import ConfigError
from .base import TargetModelData


@dataclass
class FrameEntry:
    """One frame file of a sequence."""

    frame: int
    path: Path
    points: int


@dataclass
class SequenceData:
    """One sequence of a dataset, as the evaluation needs it."""

    name: str
    root: Path
    split: str | None
    frames: list[FrameEntry]
    poses_path: Path
    scenario_path: Path
    _model_cache: dict[int, TargetModelData] = field(default_factory=dict, repr=False)

    @cached_property
    def poses(self) -> dict[str, Any]:
        """The sequence's ground-truth file."""
        from ..io.groundtruth import read_ground_truth

        data = read_ground_truth(self.poses_path)
        frames = data.get("frames")
        if not isinstance(frames, list) or len(frames) < len(self.frames):
            raise ConfigError("holds fewer frames than the manifest lists",
                              source=self.poses_path, field="frames")
        return data

    @property
    def target_names(self) -> list[str]:
        """Target names in scenario order."""
        return list(self.poses.get("target_names", []))

    def target_index(self, name: str | None) -> int:
        """Index of target ``name`` (``None``: the first target)."""
        names = self.target_names
        if not names:
            raise ConfigError("lists no targets", source=self.poses_path, field="target_names")
        if name is None:
            return 0
        if name not in names:
            raise ConfigError(f"sequence '{self.name}' has no target '{name}'; its targets: "
                              f"{', '.join(names)}", field="--target")
        return names.index(name)

    def model(self, index: int) -> TargetModelData:
        """The mesh of target ``index`` in its body frame, loaded as the simulation loads it."""
        if index not in self._model_cache:
            from ..plugins.manager import get_registry
            from ..plugins.resolve import target_mesh
            from ..scenario.load import load_scenario

            scenario = load_scenario(self.scenario_path)
            mesh = target_mesh(get_registry(), scenario, index)
            self._model_cache[index] = TargetModelData(scenario.targets[index].name, mesh)
        return self._model_cache[index]

    def truth(self, frame: int, target: int, time_s: float) -> tuple[np.ndarray, np.ndarray]:
        """True ``(q_xyzw, t_m)`` of the target in the sensor frame at ``time_s``.

        The poses file gives them at frame start and end; in between the attitude is
        interpolated by slerp and the position linearly (exact at either end; within a frame
        of 0.1 s of a body tumbling at a few degrees per second the second-order error is far
        below a micro-degree).
        """
        record = self.poses["frames"][frame]
        if record.get("frame") != frame:
            raise ConfigError(f"frame {frame} is not at its place in the frame list",
                              source=self.poses_path, field=f"frames.{frame}")
        tg = record["targets"][target]
        t0, t1 = float(record["t_start_s"]), float(record["t_end_s"])
        q0 = np.asarray(tg["q_target_in_sensor"], dtype=np.float64)
        r0 = np.asarray(tg["r_target_in_sensor_m"], dtype=np.float64)
        if time_s <= t0 or t1 <= t0:
            return q0, r0
        q1 = np.asarray(tg["q_target_in_sensor_end"], dtype=np.float64)
        r1 = np.asarray(tg["r_target_in_sensor_end_m"], dtype=np.float64)
        if time_s >= t1:
            return q1, r1
        s = (time_s - t0) / (t1 - t0)
        q = Slerp([0.0, 1.0], Rotation.from_quat([q0, q1]))([s]).as_quat()[0]
        return q, (1 - s) * r0 + s * r1

    @property
    def frozen(self) -> bool:
        """Whether the scene was frozen at frame start (``scan.motion: frozen``)."""
        return self.poses.get("motion") == "frozen"


def _manifest(root: Path) -> dict[str, Any]:
    from ..base.config_io import read_json_file
    from ..dataset.layout import MANIFEST
    from ..dataset.manifest import MANIFEST_FORMAT

    path = root / MANIFEST
    if not root.is_dir():
        raise ConfigError("dataset directory not found", source=root)
    if not path.is_file():
        raise ConfigError("not a lidarsim dataset (no manifest.json; make one with 'lidarsim "
                          "dataset')", source=root)
    data = read_json_file(path, "dataset manifest")
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT:
        raise ConfigError("not a lidarsim dataset manifest", source=path, field="format")
    if not data.get("complete"):
        raise ConfigError("the dataset is not complete: run the same 'lidarsim dataset' "
                          "command again to finish it", source=path, field="complete")
    return data


def open_dataset(root: str | Path, split: str | None = None) -> tuple[list[SequenceData], str]:
    """The sequences of the dataset at ``root`` (those of ``split`` only, if given).

    Returns
    -------
    sequences, fingerprint
        The sequences in manifest order, and a SHA-256 of the manifest that identifies the
        dataset's content (every frame's checksum is in it).

    Raises
    ------
    ConfigError
        Not a complete dataset, an unknown split, or a split the dataset does not have.
    """
    import hashlib

    from ..dataset.config import SPLIT_NAMES
    from ..dataset.layout import MANIFEST

    root = Path(root)
    manifest = _manifest(root)
    fingerprint = hashlib.sha256((root / MANIFEST).read_bytes()).hexdigest()
    if (manifest.get("identity") or {}).get("exporter", {}).get("name") == "mcap":
        raise ConfigError("this dataset holds ROS 2 bags (--format mcap); evaluate reads "
                          "datasets of frame files (e.g. --format npz)", source=root)
    if split is not None:
        if split not in SPLIT_NAMES:
            raise ConfigError(f"unknown split '{split}'; use one of {', '.join(SPLIT_NAMES)}",
                              field="--split")
        if manifest.get("splits") is None:
            raise ConfigError("this dataset has a single sequence and no splits; drop "
                              "--split", source=root, field="--split")
    sequences = []
    for i, seq in enumerate(manifest.get("sequences") or []):
        try:
            if split is not None and seq.get("split") != split:
                continue
            seq_root = root / seq["root"]
            frames = [FrameEntry(int(f["frame"]), root / f["file"], int(f["points"]))
                      for f in seq["frames"]]
            sequences.append(SequenceData(str(seq["name"]), seq_root, seq.get("split"), frames,
                                          seq_root / seq["poses"], seq_root / seq["scenario"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"malformed sequence entry ({type(exc).__name__}: {exc})",
                              source=root / MANIFEST, field=f"sequences.{i}") from None
    if not sequences:
        where = f"in split '{split}'" if split else "in the manifest"
        raise ConfigError(f"no sequences {where}", source=root, field="--split" if split else None)
    return sequences, fingerprint


# ---- frame files ---------------------------------------------------------------------------
def read_frame_columns(path: Path) -> dict[str, np.ndarray]:
    """The point record of one frame file, column name → array (every format lidarsim writes)."""
    from ..io.reader import read

    if not path.is_file():
        raise ConfigError("frame file not found (is the dataset complete?)", source=path)
    columns = read(path).columns
    missing = [c for c in ("x", "y", "z", "timestamp") if c not in columns]
    if missing:
        raise ConfigError(f"frame lacks columns {missing}", source=path)
    return dict(columns)  # already in the point record's dtypes


def frame_record_name(frame: int) -> str:
    """File name of one frame's evaluation record."""
    return f"frame_{frame:06d}.json"


def safe_name(name: str) -> str:
    """A sequence name usable as a directory name."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name) or "_"


def load_json(path: Path) -> Any:
    """Parse a JSON file, ``None`` when missing or unreadable."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
