"""Ground-truth pose files for a sequence of frames (one JSON or CSV file per sequence).

Pose convention
---------------
``q_A_in_B`` (unit quaternion, **scalar-last** ``[x, y, z, w]``, Hamilton, as SciPy) and
``r_A_in_B_m`` (metres) give frame A's pose in frame B::

    x_B = R(q_A_in_B) · x_A + r_A_in_B_m

so ``r_A_in_B_m`` is A's origin expressed in B's axes and ``R`` turns A-frame coordinates into
B-frame coordinates. The pose-estimation ground truth is ``q_target_in_sensor`` /
``r_target_in_sensor_m``: the target body frame (its mesh coordinates) in the sensor frame
(+X boresight, +Y left, +Z up). Transforming the target mesh by it gives the noiseless points
of that frame (exactly at frame start; with ``scan.motion: per_ray`` each point belongs to the
pose at its own ``timestamp``, which lies between the frame-start and frame-end poses). Names
follow the style of ESA's SPEED data set (``q_…``, ``r_…``), but SPEED stores quaternions
scalar-first: convert with ``[w, x, y, z] = [q[3], q[0], q[1], q[2]]``.

``*_in_scene`` poses are the sensor's and targets' poses in the scenario's scene frame (the
LVLH frame for orbital scenarios). Keys without ``_end`` are at frame start ``t_start_s``, keys
with ``_end`` at frame end ``t_end_s`` (seconds from the scenario epoch).

JSON layout::

    {"format": "lidarsim-poses", "version": 1, "convention": "...", "sensor": ..., "seed": ...,
     "config_hash": ..., "motion": "per_ray", "target_names": [...],
     "frames": [{"frame": 0, "t_start_s": 0.0, "t_end_s": 0.1, "cloud": "cloud_0000.ply",
                 "q_sensor_in_scene": [...], "r_sensor_in_scene_m": [...], (+ _end),
                 "targets": [{"name": "envisat",
                              "q_target_in_sensor": [...], "r_target_in_sensor_m": [...],
                              "q_target_in_scene": [...], "r_target_in_scene_m": [...],
                              (+ the same four with _end)}]}]}

CSV layout: one row per frame and target, columns ``frame, t_start_s, t_end_s, cloud, target``
then each quaternion as ``<name>_x, _y, _z, _w`` and each translation as ``<name>_x_m, _y_m,
_z_m`` (e.g. ``q_target_in_sensor_w``, ``r_target_in_sensor_x_m``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from ..geometry.poses import Poses

if TYPE_CHECKING:  # pragma: no cover
    from .pointcloud import FrameInfo


FORMAT_NAME = "lidarsim-poses"


FORMAT_VERSION = 1


CONVENTION = ("x_B = R(q_A_in_B) * x_A + r_A_in_B_m; quaternions scalar-last [x, y, z, w] "
              "(Hamilton); sensor frame +X boresight, +Y left, +Z up; keys without _end at "
              "t_start_s, with _end at t_end_s (s from the scenario epoch)")


QUATERNION_FIELDS = ("q_target_in_sensor", "q_target_in_scene", "q_sensor_in_scene")


def _pair(record: dict[str, list[float]], what: str, end: bool) -> dict[str, list[float]]:
    suffix = "_end" if end else ""
    # the sign of a quaternion is free: write the one with w >= 0
    quat = Rotation.from_quat(record["quaternion_xyzw"]).as_quat(canonical=True) + 0.0
    return {f"q_{what}{suffix}": quat.tolist(),
            f"r_{what}{suffix}_m": list(record["translation_m"])}


def frame_record(info: "FrameInfo", cloud: str | None = None) -> dict[str, Any]:
    """The ground truth of one frame as a JSON-ready dictionary (see the module docstring)."""
    out: dict[str, Any] = {"frame": info.frame, "t_start_s": info.t_start,
                           "t_end_s": info.t_end, "cloud": cloud}
    out.update(_pair(info.sensor_pose_start, "sensor_in_scene", False))
    out.update(_pair(info.sensor_pose_end, "sensor_in_scene", True))
    sensor = [_poses(info.sensor_pose_start), _poses(info.sensor_pose_end)]
    targets = []
    for j, name in enumerate(info.target_names):
        rec: dict[str, Any] = {"name": name}
        for end, scene in ((False, info.target_poses_start[j]), (True, info.target_poses_end[j])):
            # recomputed from the scene poses so files from older metadata are complete too
            in_sensor = _poses(scene).relative_to(sensor[int(end)]).to_records()[0]
            rec.update(_pair(in_sensor, "target_in_sensor", end))
            rec.update(_pair(scene, "target_in_scene", end))
        targets.append(rec)
    out["targets"] = targets
    return out


def frame_records(infos: Sequence["FrameInfo"], clouds: Sequence[str | None]
                  ) -> list[dict[str, Any]]:
    """:func:`frame_record` of many frames, each rotation operation done once over all of them
    (the same bits: SciPy's rotations work row by row); frames with different targets are
    done one at a time."""
    if len({tuple(i.target_names) for i in infos}) > 1:
        return [frame_record(i, c) for i, c in zip(infos, clouds)]
    if not infos:
        return []
    from ..geometry.poses import relative_rows

    def stacked(records: list[dict[str, list[float]]]) -> Poses:
        return Poses(np.array([r["translation_m"] for r in records], dtype=np.float64),
                     Rotation.from_quat(np.array([r["quaternion_xyzw"] for r in records])))

    def canonical(quats: np.ndarray) -> list[list[float]]:
        # the sign of a quaternion is free: write the one with w >= 0
        return (Rotation.from_quat(quats).as_quat(canonical=True) + 0.0).tolist()

    def pairs(records: list[dict[str, list[float]]], quats: list[list[float]], what: str,
              end: bool) -> list[dict[str, list[float]]]:
        suffix = "_end" if end else ""
        return [{f"q_{what}{suffix}": q, f"r_{what}{suffix}_m": list(r["translation_m"])}
                for r, q in zip(records, quats)]

    def quats_of(records: list[dict[str, list[float]]]) -> list[list[float]]:
        return canonical(np.array([r["quaternion_xyzw"] for r in records]))

    out: list[dict[str, Any]] = [{"frame": i.frame, "t_start_s": i.t_start,
                                  "t_end_s": i.t_end, "cloud": c}
                                 for i, c in zip(infos, clouds)]
    sensors = []
    for end, key in ((False, "sensor_pose_start"), (True, "sensor_pose_end")):
        records = [getattr(i, key) for i in infos]
        for row, pair in zip(out, pairs(records, quats_of(records), "sensor_in_scene", end)):
            row.update(pair)
        sensors.append(stacked(records))
    targets: list[list[dict[str, Any]]] = [[] for _ in infos]
    for j, name in enumerate(infos[0].target_names):
        recs: list[dict[str, Any]] = [{"name": name} for _ in infos]
        for end, key in ((False, "target_poses_start"), (True, "target_poses_end")):
            scene = [getattr(i, key)[j] for i in infos]
            # recomputed from the scene poses so files from older metadata are complete too
            in_sensor = relative_rows(stacked(scene), sensors[int(end)]).to_records()
            for rec, a, b in zip(recs, pairs(in_sensor, quats_of(in_sensor),
                                             "target_in_sensor", end),
                                 pairs(scene, quats_of(scene), "target_in_scene", end)):
                rec.update(a)
                rec.update(b)
        for row, rec in zip(targets, recs):
            row.append(rec)
    for row, recs in zip(out, targets):
        row["targets"] = recs
    return out


def _poses(record: dict[str, list[float]]) -> Poses:
    return Poses(np.asarray(record["translation_m"], dtype=np.float64).reshape(1, 3),
                 Rotation.from_quat(np.asarray(record["quaternion_xyzw"]).reshape(1, 4)))


def ground_truth(infos: Sequence["FrameInfo"], clouds: Sequence[str | None] | None = None
                 ) -> dict[str, Any]:
    """The ground truth of a sequence: header plus one :func:`frame_record` per frame.

    Parameters
    ----------
    infos
        Frame metadata, e.g. ``[cloud.frame for cloud in clouds]`` or
        :func:`sequence_frame_infos`.
    clouds
        Optional file name of each frame's point cloud, stored beside its poses.
    """
    if not infos:
        raise ValueError("no frames to write")
    clouds = list(clouds) if clouds is not None else [None] * len(infos)
    first = infos[0]
    return {"format": FORMAT_NAME, "version": FORMAT_VERSION, "convention": CONVENTION,
            "sensor": first.sensor, "seed": first.seed, "config_hash": first.config_hash,
            "motion": first.motion, "target_names": list(first.target_names),
            "frames": frame_records(infos, clouds)}


def pose_from_record(record: dict[str, Any], what: str = "target_in_sensor",
                     end: bool = False) -> Poses:
    """The pose ``what`` (e.g. ``"target_in_sensor"``) of a frame or target record as
    :class:`~lidarsim_core.geometry.poses.Poses` (``apply`` maps A-frame points into B)."""
    suffix = "_end" if end else ""
    return _poses({"quaternion_xyzw": record[f"q_{what}{suffix}"],
                   "translation_m": record[f"r_{what}{suffix}_m"]})
