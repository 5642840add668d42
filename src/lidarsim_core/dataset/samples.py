"""Training samples: what one frame becomes in a sharded dataset (``format: shards``).

The dataset file's ``samples:`` section chooses the products::

    samples:
      points: 2048            # fixed N: every sample has exactly N points
      sampling: uniform       # or farthest (farthest-point sampling)
      labels: true            # per-point part, target, return number, ghost, false alarm
      body_frame: true        # per-point body-frame correspondence (x_body, y_body, z_body)
      range_image: false      # organised image + label images + intrinsics (spinning,
                              # flash and raster sensors)
      shard_frames: 1000      # frames per shard file

Arrays of a sample (keys of the reader's dicts; N = ``points``)
-----------------------------------------------------------------
==================  =========  ===============================================================
key                 dtype      meaning
==================  =========  ===============================================================
points              f8 (N,3)   measured points, sensor frame (m), zero where ``mask`` is 0
mask                u1 (N,)    1: a real point, 0: padding (the frame had fewer than N)
index               i8 (N,)    row of each point in the frame's full point list (the order
                               of ``ls.read`` on the frame's file), -1 for padding
part, target        i2 (N,)    labels (``part_names`` / ``target_names`` in ``meta``), -1
                               for padding; false alarms have target -1
return_number       u1 (N,)    1-based return number, 0 for padding
ghost               u1 (N,)    1: a multipath ghost (``bounces`` > 0)
false_alarm         u1 (N,)    1: a false alarm (no target)
body                f8 (N,3)   the noiseless point in its target's body frame (NaN for
                               false alarms and padding)
pose_quaternion     f8 (T,4)   each target's rotation body → sensor, ``[x, y, z, w]``,
                               ``w >= 0``, at the frame's start time ``t_start``
pose_translation    f8 (T,3)   each target's origin in the sensor frame at ``t_start`` (m)
range_image         f8 (H,W)   first detected return per pixel (m), NaN for none
range_part          i2 (H,W)   part label image, -1 for none
range_target        i2 (H,W)   target label image, -1 for none
range_index         i8 (H,W)   row of the pixel's point in the frame's point list, -1
range_azimuth       f8 (H,W)   intrinsics: nominal azimuth of every pixel's ray (rad)
range_elevation     f8 (H,W)   intrinsics: nominal elevation of every pixel's ray (rad)
==================  =========  ===============================================================

The pose is the one ``poses.json`` gives as ``q_target_in_sensor`` / ``r_target_in_sensor_m``
(frame start). ``meta`` (a JSON member) holds the sequence, frame, split, ``t_start``,
``t_end``, sensor, target and part names, point count before sampling and the range image's
layout.

Which points are kept is a pure function of the sequence's seed and the frame index
(Philox keyed by both), so samples are the same on every run and worker.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.spatial.transform import Rotation

from ..io.rangeimage import range_image
from ..records.pointcloud import PointCloud

#: Default frames per shard file.
SHARD_FRAMES = 1000


class SampleSettings(BaseModel):
    """The ``samples:`` section of a dataset file (see the module docstring)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    points: int = Field(ge=1, le=10_000_000, description="N: points of every sample.")
    sampling: Literal["uniform", "farthest"] = Field(
        "uniform", description="'uniform': N distinct points at random; 'farthest': "
                               "farthest-point sampling from a random first point.")
    labels: bool = Field(True, description="Per-point labels.")
    body_frame: bool = Field(False, description="Per-point body-frame correspondences.")
    range_image: bool = Field(False, description="Range and label images with intrinsics.")
    shard_frames: int = Field(SHARD_FRAMES, ge=1, le=100_000,
                              description="Frames per shard file.")


def sampling_rng(seed: int, frame: int) -> np.random.Generator:
    """The stream that picks the points of ``frame`` of a sequence with noise seed ``seed``."""
    return np.random.Generator(np.random.Philox(key=[seed % 2 ** 64, frame]))


def farthest_point_indices(xyz: np.ndarray, n: int, first: int) -> np.ndarray:
    """Indices of ``n`` points of ``xyz`` chosen by farthest-point sampling from ``first``.

    Each next point is the one farthest (Euclidean) from all chosen so far; ties go to the
    lowest index. ``n`` must not exceed ``len(xyz)``.
    """
    chosen = np.empty(n, dtype=np.int64)
    chosen[0] = first
    dist = np.sum((xyz - xyz[first]) ** 2, axis=1)
    for i in range(1, n):
        nxt = int(np.argmax(dist))
        chosen[i] = nxt
        np.minimum(dist, np.sum((xyz - xyz[nxt]) ** 2, axis=1), out=dist)
    return chosen


def choose_points(xyz: np.ndarray, settings: SampleSettings, rng: np.random.Generator
                  ) -> np.ndarray:
    """Rows of the kept points: all of them (in order) if there are at most N, else N."""
    count, n = len(xyz), settings.points
    if count <= n:
        return np.arange(count, dtype=np.int64)
    if settings.sampling == "uniform":
        return np.sort(rng.choice(count, size=n, replace=False)).astype(np.int64)
    return farthest_point_indices(xyz, n, int(rng.integers(count)))


def _pad(values: np.ndarray, n: int, fill: Any) -> np.ndarray:
    out = np.full((n, *values.shape[1:]), fill, dtype=values.dtype)
    out[:len(values)] = values
    return out


def target_poses(cloud: PointCloud) -> tuple[np.ndarray, np.ndarray]:
    """Each target's quaternion ``[x, y, z, w]`` (``w >= 0``) and translation in the sensor
    frame at the frame's start (``FrameInfo.targets_in_sensor``)."""
    poses = cloud.frame.targets_in_sensor
    if not poses:
        return np.empty((0, 4)), np.empty((0, 3))
    quat = Rotation.from_quat([p["quaternion_xyzw"] for p in poses]).as_quat(canonical=True)
    return quat + 0.0, np.array([p["translation_m"] for p in poses], dtype=np.float64)


def range_products(cloud: PointCloud, pattern: Any) -> dict[str, np.ndarray]:
    """The range image of ``cloud``, its label images and its intrinsics (per-pixel nominal
    azimuth and elevation of the pattern's rays for this frame)."""
    image = range_image(cloud, pattern)
    out = {"range_image": image.range,
           "range_part": image.part.astype(np.int16),
           "range_index": image.point_index}
    target = np.full(image.shape, -1, dtype=np.int16)
    hit = image.point_index >= 0
    target[hit] = cloud["target"][image.point_index[hit]]
    out["range_target"] = target
    # intrinsics: an image of every ray of the frame, each as if it had returned
    k0, k1 = pattern.index_range(cloud.frame.t_start, cloud.frame.t_end)
    rays = np.arange(k0, k1, dtype=np.int64)
    direction = pattern.rays_for_indices(rays).direction
    azimuth = np.arctan2(direction[:, 1], direction[:, 0])
    elevation = np.arctan2(direction[:, 2], np.hypot(direction[:, 0], direction[:, 1]))
    count = len(rays)
    columns = {name: np.zeros(count, dtype=np.dtype(cloud[name].dtype))
               for name in cloud.columns}
    columns.update(ray_index=rays, azimuth=azimuth, elevation=elevation,
                   detected=np.ones(count, dtype=np.uint8),
                   return_number=np.ones(count, dtype=np.uint8))
    every = range_image(PointCloud(columns, cloud.frame), pattern).point_index
    az = np.full(image.shape, np.nan)
    el = np.full(image.shape, np.nan)
    filled = every >= 0
    az[filled] = azimuth[every[filled]]
    el[filled] = elevation[every[filled]]
    out["range_azimuth"] = az
    out["range_elevation"] = el
    return out


def make_sample(cloud: PointCloud, settings: SampleSettings, seed: int,
                pattern: Any = None) -> dict[str, np.ndarray]:
    """The arrays of one frame's sample (see the module docstring).

    Parameters
    ----------
    cloud
        The frame's full point cloud (detected and kept-undetected returns alike).
    settings
        The dataset's ``samples:`` section.
    seed
        The sequence's noise seed (with the frame index, it keys the point choice).
    pattern
        The simulation's scan pattern (needed for range images).
    """
    n = settings.points
    xyz = cloud.xyz
    rows = choose_points(xyz, settings, sampling_rng(seed, cloud.frame.frame))
    out: dict[str, np.ndarray] = {
        "points": _pad(xyz[rows], n, 0.0),
        "mask": _pad(np.ones(len(rows), dtype=np.uint8), n, 0),
        "index": _pad(rows, n, -1),
    }
    if settings.labels:
        target = cloud["target"][rows].astype(np.int16)
        out["part"] = _pad(cloud["part"][rows].astype(np.int16), n, -1)
        out["target"] = _pad(target, n, -1)
        out["return_number"] = _pad(cloud["return_number"][rows].astype(np.uint8), n, 0)
        bounces = cloud.columns.get("bounces")
        ghost = (bounces[rows] > 0) if bounces is not None else np.zeros(len(rows), dtype=bool)
        out["ghost"] = _pad(ghost.astype(np.uint8), n, 0)
        out["false_alarm"] = _pad((target < 0).astype(np.uint8), n, 0)
    if settings.body_frame:
        body = np.column_stack([cloud["x_body"], cloud["y_body"], cloud["z_body"]])[rows]
        out["body"] = _pad(body, n, np.nan)
    quat, trans = target_poses(cloud)
    out["pose_quaternion"] = quat
    out["pose_translation"] = trans
    if settings.range_image:
        out.update(range_products(cloud, pattern))
    return out


def sample_meta(cloud: PointCloud, *, sequence: str, split: str | None,
                settings: SampleSettings, layout: str | None) -> dict[str, Any]:
    """The JSON metadata of a sample."""
    info = cloud.frame
    return {"sequence": sequence, "frame": info.frame, "split": split,
            "t_start": info.t_start, "t_end": info.t_end, "sensor": info.sensor,
            "seed": info.seed, "target_names": list(info.target_names),
            "part_names": list(info.part_names), "points_in_frame": len(cloud),
            "points": settings.points, "range_image_layout": layout,
            "pose_time": "t_start"}
