"""The point cloud of one frame: the point record (DESIGN §5) as columns, plus frame metadata.

Columns (all arrays of equal length N; units in the table)
-------------------------------------------------------------
=====================  =======  ==============================================================
column                 dtype    meaning
=====================  =======  ==============================================================
x, y, z                f8       measured point, sensor frame at the ray's emission time (m)
x_true, y_true, z_true f8       noiseless point: true surface hit of the flown ray (m)
range                  f8       measured range (m)
range_true             f8       true range along the flown ray (m)
azimuth, elevation     f8       nominal emitted direction, sensor frame (rad)
timestamp              f8       emission time, seconds from the scenario epoch
return_number          u1       1-based return number
number_of_returns      u1       returns of this pulse
channel                i2       emitter / channel index
ray_index              i8       global index of the emitted pulse
face_index             i8       hit triangle of the target mesh
target                 i2       index into ``frame.target_names``
part                   i2       index into ``frame.part_names`` (scene-wide part labels)
incidence_angle        f8       angle between the ray and the surface normal (rad)
intensity              f4       apparent reflectivity of the return (0.2 for a 20 % Lambertian
                                target face-on; above 1 for glints, retro-reflectors); see
                                ``docs/realism.md``
detected               u1       1: reported by the sensor; 0: missed by the detection model,
                                kept only with ``sensor.detection.keep_undetected``
=====================  =======  ==============================================================

Optional columns, present only when the stage that writes them is on:

=====================  =======  ==============================================================
bounces                u1       specular bounces before the surface seen (0: direct return;
                                b > 0: a multipath ghost, whose ``x_true``... is the true
                                surface point the light came from; ``sensor.multipath``)
=====================  =======  ==============================================================

False alarms (noise model ``false_alarms``) have target -1, face -1, the scene's last part
(``<scene>/false_alarm``) and NaN ground truth (``x_true``..., ``range_true``,
``incidence_angle``). Kept undetected returns have ``return_number`` and
``number_of_returns`` 0.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: Column name → dtype of the point record, in file order.
POINT_FIELDS: dict[str, str] = {
    "x": "f8", "y": "f8", "z": "f8",
    "x_true": "f8", "y_true": "f8", "z_true": "f8",
    "range": "f8", "range_true": "f8",
    "azimuth": "f8", "elevation": "f8",
    "timestamp": "f8",
    "return_number": "u1", "number_of_returns": "u1",
    "channel": "i2", "ray_index": "i8", "face_index": "i8",
    "target": "i2", "part": "i2",
    "incidence_angle": "f8",
    "intensity": "f4", "detected": "u1",
}


@dataclass
class FrameInfo:
    """Metadata of one frame: who, when, where, and how to reproduce it.

    Poses are body→scene (``translation_m``, ``quaternion_xyzw`` scalar-last). ``targets_in_sensor``
    gives each target's pose in the sensor frame at frame start (the usual pose-estimation
    ground truth: ``x_sensor = R @ x_target_body + t``), ``targets_in_sensor_end`` the same at
    frame end.
    """

    frame: int
    t_start: float
    t_end: float
    sensor: str
    seed: int
    config_hash: str
    backend: str
    noise: list[str]
    motion: str
    target_names: list[str]
    part_names: list[str]
    rays_emitted: int
    sensor_pose_start: dict[str, list[float]]
    sensor_pose_end: dict[str, list[float]]
    target_poses_start: list[dict[str, list[float]]]
    target_poses_end: list[dict[str, list[float]]]
    targets_in_sensor: list[dict[str, list[float]]]
    software: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    targets_in_sensor_end: list[dict[str, list[float]]] = field(default_factory=list)

    def __repr__(self) -> str:
        return (f"FrameInfo(frame={self.frame}, t={self.t_start:g}–{self.t_end:g} s, "
                f"sensor={self.sensor!r}, targets={self.target_names!r}, "
                f"rays_emitted={self.rays_emitted:,}, seed={self.seed}, "
                f"backend={self.backend!r})")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return dict(self.__dict__)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "FrameInfo":
        """Inverse of :meth:`to_dict`."""
        return cls(**data)


@dataclass
class PointCloud:
    """Points of one frame with their ground truth (see module docstring for the columns).

    ``save(path)`` and ``range_image()`` are attached by :mod:`lidarsim_core.plugins.shortcuts`
    (they resolve exporters and scan patterns by name, which this data type never does).
    """

    columns: dict[str, np.ndarray]
    frame: FrameInfo

    def __post_init__(self) -> None:
        missing = set(POINT_FIELDS) - set(self.columns)
        if missing:
            raise ValueError(f"point cloud lacks columns {sorted(missing)}")
        lengths = {len(v) for v in self.columns.values()}
        if len(lengths) > 1:
            raise ValueError("point cloud columns differ in length")

    def __len__(self) -> int:
        return len(self.columns["x"])

    def __repr__(self) -> str:
        f = self.frame
        return (f"PointCloud({len(self):,} points from {f.rays_emitted:,} rays, frame {f.frame}, "
                f"t={f.t_start:g}–{f.t_end:g} s, sensor={f.sensor!r}, "
                f"targets={f.target_names!r}, {len(self.columns)} columns)")

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    @property
    def xyz(self) -> np.ndarray:
        """(N, 3) measured points, sensor frame (m)."""
        return np.column_stack([self.columns["x"], self.columns["y"], self.columns["z"]])

    @property
    def xyz_true(self) -> np.ndarray:
        """(N, 3) noiseless points, sensor frame (m)."""
        return np.column_stack([self.columns["x_true"], self.columns["y_true"],
                                self.columns["z_true"]])

    def part_labels(self) -> np.ndarray:
        """(N,) part names of the points (object array)."""
        names = np.asarray(self.frame.part_names, dtype=object)
        return names[self.columns["part"]] if len(self) else names[:0]

    def to_structured(self) -> np.ndarray:
        """A NumPy structured array with one field per column, in :data:`POINT_FIELDS` order."""
        out = np.empty(len(self), dtype=[(k, v) for k, v in POINT_FIELDS.items()])
        for key in POINT_FIELDS:
            out[key] = self.columns[key]
        return out

    @classmethod
    def empty(cls, frame: FrameInfo) -> "PointCloud":
        """A cloud with no points."""
        return cls({k: np.empty(0, dtype=v) for k, v in POINT_FIELDS.items()}, frame)

    @classmethod
    def concatenate(cls, parts: list[dict[str, np.ndarray]], frame: FrameInfo) -> "PointCloud":
        """Join per-chunk column dictionaries into one cloud.

        The cloud takes the parts' arrays over: a single part's column that already has its
        dtype, is C-contiguous, writeable and shares no memory with another column is used
        as it is, not copied (the simulation's pieces are; the values are the same either
        way). Every other column is a new array.
        """
        if not parts:
            return cls.empty(frame)
        if len(parts) == 1:
            return cls(_taken_over(parts[0]), frame)
        columns = {k: np.concatenate([p[k] for p in parts]).astype(v, copy=False)
                   for k, v in POINT_FIELDS.items()}
        # optional columns every chunk has (multipath's ``bounces``, ``x_body``...), in order
        columns.update({k: np.concatenate([p[k] for p in parts]) for k in parts[0]
                        if k not in POINT_FIELDS and all(k in p for p in parts)})
        return cls(columns, frame)

    def metadata_json(self) -> str:
        """The frame metadata as a compact JSON string."""
        return json.dumps(self.frame.to_dict(), sort_keys=True, separators=(",", ":"))

    def summary(self) -> dict[str, Any]:
        """Counts and extents, for reports and the CLI."""
        n = len(self)
        out: dict[str, Any] = {"points": n, "rays_emitted": self.frame.rays_emitted,
                               "hit_fraction": n / self.frame.rays_emitted
                               if self.frame.rays_emitted else 0.0}
        if n:
            rng = self.columns["range_true"]
            out.update(range_min_m=float(rng.min()), range_max_m=float(rng.max()))
            labels, counts = np.unique(self.columns["part"], return_counts=True)
            out["points_per_part"] = {self.frame.part_names[i]: int(c)
                                      for i, c in zip(labels, counts)}
        return out


def _taken_over(part: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The columns of one part as :meth:`PointCloud.concatenate` joins them: the point
    record's columns in :data:`POINT_FIELDS` order with their dtypes, then the optional ones;
    an array is kept when it is usable as it is (its dtype, C-contiguous, writeable, alone in
    its memory), else copied."""
    columns: dict[str, np.ndarray] = {}
    spans: list[tuple[int, int, str]] = []  # memory of the arrays kept as they are
    for key in (*POINT_FIELDS, *(k for k in part if k not in POINT_FIELDS)):
        array = np.asarray(part[key])
        dtype = _DTYPES.get(key, array.dtype)
        if array.dtype == dtype and array.ndim == 1 and array.flags.c_contiguous \
                and array.flags.writeable:
            columns[key] = array
            if array.nbytes:
                start = array.__array_interface__["data"][0]
                spans.append((start, start + array.nbytes, key))
        else:
            columns[key] = np.array(array, dtype=dtype, order="C")
    # two arrays sharing memory (the same array twice, overlapping views): all but one copied
    spans.sort()
    end = 0
    for start, stop, key in spans:
        if start < end:
            columns[key] = columns[key].copy()
        else:
            end = stop
    return columns


_DTYPES = {key: np.dtype(code) for key, code in POINT_FIELDS.items()}
