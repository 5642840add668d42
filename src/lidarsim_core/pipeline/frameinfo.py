"""Frame metadata of many frames at once (:meth:`Simulation.frame_infos <lidarsim_core.pipeline.simulation.Simulation.frame_infos>`).

A frame's metadata holds the sensor's and every target's pose at its start and end, from the
trajectories' SciPy path (``poses_at``), so that the ground truth does not depend on the
compiled kernels. Looked up one frame at a time, a frame's metadata and poses-file record cost
~1.2 ms of SciPy call overhead (a ``poses_at`` per trajectory, a dozen one-row rotations), about
a fifth of a serial ``lidarsim dataset`` run on short frames (the poses file asks for every
frame before the first is simulated). Here every trajectory is evaluated once over the start and end times of all the
frames asked for, and the records are made from those arrays: each row's arithmetic is the
one-frame arithmetic (SciPy's rotations and NumPy's functions work row by row), so the
metadata, and every file written from it, is the same to the bit (``tests/test_frameinfo.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .._version import __version__
from ..geometry.poses import relative_rows
from ..records.pointcloud import FrameInfo
from .context import RunContext
from .spanposes import SpanPoses, same_times, span_poses


@dataclass(frozen=True, eq=False)
class PoseRecords:
    """The metadata's pose records at ``times`` (rows ``2i`` and ``2i + 1``: frame ``i``'s
    start and end): the sensor's, each target's in the scene and each target's in the
    sensor frame, as :meth:`~lidarsim_core.geometry.poses.Poses.to_records` gives them."""

    times: np.ndarray
    sensor: list[dict[str, list[float]]]
    scene: list[list[dict[str, list[float]]]]
    inside: list[list[dict[str, list[float]]]]

    def rows(self, start: int, stop: int) -> "PoseRecords":
        """Rows ``start:stop``, every record a copy (a frame's metadata owns its records)."""
        def copied(records: list[dict[str, list[float]]]) -> list[dict[str, list[float]]]:
            return [{key: list(value) for key, value in rec.items()}
                    for rec in records[start:stop]]

        return PoseRecords(self.times[start:stop], copied(self.sensor),
                           [copied(r) for r in self.scene], [copied(r) for r in self.inside])

    def at(self, times: np.ndarray) -> "PoseRecords | None":
        """These records when they were made for exactly ``times``, else None."""
        return self if same_times(self.times, times) else None


def pose_records(ctx: RunContext, times: np.ndarray, poses: SpanPoses | None = None
                 ) -> PoseRecords:
    """The trajectories' poses at ``times`` as the metadata records them (``poses``: when
    already looked up at those times)."""
    looked_up = (None if poses is None else poses.at(times)) or span_poses(ctx, times)
    sensor, targets = looked_up.sensor, looked_up.targets
    return PoseRecords(times, sensor.to_records(), [p.to_records() for p in targets],
                       [relative_rows(p, sensor).to_records() for p in targets])


def frame_infos(ctx: RunContext, frames: Sequence[int], measurement: dict[str, Any],
                intervals: Sequence[tuple[float, float]] | None = None,
                poses: SpanPoses | None = None, records: PoseRecords | None = None
                ) -> list[FrameInfo]:
    """Metadata of ``frames`` of a run (what :meth:`Simulation.frame_info` gives for each);
    ``measurement`` is the simulation's description of its measurement model
    (:meth:`Simulation.measurement_info`), the frames' ``extra``; ``intervals`` (one
    ``(t_start, t_end)`` per frame) replace the scenario's frame intervals; ``poses``: the
    trajectories' poses when already looked up at the frames' starts and ends, in order;
    ``records``: their pose records, when already made for those times."""
    frames = [int(f) for f in frames]
    if not frames:
        return []
    scan = ctx.scenario.scan
    if intervals is None:
        intervals = [scan.frame_interval(f) for f in frames]
    intervals = [(float(a), float(b)) for a, b in intervals]
    # rows 2i and 2i + 1: frame i's start and end
    times = np.array([t for interval in intervals for t in interval], dtype=np.float64)
    made = (None if records is None else records.at(times)) or pose_records(ctx, times, poses)
    sensor_rec, scene_rec, inside_rec = made.sensor, made.scene, made.inside
    config_hash = ctx.config_hash
    noise = [m.name for m in ctx.noise]
    names = [t.name for t in ctx.targets]
    infos = []
    for i, (frame, (t0, t1)) in enumerate(zip(frames, intervals)):
        k0, k1 = ctx.pattern.frame_index_range(t0, t1)  # a flash LiDAR's frame: one flash
        a, b = 2 * i, 2 * i + 1
        infos.append(FrameInfo(
            frame=frame, t_start=t0, t_end=t1, sensor=ctx.sensor.name,
            seed=ctx.scenario.seed, config_hash=config_hash, backend=ctx.backend.name,
            noise=list(noise), motion=scan.motion, target_names=list(names),
            part_names=ctx.part_names, rays_emitted=k1 - k0,
            sensor_pose_start=sensor_rec[a], sensor_pose_end=sensor_rec[b],
            target_poses_start=[rec[a] for rec in scene_rec],
            target_poses_end=[rec[b] for rec in scene_rec],
            targets_in_sensor=[rec[a] for rec in inside_rec],
            targets_in_sensor_end=[rec[b] for rec in inside_rec],
            software=f"lidarsim-core {__version__}", extra=measurement))
    return infos
