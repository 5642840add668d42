"""What ``lidarsim evaluate`` reads from a dataset directory: sequences, frames, truth, model.

Everything comes from the files ``lidarsim dataset`` writes (docs/datasets.md): the manifest
lists the sequences (with their split) and every frame file, each sequence's ``poses.json``
holds the true poses at frame start and end, and its normalised ``scenario.yaml`` names the
target's mesh, which is loaded by the simulation's own loader.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..base.config_io import read_text_file
from ..base.errors import ConfigError, UserInputError
from .base import TargetModelData


@dataclass
class FrameEntry:
    """One frame file of a sequence (``sha256``: its checksum in the manifest)."""

    frame: int
    path: Path
    points: int
    sha256: str | None = None


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
        check_poses(data, self.poses_path, [entry.frame for entry in self.frames])
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


#: How far from 1 the norm of a stored quaternion may be (they are written with 17 digits).
UNIT_TOLERANCE = 1e-6


def check_poses(data: dict[str, Any], path: Path, frames: list[int]) -> None:
    """Validate the truth of a sequence's ``poses.json`` for ``frames`` before anything is
    scored: every frame at its place, finite frame times with ``t_start_s <= t_end_s``, one
    record per target, finite positions and unit quaternions at frame start and end.

    Raises
    ------
    ConfigError
        Naming ``path`` and the field (``frames.3.targets.0.q_target_in_sensor``).
    """
    names = data.get("target_names")
    if not isinstance(names, list) or not names:
        raise ConfigError("lists no targets", source=path, field="target_names")
    records = data["frames"]
    for frame in frames:
        where = f"frames.{frame}"
        if not 0 <= frame < len(records) or not isinstance(records[frame], dict):
            raise ConfigError("the frame is missing", source=path, field=where)
        record = records[frame]
        if record.get("frame") != frame:
            raise ConfigError(f"frame {frame} is not at its place in the frame list",
                              source=path, field=where)
        times = [_number(record, key, path, where) for key in ("t_start_s", "t_end_s")]
        if times[1] < times[0]:
            raise ConfigError(f"the frame ends ({times[1]:g} s) before it starts "
                              f"({times[0]:g} s)", source=path, field=f"{where}.t_end_s")
        targets = record.get("targets")
        if not isinstance(targets, list) or len(targets) != len(names):
            raise ConfigError(f"holds {len(targets) if isinstance(targets, list) else 'no'} "
                              f"target records for {len(names)} targets", source=path,
                              field=f"{where}.targets")
        for i, target in enumerate(targets):
            at = f"{where}.targets.{i}"
            if not isinstance(target, dict):
                raise ConfigError("is not a mapping", source=path, field=at)
            for key in ("q_target_in_sensor", "q_target_in_sensor_end"):
                q = _vector(target, key, 4, path, at)
                if abs(float(np.linalg.norm(q)) - 1.0) > UNIT_TOLERANCE:
                    raise ConfigError(f"quaternion of norm {np.linalg.norm(q):.6g} is not a "
                                      "unit quaternion", source=path, field=f"{at}.{key}")
            for key in ("r_target_in_sensor_m", "r_target_in_sensor_end_m"):
                _vector(target, key, 3, path, at)


def _number(record: dict[str, Any], key: str, path: Path, where: str) -> float:
    value = record.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value):
        raise ConfigError(f"{value!r} is not a finite number", source=path,
                          field=f"{where}.{key}")
    return float(value)


def _vector(record: dict[str, Any], key: str, size: int, path: Path, where: str
            ) -> np.ndarray:
    value = record.get(key)
    if not isinstance(value, list) or len(value) != size or \
            any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
        raise ConfigError(f"is not a list of {size} numbers", source=path,
                          field=f"{where}.{key}")
    array = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(array)):
        raise ConfigError(f"holds a value that is not finite ({value})", source=path,
                          field=f"{where}.{key}")
    return array


def inside_dataset(root: Path, name: object, *, manifest: Path, field: str) -> Path:
    """``root / name`` for a file name read from the manifest, refused unless it stays inside
    the dataset: a relative path without ``..``, and, once symbolic links are resolved, still
    under ``root`` (a link out of the dataset is refused too).

    Raises
    ------
    ConfigError
        Naming the manifest and ``field``.
    """
    if not isinstance(name, str) or not name:
        raise ConfigError(f"{name!r} is not a file name", source=manifest, field=field)
    relative = Path(name)
    if relative.is_absolute() or ".." in relative.parts or "\0" in name:
        raise ConfigError(f"'{name}' is not a path inside the dataset (absolute paths and "
                          "'..' are refused)", source=manifest, field=field)
    path = root / relative
    try:
        resolved = path.resolve()
        base = root.resolve()
    except (OSError, RuntimeError) as exc:
        raise ConfigError(f"'{name}' cannot be resolved ({exc})", source=manifest,
                          field=field) from None
    if resolved != base and base not in resolved.parents:
        raise ConfigError(f"'{name}' is a symbolic link out of the dataset (to {resolved})",
                          source=manifest, field=field)
    return path


def verify_checksums(sequences: list["SequenceData"], manifest: Path) -> None:
    """Recompute every frame file's SHA-256 and compare it with the manifest's.

    Raises
    ------
    ConfigError
        Naming the frame file whose content differs from what the dataset wrote (a frame
        copied over another, a truncated or edited file) or that has no checksum.
    """
    from ..base.config_io import check_input_file
    from ..io.sidecar import sha256_file

    for seq in sequences:
        for entry in seq.frames:
            if not isinstance(entry.sha256, str):
                raise ConfigError("the manifest lists no sha256 for this frame (use "
                                  "--no-verify to skip the check)", source=entry.path,
                                  field="sha256")
            check_input_file(entry.path, "frame file", limit_name="data_bytes")
            if sha256_file(entry.path) != entry.sha256:
                raise ConfigError("the file's SHA-256 differs from the manifest's: it is not "
                                  "the frame the dataset wrote (edited, truncated or "
                                  "replaced; use --no-verify to skip the check)",
                                  source=entry.path, field="sha256")


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


def open_dataset(root: str | Path, split: str | None = None, *, verify: bool = True
                 ) -> tuple[list[SequenceData], str]:
    """The sequences of the dataset at ``root`` (those of ``split`` only, if given).

    Every file the manifest names must lie inside the dataset (no absolute path, no ``..``,
    no symbolic link out); with ``verify`` (the default) every frame file's SHA-256 is
    recomputed and compared with the manifest's before anything is evaluated.

    Returns
    -------
    sequences, fingerprint
        The sequences in manifest order, and a SHA-256 of the manifest that identifies the
        dataset's content (every frame's checksum is in it).

    Raises
    ------
    ConfigError
        Not a complete dataset, an unknown split, a split the dataset does not have, a file
        outside the dataset or (``verify``) a frame whose checksum differs.
    """
    import hashlib

    from ..dataset.config import SPLIT_NAMES
    from ..dataset.layout import MANIFEST

    root = Path(root)
    manifest = _manifest(root)
    fingerprint = hashlib.sha256((root / MANIFEST).read_bytes()).hexdigest()
    identity = manifest.get("identity")
    exporter = identity.get("exporter") if isinstance(identity, dict) else None
    if isinstance(exporter, dict) and exporter.get("name") == "mcap":
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
    listed = manifest.get("sequences") or []
    if not isinstance(listed, list):
        raise ConfigError("is not a list of sequences", source=root / MANIFEST,
                          field="sequences")
    for i, seq in enumerate(listed):
        try:
            if not isinstance(seq, dict):
                raise TypeError("not a mapping")
            if split is not None and seq.get("split") != split:
                continue
            manifest_path = root / MANIFEST
            at = f"sequences.{i}"
            seq_root = inside_dataset(root, seq["root"], manifest=manifest_path,
                                      field=f"{at}.root")
            frames = [FrameEntry(int(f["frame"]),
                                 inside_dataset(root, f["file"], manifest=manifest_path,
                                                field=f"{at}.frames.{j}.file"),
                                 int(f["points"]), f.get("sha256"))
                      for j, f in enumerate(seq["frames"])]
            poses = inside_dataset(root, str(Path(seq["root"]) / seq["poses"]),
                                   manifest=manifest_path, field=f"{at}.poses")
            scenario = inside_dataset(root, str(Path(seq["root"]) / seq["scenario"]),
                                      manifest=manifest_path, field=f"{at}.scenario")
            sequences.append(SequenceData(str(seq["name"]), seq_root, seq.get("split"), frames,
                                          poses, scenario))
        except (KeyError, TypeError, ValueError, AttributeError, OverflowError) as exc:
            raise ConfigError(f"malformed sequence entry ({type(exc).__name__}: {exc})",
                              source=root / MANIFEST, field=f"sequences.{i}") from None
    if not sequences:
        where = f"in split '{split}'" if split else "in the manifest"
        raise ConfigError(f"no sequences {where}", source=root, field="--split" if split else None)
    if verify:
        verify_checksums(sequences, root / MANIFEST)
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
    try:  # the bounded reader: a FIFO or a huge file in its place is not read
        return json.loads(read_text_file(path, "evaluation record"))
    except (UserInputError, json.JSONDecodeError, RecursionError):
        return None
