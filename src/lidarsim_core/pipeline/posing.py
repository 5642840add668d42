"""The poses of a piece's rays, computed once and shared by culling and casting.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..patterns.base import RayBatch
from ..geometry.posing import PoseMatrices
from .context import RunContext


@dataclass(frozen=True)
class PiecePoses:
    """The sensor's and every target's poses at the rays of one piece (one pose each when it
    cannot vary)."""

    sensor: PoseMatrices
    targets: tuple[PoseMatrices, ...]

    def take(self, rows: np.ndarray) -> "PiecePoses":
        """The poses of the rays at ``rows``."""
        return PiecePoses(self.sensor.take(rows), tuple(p.take(rows) for p in self.targets))


def piece_poses(ctx: RunContext, batch: "RayBatch", t_frame: float) -> PiecePoses:
    """The poses of ``batch``'s rays: the ones attached by :func:`with_piece_poses`, else
    computed now."""
    attached = batch.poses
    if isinstance(attached, PiecePoses):
        return attached
    return PiecePoses(_shared(ctx.trajectory_poses(ctx.sensor_trajectory, batch.t, t_frame)),
                      tuple(_shared(ctx.trajectory_poses(target.trajectory, batch.t, t_frame))
                            for target in ctx.targets))


def _shared(poses: PoseMatrices) -> PoseMatrices:
    """One row for a position or rotation that every ray shares (a chaser holding its
    station, a body turning about its origin): the frame changes then use it for every ray,
    with the same bits (:func:`lidarsim_core.geometry.frames.rotate`)."""
    position, matrix = poses.position, poses.matrix
    if len(position) > 1 and bool((position[-1] == position[0]).all()) and \
            bool((position == position[0]).all()):
        position = position[:1]
    if len(matrix) > 1 and bool((matrix[-1] == matrix[0]).all()) and \
            bool((matrix == matrix[0]).all()):
        matrix = matrix[:1]
    return PoseMatrices(position, matrix)


def with_piece_poses(ctx: RunContext, batch: "RayBatch", t_frame: float) -> "RayBatch":
    """``batch`` with its rays' poses attached, computed once for culling and casting."""
    from dataclasses import replace

    return replace(batch, poses=piece_poses(ctx, batch, t_frame))
